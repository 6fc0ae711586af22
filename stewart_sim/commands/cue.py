"""`stewart-sim cue SCENE --motion VEHICLE.csv --out DIR [--mode M] [--compare] [--track]`:
motion cueing from a vehicle's motion to the platform, with its perception and feasibility.

The vehicle motion file has the columns t,fx,fy,fz,wx,wy,wz (specific force in m/s^2 and
angular velocity in rad/s, vehicle frame x forward, y left, z up; at rest fz = +9.81; uniform
sampling): see scenes/motions/README.md. The scene's [cueing] table sets the washout
(docs/scene-format.md; defaults when absent). DIR gets the files listed in
stewart_sim/cueing/report.py, all or nothing. Exit status 0 also when the cue breaks a limit:
the violations are the result, listed in summary.md and on the terminal; a cue that reaches the
scene's first mode ([stiffness]) is a warning on stderr and in summary.md.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame


def add_parser(sub, help_text: str) -> None:
    """Register `cue` on the command line's subparsers."""
    (modes,) = literals("stewart_sim.cueing.study", "MODES")
    (view_file,) = literals("stewart_sim.view.files", "VIEW_FILE")
    p = sub.add_parser(
        "cue", help=help_text,
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
    p.add_argument("--mode", choices=modes, default=modes[0],
                   help="cueing algorithm whose trajectory is written (default: %(default)s)")
    p.add_argument("--compare", action="store_true",
                   help="also run the other cueing modes and compare them in summary.md")
    p.add_argument("--track", action="store_true",
                   help="also run the scene's closed loop ([controller]) on the cue, as `run`")
    p.add_argument("--no-view", dest="view", action="store_false",
                   help=f"do not write the 3D view ({view_file})")
    add_frame(p, "DIR/trajectory*.csv (and tracking.csv's poses) are written in")
    p.set_defaults(run=run)


def warn_first_mode(study) -> None:
    """On stderr, a line for each cue that reaches the scene's first mode."""
    import sys

    from stewart_sim.cueing.report import first_mode_warnings

    for line in first_mode_warnings(study):
        print(line, file=sys.stderr)


def run(args: argparse.Namespace) -> None:
    """Run `cue`; StewartError subclasses for bad input."""
    from stewart_fmu.frames import chosen_frame
    from stewart_sim.cueing.motion import read_motion
    from stewart_sim.cueing.report import cue_view, verdict, write_cue_report
    from stewart_sim.cueing.study import MODES, cue_study
    from stewart_sim.scene.load import load
    from stewart_sim.shell.progress import Progress
    from stewart_sim.view.files import VIEW_FILE, write_beside

    scene = load(args.scene)
    model = scene.model
    frame = chosen_frame(model, args.frame)
    motion = read_motion(Path(args.motion))
    modes = (args.mode, *(m for m in MODES if m != args.mode)) if args.compare else (args.mode,)
    progress = Progress()
    try:
        study = cue_study(scene, motion, modes, track=args.track,
                          progress=lambda stage, done, total: progress.update(stage, done, total,
                                                                              unit="steps"))
    finally:
        progress.close()
    if scene.controller is not None:
        study = preflown(study, scene, motion)
    out = Path(args.out)
    title = f"{model.name}: {Path(args.motion).name}, {args.mode} cue"
    warn_first_mode(study)
    lines: list[str] = []

    def view(stage: Path) -> list[str]:
        lines.append(write_beside(stage / VIEW_FILE, cue_view(study, title, scene.controller)))
        return [VIEW_FILE]

    for path in write_cue_report(study, out, title, extra=view if args.view else None,
                                 model=model, frame=frame):
        print(f"wrote {path}" + (f": {lines[0]}" if path.name == VIEW_FILE else ""))
    print(f"trajectories in the {frame} frame")
    print(verdict(study))


def preflown(study, scene, motion):
    """The study with each classical run's cue-live preflight (live.preflight: the envelope
    on a simulated clock); the optimal mode's live MPC has no preview, another cue: not
    preflown."""
    from dataclasses import replace

    from stewart_sim.live.preflight import preflight

    runs = tuple(replace(r, live=preflight(scene, motion).as_dict()) if r.mode == "classical"
                 else r for r in study.runs)
    return replace(study, runs=runs)
