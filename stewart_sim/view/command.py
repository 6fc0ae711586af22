"""`stewart-sim view SOURCE [--scene SCENE] [--trajectory TRAJ.csv] -o VIEW.html [--fps FPS]`:
the 3D view of a run directory or CSV as one self-contained HTML file (stewart_sim.view.html),
and `write_beside`, the step `run`, `inverse`, `demo` and `paper` take to write theirs."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from stewart_fmu.errors import StewartError
from stewart_fmu.io import writing
from stewart_fmu.scene import load_scene
from stewart_sim.argtypes import positive_rate
from stewart_sim.view.data import DEFAULT_FPS, ViewData
from stewart_sim.view.html import write_view
from stewart_sim.view.sources import recorded_scene, view_of

VIEW_FILE = "view.html"


def add_parser(sub) -> None:
    """Register `view` on the CLI's subparsers."""
    p = sub.add_parser(
        "view", help="3D view of a run or trajectory as one HTML file (opens offline)",
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
    p.add_argument("--fps", type=positive_rate, default=DEFAULT_FPS, metavar="FPS",
                   help=f"frames per second of simulated time (default {DEFAULT_FPS:g}): the "
                        "samples are decimated to this rate (the page states it)")
    p.set_defaults(run=cmd_view)


def scene_for(source: Path, scene: str | None) -> Path:
    """--scene, else the scene a run directory (or the directory of a run table) recorded."""
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


def cmd_view(args: argparse.Namespace) -> None:
    source = Path(args.source)
    if not source.exists():
        raise StewartError(f"{source}: no such file or directory")
    model = load_scene(scene_for(source, args.scene))
    start = time.perf_counter()
    view = view_of(source, model, fps=args.fps,
                   trajectory=Path(args.trajectory) if args.trajectory else None)
    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the page's file name, e.g. "
                           f"{out / VIEW_FILE}")
    with writing(out):
        size = write_view(out, view)
    print(f"wrote {out}: {describe(view, size)} in {time.perf_counter() - start:.3g} s")


def describe(view: ViewData, size: int) -> str:
    """One line: the page's size and what it shows."""
    return (f"{size / 1e6:.2f} MB, {view.frames} frames at {view.fps:g} frames/s from "
            f"{view.source_samples} samples")


def write_beside(path: Path, view: ViewData) -> str:
    """Write a command's view (inside its result set); returns the describe() line."""
    with writing(path):
        size = write_view(path, view)
    return describe(view, size)
