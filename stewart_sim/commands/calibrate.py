"""`stewart-sim calibrate SCENE --poses P.csv --out DIR [--select N]`: kinematic calibration
of the joints and leg-length offsets from tracker poses and encoder lengths.

The poses file has the columns x,y,z,thx,thy,thz (the measured platform pose, docs/conventions.md)
and l1..l6 (the lengths the encoders report), in any order; the model and the method are in
stewart_sim/studies/calibrate/study.py, the files DIR gets (all or nothing) in
stewart_sim/studies/calibrate/report.py.
"""
from __future__ import annotations

import argparse

from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import number


def _at_least_one(v: int) -> bool:
    return v >= 1


def add_parser(sub, help_text: str) -> None:
    """Register `calibrate` on the command line's subparsers."""
    p = sub.add_parser(
        "calibrate", help=help_text,
        description="Estimate the base joints a_i, platform joints p_i and leg-length offsets "
                    "delta_i (42 parameters) from measured platform poses and the leg lengths "
                    "the encoders report, model l_i = |x + R p_i - a_i| + delta_i, by "
                    "Levenberg-Marquardt from the scene's joints. Reports which parameters "
                    "are observable (singular values of the identification Jacobian), their "
                    "standard deviations and the residuals. Writes DIR/calibrated.toml (the "
                    "scene with the estimated joints), offsets.csv (delta_i), "
                    "calibration.csv, residuals.png and report.md, all or nothing.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML): the nominal joints")
    p.add_argument("--poses", required=True, metavar="P.csv",
                   help="measured poses and leg lengths: columns x,y,z,thx,thy,thz,l1..l6 "
                        "(m, rad)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--select", type=number(int, "a whole number", _at_least_one,
                                           "a whole number >= 1"),
                   metavar="N", help="calibrate on the N most informative poses of the file "
                                     "(greedy D-optimal selection)")
    add_frame(p, "P.csv's measured poses are given in (a tracker's target as the tool frame, "
                 "its base as the user frame)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run `calibrate`; StewartError subclasses for bad input."""
    from dataclasses import replace

    from stewart_fmu.frames import chosen_frame, to_platform
    from stewart_sim.scene.load import load
    from stewart_sim.studies.calibrate.report import write_calibration
    from stewart_sim.studies.calibrate.study import (calibrate, check_bounds, check_finite,
                                                     read_poses)

    scene = load(args.scene)
    frame = chosen_frame(scene.model, args.frame)
    data = read_poses(args.poses)
    data = replace(data, poses=to_platform(scene.model, data.poses, frame))
    check_bounds(scene.model, data, args.poses)
    cal = calibrate(scene.model, data, args.select)
    check_finite(cal, args.poses)       # before the first file is written
    for path in write_calibration(cal, args.scene, args.poses, args.out):
        print(f"wrote {path}")
    worst = max(range(6), key=lambda i: cal.rms[i])
    print(f"{len(cal.used)} poses, scaled cond {cal.cond:.3g}, "
          f"{int(cal.observable.sum())} of 42 parameters observable; residual RMS "
          f"{cal.rms.min() * 1e6:.3g}-{cal.rms[worst] * 1e6:.3g} um (worst leg {worst + 1}); "
          f"poses read in the {frame} frame")
