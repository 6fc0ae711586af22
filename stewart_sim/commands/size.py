"""`stewart-sim size SCENE --motions M1.csv [M2.csv ...] --out DIR [--catalogue drives.csv]
[--margin F] [--scheduler tcp://HOST:PORT | --workers N]`: the actuators a platform needs for
the motions it is to fly (stewart_sim.studies.sizing). DIR gets the files listed in
stewart_sim/studies/sizing/report.py, all or nothing. Exit status 0 also when no drive qualifies:
the report says so. A motion that reaches the scene's first mode ([stiffness]) is a warning on
stderr and in report.md."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import number

_workers = number(int, "an integer", lambda v: 1 <= v <= 1024, "1 to 1024")
_margin = number(float, "a number", lambda v: 0.0 <= v <= 10.0, "a fraction from 0 to 10")


def add_parser(sub, help_text: str) -> None:
    """Register `size` on the command line's subparsers."""
    (margin,) = literals("stewart_sim.studies.sizing.study", "DEFAULT_MARGIN")
    p = sub.add_parser(
        "size", help=help_text,
        description="For a set of motions (platform trajectories in the `inverse` format, `cue`'s "
                    "trajectory.csv as it is, or vehicle motions t,fx,fy,fz,wx,wy,wz cued with the "
                    "scene's [cueing] classical washout), the stroke, speed, acceleration, rack "
                    "force, motor torque, speed and power each leg needs (peak and RMS, with the "
                    "motion and time of each peak) through the scene's full dynamics including "
                    "the drive; the margins of the scene's drive and motor; with --catalogue, "
                    "every drive of the catalogue in the scene's place (on Dask), the ones that "
                    "meet every motion with the margin ranked by price, else mass.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--motions", required=True, nargs="+", metavar="MOTION.csv",
                   help="platform trajectories or vehicle motions (told apart by the header)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--catalogue", metavar="drives.csv",
                   help="drives to choose from: name, gear_ratio, pinion_radius (m), "
                        "rotor_inertia (kg m^2), peak_torque, continuous_torque (N m), max_speed "
                        "(rad/s), price and/or mass (kg) (scenes/catalogues/README.md)")
    p.add_argument("--margin", type=_margin, default=margin, metavar="F",
                   help="fraction of every rating kept free (default: %(default)s)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run the catalogue on this Dask distributed scheduler's workers")
    where.add_argument("--workers", type=_workers, metavar="N",
                       help="local worker processes (default: one per core, at most one per drive)")
    add_frame(p, "the platform trajectories among --motions are given in (a vehicle motion is "
                 "cued into C's pose)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run the sizing and write its report; StewartError subclasses for bad input."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_sim.scene.load import load
    from stewart_sim.shell.progress import Progress
    from stewart_sim.cueing.resonance import resonance
    from stewart_sim.studies.sizing.catalogue import read_catalogue
    from stewart_sim.studies.sizing.motions import read_motions
    from stewart_sim.studies.sizing.report import write_size_report
    from stewart_sim.studies.sizing.study import (check_budget, check_finite, ranking, size_scene,
                                                  sweep_catalogue)

    if not args.catalogue and (args.scheduler or args.workers):
        raise StewartError("--scheduler and --workers run the catalogue sweep: give --catalogue")
    scene = load(args.scene)
    model = scene.model
    frame = chosen_frame(model, args.frame)
    motions = read_motions(scene, args.motions, frame)
    drives = read_catalogue(args.catalogue) if args.catalogue else None   # before any work
    if drives is not None:
        check_budget(drives, motions, args.catalogue)
    sizing = size_scene(model, scene.controller, motions)
    first_mode = tuple(resonance(model, m.t, m.q, m.qd, m.qdd) for m in motions)
    sweep, ranked = None, []
    if drives is not None:
        progress = Progress()
        try:
            sweep = sweep_catalogue(Path(args.scene), drives, motions, args.scheduler,
                                    args.workers, progress)
        finally:
            progress.close()
        ranked = ranking(sweep.results, args.margin)
        where = args.scheduler or "local cluster"
        print(f"catalogue: {len(drives)} drives on {sweep.workers} workers ({where}"
              + (f", dashboard {sweep.dashboard}" if sweep.dashboard else "") + ")")
    check_finite(sizing, sweep.results if sweep else (), args.catalogue)   # before any file
    for m, r in zip(motions, first_mode):
        if r is not None and r.reaches:
            print(r.line(m.name), file=sys.stderr)
    for path in write_size_report(Path(args.out), model, motions, sizing, sweep, ranked,
                                  args.margin, model.name, first_mode, frame):
        print(f"wrote {path}")
    peak = max((d.statistics()["force"].peak for d in sizing.demands), key=lambda p: p.magnitude)
    motion = next(d.motion for d in sizing.demands if d.statistics()["force"].peak == peak)
    if any(m.kind == "platform" for m in motions):
        print(f"platform trajectories read in the {frame} frame")
    print(f"peak rack force {peak.magnitude:.6g} N (leg {peak.leg}, t = {peak.t:g} s, {motion})")
    if drives is not None:
        good = [r for r in ranked if r.qualifies(args.margin)]
        first = f"; first: {good[0].drive.name}" if good else ""
        print(f"{len(good)} of {len(drives)} drives meet every motion with a "
              f"{100 * args.margin:g} % margin{first}")
