"""`stewart-sim cue SCENE --motion VEHICLE.csv --out DIR [--mode M] [--compare] [--track]`:
motion cueing from a vehicle's motion to the platform, with its perception and feasibility.

The vehicle motion file has the columns t,fx,fy,fz,wx,wy,wz (specific force in m/s^2 and
angular velocity in rad/s, vehicle frame x forward, y left, z up; at rest fz = +9.81; uniform
sampling): see scenes/motions/README.md. The scene's [cueing] table sets the washout
(docs/scene-format.md; defaults when absent). DIR gets the files listed in report.py, all or
nothing. Exit status 0 also when the cue breaks a limit: the violations are the result, listed
in summary.md and on the terminal.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from stewart_fmu.scene import load_scene
from stewart_sim.progress import Progress

from stewart_sim.view.command import VIEW_FILE, write_beside
from stewart_sim.view.data import view_data
from stewart_sim.view.sources import run_table_view

from .motion import read_motion
from .report import write_cue_report
from .study import MODES, CueStudy, cue_study

RACK = "rack force σ (inverse dynamics of the cue, incl. drive)"


def add_parser(sub) -> None:
    """Register `cue` on the CLI's subparsers."""
    p = sub.add_parser(
        "cue", help="motion cueing: vehicle motion -> platform trajectory, perception, limits",
        description="Turn a vehicle's motion (CSV t,fx,fy,fz,wx,wy,wz: specific force in m/s^2 "
                    "and angular velocity in rad/s, vehicle frame x forward, y left, z up) into "
                    "a platform trajectory with the classical washout (the scene's [cueing] "
                    "table), then check what a person perceives of it (otolith and canal "
                    "models) and whether the mechanism can fly it (stroke, cond(J), leg forces "
                    "from the scene's inverse dynamics, motor current and voltage). Writes "
                    "DIR/trajectory.csv (the `inverse` command's input format), forces.csv, "
                    "perception.csv, summary.md and figures, all or nothing.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--motion", required=True, metavar="VEHICLE.csv",
                   help="vehicle motion: columns t,fx,fy,fz,wx,wy,wz (scenes/motions/ has examples)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--mode", choices=MODES, default=MODES[0],
                   help="cueing algorithm whose trajectory is written (default: %(default)s)")
    p.add_argument("--compare", action="store_true",
                   help="also run the other cueing modes and compare them in summary.md")
    p.add_argument("--track", action="store_true",
                   help="also run the scene's closed loop ([controller]) on the cue, as `run`")
    p.add_argument("--no-view", dest="view", action="store_false",
                   help=f"do not write the 3D view ({VIEW_FILE})")
    p.set_defaults(run=cmd)


def cmd(args: argparse.Namespace) -> None:
    """Run `cue`; StewartError subclasses for bad input."""
    model = load_scene(args.scene)
    motion = read_motion(Path(args.motion))
    modes = (args.mode, *(m for m in MODES if m != args.mode)) if args.compare else (args.mode,)
    progress = Progress()
    try:
        study = cue_study(model, motion, modes, track=args.track,
                          progress=lambda stage, done, total: progress.update(stage, done, total,
                                                                              unit="steps"))
    finally:
        progress.close()
    out = Path(args.out)
    title = f"{model.name}: {Path(args.motion).name}, {args.mode} cue"
    lines: list[str] = []

    def view(stage: Path) -> list[str]:
        lines.append(write_beside(stage / VIEW_FILE, cue_view(study, title)))
        return [VIEW_FILE]

    for path in write_cue_report(study, out, title, extra=view if args.view else None):
        print(f"wrote {path}" + (f": {lines[0]}" if path.name == VIEW_FILE else ""))
    print(verdict(study))


def cue_view(study: CueStudy, title: str):
    """The 3D view: the closed loop with the cue as its ghost when it ran, else the cue with
    the rack forces of its inverse dynamics."""
    if study.tracking is not None:
        return run_table_view(study.model, study.tracking.table, title=f"{title}, closed loop",
                              source="tracking.csv")
    run = study.runs[0]
    return view_data(study.model, run.cue.t, run.cue.q, run.feasibility.sigma,
                     force_label=RACK, title=title, source="trajectory.csv")


def verdict(study: CueStudy) -> str:
    """One line per mode: feasible or its first violations; the RMS perceived error."""
    lines = []
    for r in study.runs:
        p = r.perception
        rms = (f"RMS perceived error f {', '.join(f'{v:.3g}' for v in p.rms_f)} m/s², "
               f"ω {', '.join(f'{math.degrees(v):.3g}' for v in p.rms_w)} deg/s")
        v = r.feasibility.violations
        if not v:
            lines.append(f"{r.mode}: inside every limit; {rms}")
        else:
            first = ", ".join(f"{x.quantity} leg {x.leg} at t = {x.t:.3f} s" if x.leg else
                              f"{x.quantity} at t = {x.t:.3f} s" for x in v[:3])
            lines.append(f"{r.mode}: {len(v)} limit crossings (first: {first}); {rms}")
    return "\n".join(lines)
