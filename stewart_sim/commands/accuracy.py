"""`stewart-sim accuracy SCENE --out DIR [--horizon S] [--comm-step S] [--fine] [--repeats N]
[--closed-loop-duration S | --no-closed-loop]`: the work-precision report
(stewart_sim.studies.accuracy) into DIR, all or nothing."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.shell.argtypes import number, positive_seconds

_repeats = number(int, "an integer", lambda v: 1 <= v <= 20, "1 to 20")


def add_parser(sub, help_text: str) -> None:
    """Register `accuracy` on the command line's subparsers."""
    horizon, comm_step, closed_loop, repeats = literals(
        "stewart_sim.studies.accuracy.study", "HORIZON", "COMM_STEP", "CLOSED_LOOP_DURATION",
        "REPEATS")
    p = sub.add_parser("accuracy", help=help_text,
                       description="Work-precision report: forward simulations of the scene "
                                   "with every integrator over a range of steps or tolerances "
                                   "against a DOP853 reference at rtol 1e-13 (checked by "
                                   "Radau), the convergence order of the fixed-step methods, "
                                   "and the closed loop at several communication steps; "
                                   "writes open_loop.csv, closed_loop.csv, work_precision.png "
                                   "and summary.md into DIR.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--horizon", type=positive_seconds, default=horizon, metavar="SECONDS",
                   help=f"open-loop simulated time (default {horizon:g} s)")
    p.add_argument("--comm-step", type=positive_seconds, default=comm_step, metavar="SECONDS",
                   help=f"open-loop communication step: the forces are held over it and the "
                        f"fixed-step methods divide it (default {comm_step:g} s)")
    p.add_argument("--fine", action="store_true",
                   help="finer sweep: every decade of rtol from 1e-3 to 1e-12, more steps")
    p.add_argument("--repeats", type=_repeats, default=repeats, metavar="N",
                   help="time each run N times or more (runs under 0.2 s repeat until then), keep "
                        f"the best; 1: a single timing (default {repeats})")
    p.add_argument("--closed-loop-duration", type=positive_seconds,
                   default=closed_loop, metavar="SECONDS",
                   help=f"length of the closed-loop runs (default {closed_loop:g} s)")
    p.add_argument("--no-closed-loop", action="store_true",
                   help="skip the closed loop (it needs the scene's [controller] table)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run the study, write its report, print the files."""
    from stewart_sim.scene.load import load

    scene = load(args.scene)        # a bad scene file fails before the heavy imports
    from stewart_fmu.io import writing
    from stewart_sim.shell.outputs import result_set, written_in
    from stewart_sim.shell.progress import Progress
    from stewart_sim.shell.run_length import check_samples
    from stewart_sim.studies.accuracy.report import write_accuracy_report
    from stewart_sim.studies.accuracy.study import CLOSED_LOOP_REFERENCE, accuracy_study

    check_samples("--horizon", args.horizon, 2.0 / args.comm_step,
                  "the open loop samples the move twice per --comm-step")
    if not args.no_closed_loop:
        check_samples("--closed-loop-duration", args.closed_loop_duration,
                      1.0 / CLOSED_LOOP_REFERENCE, "the closed loop's reference run")
    out = Path(args.out)
    with result_set(out) as stage:
        progress = Progress()
        try:
            results = accuracy_study(
                scene.model, scene.controller, args.horizon, args.comm_step,
                "fine" if args.fine else "default", args.repeats,
                None if args.no_closed_loop else args.closed_loop_duration,
                lambda stage_, done, total: progress.update(stage_, done, total, unit="runs"))
        finally:
            progress.close()
        with writing(out):
            paths = write_accuracy_report(results, stage)
    for path in written_in(stage, out, paths):
        print(f"wrote {path}")
