"""`stewart-sim view SOURCE [--scene SCENE] [--trajectory TRAJ.csv] -o VIEW.html [--fps FPS]
[--frame NAME]`:
the 3D view of a run directory or CSV as one self-contained HTML file (stewart_sim.view.html)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import positive_rate


def add_parser(sub, help_text: str) -> None:
    """Register `view` on the command line's subparsers."""
    (fps,) = literals("stewart_sim.view.data", "DEFAULT_FPS")
    p = sub.add_parser(
        "view", help=help_text,
        description="Write a self-contained HTML page (meshcat's three.js viewer, no server) "
                    "showing the platform, the legs as cylinder and piston coloured by force, "
                    "the reference pose as a ghost for closed-loop runs, with play/pause, a "
                    "time slider, the pose, leg lengths, forces and cond(J), and marks for legs "
                    "at a stroke limit and near-singular poses. SOURCE: a `run` directory "
                    "(run.csv or run.parquet), a `demo` or `paper` directory, a trajectory CSV "
                    "(forces by inverse dynamics) or a forces CSV with --trajectory.")
    p.add_argument("source", metavar="SOURCE", help="result directory or CSV")
    p.add_argument("--scene", metavar="SCENE",
                   help="scene file (TOML); default for a `run` directory: the scene its "
                        "summary.md records")
    p.add_argument("--trajectory", metavar="TRAJ.csv",
                   help="with a forces CSV: the trajectory the forces were computed from")
    p.add_argument("-o", "--out", required=True, metavar="VIEW.html", help="the page to write")
    p.add_argument("--fps", type=positive_rate, default=fps, metavar="FPS",
                   help=f"frames per second of simulated time (default {fps:g}): the "
                        "samples are decimated to this rate (the page states it)")
    add_frame(p, "a trajectory CSV's and a run table's poses are given in (a `demo` or "
                 "`paper` directory holds C's pose)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Write the page; print its size and what it shows."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_fmu.io import writing
    from stewart_sim.scene.load import load
    from stewart_sim.view.files import VIEW_FILE, describe
    from stewart_sim.view.html import write_view
    from stewart_sim.view.sources import view_of

    source = Path(args.source)
    if not source.exists():
        raise StewartError(f"{source}: no such file or directory")
    scene = load(scene_for(source, args.scene))
    model = scene.model
    frame = chosen_frame(model, args.frame)
    start = time.perf_counter()
    view = view_of(source, model, controller=scene.controller, fps=args.fps,
                   trajectory=Path(args.trajectory) if args.trajectory else None, frame=frame)
    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the page's file name, e.g. "
                           f"{out / VIEW_FILE}")
    with writing(out):
        size = write_view(out, view)
    print(f"wrote {out}: {describe(view, size)} in {time.perf_counter() - start:.3g} s; poses "
          f"read in the {frame} frame")


def scene_for(source: Path, scene: str | None) -> Path:
    """--scene, else the scene a run directory (or the directory of a run table) recorded."""
    from stewart_fmu.errors import StewartError
    from stewart_sim.view.sources import recorded_scene

    if scene is not None:
        return Path(scene)
    directory = source if source.is_dir() else source.parent
    recorded = recorded_scene(directory)
    if recorded is None:
        raise StewartError(f"{source}: no scene recorded with it (a `run` directory's "
                           "summary.md names one): give --scene SCENE")
    if not recorded.is_file():
        raise StewartError(f"{source}: the scene it recorded, {recorded}, is not there from "
                           f"{Path.cwd()}: give --scene SCENE")
    return recorded
