"""`stewart-sim excite SCENE --out T.csv [--duration S] [--period S] [--harmonics H]
[--starts N] [--frame NAME]`: an excitation trajectory for identification, optimised for the condition number
of the stacked base regressor inside the scene's limits (stewart_sim/studies/excite/)."""
from __future__ import annotations

import argparse

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import number, positive_seconds


def _at_least(low: int):
    return lambda v: v >= low


def _between(low: int, high: int):
    return lambda v: low <= v <= high


def add_parser(sub, help_text: str) -> None:
    """Register `excite` on the command line's subparsers."""
    period, harmonics, periods, starts, most, iterations, polish = literals(
        "stewart_sim.studies.excite.design", "PERIOD", "HARMONICS", "PERIODS", "STARTS",
        "MAX_STARTS", "MAX_ITERATIONS", "POLISH_ITERATIONS")
    margin, fraction = literals("controller.capability", "EXCITE_STROKE", "EXCITE_FRACTION")
    (rate,) = literals("controller.moves", "DEMO_RATE")
    p = sub.add_parser(
        "excite", help=help_text,
        description="Design a periodic excitation trajectory for `identify`: a finite Fourier "
                    "series per pose axis, at rest at home at both ends, whose coefficients "
                    "minimise the scaled condition number of the base regressor stacked over "
                    "one period (SLSQP, fixed seed), inside the stroke with "
                    f"{margin:.0%} of it kept free at each end, and within {fraction:.0%} of "
                    "the drive's no-load leg speed, its peak acceleration, its peak rack force "
                    "(the scene's inverse dynamics), the motor's voltage limit and the cond(J) "
                    "limit. Writes T.csv in the format `inverse` reads (at the scene's "
                    f"controller rate, or {rate:g} Hz without one), and beside it T.md (the "
                    "condition number, the base parameters, every limit's margin, the "
                    "coefficients) and T.png (one period of the pose and the leg lengths).")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML): the prior model")
    p.add_argument("--out", required=True, metavar="T.csv",
                   help="trajectory to write; T.md and T.png are written beside it")
    p.add_argument("--duration", type=positive_seconds, default=None, metavar="S",
                   help=f"length, a whole number of periods (default {periods} periods, "
                        f"{periods * period:g} s)")
    p.add_argument("--period", type=positive_seconds, default=period, metavar="S",
                   help=f"the fundamental period (default {period:g} s)")
    p.add_argument("--harmonics", type=number(int, "a whole number", _at_least(2),
                                              "a whole number >= 2"),
                   default=harmonics, metavar="H",
                   help=f"harmonics per axis (default {harmonics})")
    p.add_argument("--starts", type=number(int, "a whole number", _between(1, most),
                                           f"a whole number from 1 to {most}"),
                   default=starts, metavar="N",
                   help=f"random starts of the optimiser, {iterations} iterations each, then "
                        f"up to {polish} from the best (default {starts})")
    add_frame(p, "T.csv is written in (its poses, rates and accelerations)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run `excite`; StewartError subclasses for bad input."""
    from controller.moves import DEMO_RATE
    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_sim.scene.load import load
    from stewart_sim.shell.progress import Progress
    from stewart_sim.shell.run_length import check_samples
    from stewart_sim.studies.excite.design import PERIODS, check_sizes, design, excitation
    from stewart_sim.studies.excite.report import side_paths, summary, write_excitation

    side_paths(args.out)        # a bad --out before the work
    periods = PERIODS if args.duration is None else args.duration / args.period
    if abs(periods - round(periods)) > 1e-9 * max(1.0, periods) or round(periods) < 1:
        raise StewartError(f"excite: --duration {args.duration:g} s is not a whole number of "
                           f"periods of {args.period:g} s (e.g. {args.period:g}, "
                           f"{2 * args.period:g}, {3 * args.period:g})")
    periods = int(round(periods))
    scene = load(args.scene)
    frame = chosen_frame(scene.model, args.frame)
    rate = DEMO_RATE if scene.controller is None else scene.controller.rate
    check_samples("--duration", periods * args.period, rate)
    check_sizes(args.harmonics, args.period, periods, rate)
    progress = Progress()
    try:
        d = design(scene.model, scene.controller, period=args.period, harmonics=args.harmonics,
                   starts=args.starts,
                   progress=lambda stage, done, total: progress.update(stage, done, total,
                                                                       "iterations"))
        e = excitation(scene.model, scene.controller, d, periods, rate)
    finally:
        progress.close()
    for path in write_excitation(scene.model, e, args.scene, args.out, frame):
        print(f"wrote {path}")
    print(f"the trajectory's motion in the {frame} frame")
    print(f"{periods} periods of {args.period:g} s ({periods * args.period:g} s) at {rate:g} Hz, "
          f"{args.harmonics} harmonics")
    for line in summary(e):
        print(line)
