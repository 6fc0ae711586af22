"""`stewart-sim inverse SCENE --trajectory TRAJ.csv --out FORCES.csv [--parts] [--no-view]
[--frame NAME]`: the rack forces along a trajectory (stewart_sim.open_loop.inverse_forces.run_inverse) and their 3D view
beside."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.frame_option import add_frame


def add_parser(sub, help_text: str) -> None:
    """Register `inverse` on the command line's subparsers."""
    p = sub.add_parser("inverse", help=help_text,
                       description="Actuator (rack) forces for a trajectory CSV, with exactly "
                                   "the effects the scene declares.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--trajectory", required=True, metavar="TRAJ.csv",
                   help="columns t,x,y,z,thx,thy,thz, their rates d*, accelerations dd*")
    p.add_argument("--out", required=True, metavar="FORCES.csv",
                   help="t,sigma1..sigma6,cond[,<part>1..<part>6 ...]; it and its view "
                        "FORCES.html are written together or not at all")
    p.add_argument("--parts", action="store_true",
                   help="add the breakdown of sigma by contribution (the parts the scene has)")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default FORCES.html beside FORCES.csv: "
                        "stewart-sim view)")
    add_frame(p, "TRAJ.csv's poses, rates and accelerations are given in")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Write the forces (and their view) or neither; print what was written."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_sim.open_loop.inverse_forces import run_inverse
    from stewart_sim.scene.load import load
    from stewart_sim.shell.outputs import file_set
    from stewart_sim.shell.progress import Progress

    scene = load(args.scene)
    model = scene.model
    frame = chosen_frame(model, args.frame)
    out = Path(args.out)
    view = None if args.no_view else out.with_suffix(".html")
    if view == out:
        raise StewartError(f"--out {out}: the 3D view would be written over it: give a .csv "
                           "name, or --no-view")
    progress = Progress()
    try:   # the forces and their view: both files or neither (Ctrl-C: neither)
        with file_set(out, *([view] if view else [])) as staged:
            n, _ = run_inverse(model, Path(args.trajectory), staged[0], args.parts, progress,
                               view=staged[1] if view else None, controller=scene.controller,
                               frame=frame)
    finally:
        progress.close()
    print(f"wrote {args.out}: {n} samples" + (" with the breakdown by part" if args.parts else "")
          + f" (trajectory read in the {frame} frame)")
    if view is not None:
        print(f"wrote {view}")
