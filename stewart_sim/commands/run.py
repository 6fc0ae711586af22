"""`stewart-sim run SCENE [--fmu PLANT.fmu | --link serial|udp [--mode lockstep|realtime]
[--truth TRUE.toml] [--trajectory T.csv] [--record RUN.csv]] --out DIR [--duration S]
[--feedforward F] [--format csv|parquet] [--no-view] [--frame NAME]`: the closed loop
(stewart_sim.closed_loop.run_files, or stewart_sim.closed_loop.over_link over the link) into DIR,
all or nothing; then the recording RUN.csv."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `run` on the command line's subparsers."""
    duration, move, hold = literals("controller.moves", "DEMO_DURATION", "RUN_MOVE", "RUN_HOLD")
    (formats,) = literals("stewart_sim.closed_loop.run_files", "FORMATS")
    (feedforward,) = literals("controller.config", "FEEDFORWARD")
    p = sub.add_parser("run", help=help_text,
                       description="Track a demonstration reference (a quintic six-axis move "
                                   "out and back, with holds) with the scene's per-axis "
                                   "controllers ([controller] table) around the in-process plant "
                                   "or an exported FMU; writes run.csv, three plots and "
                                   "summary.md into DIR and prints the summary.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [controller] table")
    p.add_argument("--fmu", metavar="PLANT.fmu",
                   help="drive this FMU (export-fmu of the same scene) through fmpy instead of "
                        "the in-process plant")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", type=positive_seconds, metavar="SECONDS",
                   help=f"length of the run (default {duration:g} s): the move out and "
                        f"back take {100 * move:g} %% of it each, the holds after them "
                        f"{100 * hold:g} %% each")
    p.add_argument("--format", choices=formats, default=formats[0],
                   help="the run's table: run.csv (default) or run.parquet (smaller and much "
                        "faster to write for long runs; needs pyarrow: pip install "
                        "'stewart-sim[parquet]')")
    p.add_argument("--feedforward", choices=feedforward,
                   help="override the scene's controller.feedforward")
    p.add_argument("--link", choices=("serial", "udp"),
                   help="run the controller against the emulated device (hil.device, in its "
                        "own process) over a pseudo-terminal (serial) or loopback UDP instead "
                        "of the in-process plant; writes run.csv and summary.md")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="with --link: lockstep (deterministic, one exchange per controller "
                        "step; default) or realtime (wall clock, link delays visible)")
    p.add_argument("--truth", metavar="TRUE.toml",
                   help="with --link: the device's plant and [sensors] come from this hidden "
                        "true scene (same geometry, other masses, inertias, frictions); the "
                        "host and the device's controllers still believe SCENE")
    p.add_argument("--trajectory", metavar="T.csv",
                   help="with --link: follow this trajectory (the columns inverse reads, "
                        "starting at rest at the home pose; resampled to the controller rate "
                        "when its step differs) instead of the demonstration move")
    p.add_argument("--record", metavar="RUN.csv",
                   help="with --link in lockstep: write the run as the device reported it: "
                        "t (device time), l1..l6 (m), sigma1..sigma6 (N), current1..current6 "
                        "(A), one row per controller period (the input of identify)")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html)")
    add_frame(p, "--trajectory T.csv is given in and run.csv's poses (x..thz, x_ref..thz_ref) "
                 "are written in")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Check the options against each other, run, print summary.md and the files."""
    from dataclasses import replace

    from stewart_sim.scene.load import load

    scene = load(args.scene)        # a bad scene file fails before the heavy imports
    from stewart_fmu.errors import StewartError
    from stewart_sim.closed_loop.run_files import (ANY_RUN_FILES, check_format,
                                                   run_closed_loop_files, run_files)
    from stewart_sim.shell.outputs import result_set
    from stewart_sim.shell.run_length import check_samples
    from stewart_sim.view.files import VIEW_FILE

    from stewart_fmu.frames import chosen_frame

    model, config = scene.model, scene.require_controller()
    frame = chosen_frame(model, args.frame)
    if args.feedforward is not None:
        config = replace(config, feedforward=args.feedforward)
    if args.link is not None and args.fmu:
        raise StewartError("run: --fmu and --link exclude each other (the device over the "
                           "link runs its own in-process plant)")
    if args.link is None and args.mode != "lockstep":
        raise StewartError("run: --mode needs --link serial|udp")
    for name in ("truth", "trajectory", "record"):
        if args.link is None and getattr(args, name) is not None:
            raise StewartError(f"run: --{name} needs --link serial|udp")
    if args.trajectory is not None and args.duration is not None:
        raise StewartError("run: --duration and --trajectory exclude each other (the "
                           "trajectory's own length is run)")
    if args.record is not None and args.mode != "lockstep":
        raise StewartError("run: --record needs --mode lockstep (every device tick recorded; "
                           "in real time the link carries only part of them)")
    if args.record is not None and Path(args.record).is_dir():
        raise StewartError(f"run: --record {args.record} is a directory, not a CSV file")
    if args.duration is None:
        from controller.moves import DEMO_DURATION

        args.duration = DEMO_DURATION
    if scene.has_solver and (args.fmu or args.link):
        raise StewartError("run: the scene's [solver] sets the in-process plant's integrator; "
                           "the FMU (--fmu) and the device (--link) integrate with their own: "
                           "remove [solver] or run in-process")
    check_samples("--duration", args.duration, config.rate)
    check_format(args.format)
    out = Path(args.out)
    if args.link is not None:
        # hil (pymavlink, the device process): only for --link
        from stewart_fmu.io import write_csv, writing
        from stewart_sim.closed_loop.over_link import (LINK_FILES, link_trajectory, record_table,
                                                       run_link_files)

        if args.format != "csv":
            raise StewartError("run --link: --format parquet is not supported over the link")
        from hil.sensors import latency_ticks
        from hil.truth import check_truth

        # the machine's faults are refused here, in one line, not by the device process
        machine = load(args.truth) if args.truth is not None else scene
        if args.truth is not None:
            check_truth(model, machine.model)
        latency_ticks(machine.sensors, config.rate, machine.model.source)
        truth = Path(args.truth) if args.truth is not None else None
        traj = link_trajectory(model, config, args.trajectory, frame) if args.trajectory \
            else None
        with result_set(out, ANY_RUN_FILES) as stage:
            run, _ = run_link_files(model, config, args.duration, stage, args.link, args.mode,
                                    view=not args.no_view, traj=traj, truth=truth,
                                    currents=args.record is not None)
        names = [n for n in LINK_FILES if not (args.no_view and n == VIEW_FILE)]
        if args.record is not None:
            record = Path(args.record)
            with writing(record):
                write_csv(record, record_table(run))
    else:
        names = run_files(args.format, not args.no_view)
        with result_set(out, ANY_RUN_FILES) as stage:
            run_closed_loop_files(model, config, args.duration, stage,
                                  Path(args.fmu) if args.fmu else None, args.format,
                                  not args.no_view, options=scene.solver, frame=frame)
    print((out / "summary.md").read_text(encoding="utf-8"), end="")
    print(f"poses in the {frame} frame" + (" (--trajectory read in it; run.csv over the link "
                                           "holds leg lengths only)" if args.link else ""))
    for name in names:
        print(f"wrote {out / name}")
    if args.record is not None:
        print(f"wrote {args.record}")
