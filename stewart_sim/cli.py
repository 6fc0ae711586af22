"""The stewart-sim command line: arguments, exit statuses, and which pipeline each command runs
(inverse_files, paper_report, demo, stewart_sim.run, fmu, scene_info).

Subcommands: `inverse` (the contract's command), `paper` (Section 3 rerun), `demo` (what
`make demo` runs), `run` (closed loop: the per-axis controllers around the plant or an FMU),
`compare` (constant-load vs Kane control over a drive-inertia sweep), `accuracy` (error
against run time of every integrator and of the co-simulation step), `sweep` (design sweeps
on Dask), `scene-info`,
`export-fmu` and `device` (the emulated micro-manipulator behind a MAVLink link). Exit status: 0 on success; 2 on a usage error or on an
error in the inputs (every StewartError: scene, trajectory, pose); 1 when an output cannot be
written (OutputError); 130 on Ctrl-C. Every output file is written atomically: an error leaves
an existing file as it was.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path
from typing import Sequence

from stewart_sim.argtypes import number, port, positive_seconds

# Only the standard library up here: `--help` and `--version` must answer at once. Each command
# imports what it needs (numpy, the C core, matplotlib, scipy, dask, fmpy, pymavlink) when it
# runs; the defaults the help shows are repeated below (tests/app/test_cli_edges.py holds them
# to the library's values).
DEMO_DURATION = 4.0           # controller.moves.DEMO_DURATION, s
DEMO_RATE = 1000.0            # controller.moves.DEMO_RATE, Hz
RUN_MOVE = 0.3                # controller.moves.RUN_MOVE
RUN_HOLD = 0.2                # controller.moves.RUN_HOLD
HORIZON = 1.0                 # stewart_sim.accuracy.study.HORIZON, s
COMM_STEP = 0.05              # stewart_sim.accuracy.study.COMM_STEP, s
CLOSED_LOOP_DURATION = 4.0    # stewart_sim.accuracy.study.CLOSED_LOOP_DURATION, s
PROG = "stewart-sim"
DEFAULT_SCENE = Path("scenes") / "micro_manipulator.toml"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 I/O failure, 2 bad input,
    130 Ctrl-C)."""
    # Ctrl-C is caught from the start, before anything beyond the standard library is imported
    # (an interrupt inside an import waits for it to return: stewart_sim/interrupt.py)
    from stewart_sim import interrupt

    interrupt.reset_interrupt()
    restore = _catch_sigint(interrupt.sigint_handler)
    try:
        argv = list(sys.argv[1:] if argv is None else argv)
        parser = build_parser(argv[0] if argv else None)
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, usage errors: argparse has printed the message
            return exc.code if isinstance(exc.code, int) else 2
        return _run(args)
    except KeyboardInterrupt:          # while parsing, or while the packages were imported
        return _fail(f"interrupted: {KEPT}", 130)
    finally:
        restore()


def _run(args: argparse.Namespace) -> int:
    """Run the command parsed, SIGINT caught; returns the exit status (see main)."""
    # imported after parsing: --help, --version and usage errors need none of the packages
    from stewart_fmu.errors import StewartError
    from stewart_fmu.io import OutputError
    from stewart_sim import interrupt, outputs

    try:
        args.run(args)
        interrupt.check_interrupted()   # a Ctrl-C swallowed in a callback still ends with 130
    except outputs.Interrupted as exc:   # one line: interrupted, and what was kept
        return _fail(f"interrupted: {exc.kept}", 130)
    except KeyboardInterrupt:
        if hasattr(args, "kept"):          # sweep: its note, then the line scripts look for
            print(f"{PROG}: {args.kept}", file=sys.stderr)
            return _fail("interrupted", 130)
        return _fail(f"interrupted: {KEPT}", 130)
    except StewartError as exc:
        return _fail(str(exc), 2)
    except OutputError as exc:
        return _fail(str(exc), 1)
    return 0


KEPT = "nothing new written (an earlier output is left as it was)"  # on Ctrl-C


def _catch_sigint(handler):
    """Install `handler` for SIGINT (main thread only) and hide the "Exception ignored"
    report of a KeyboardInterrupt raised inside a callback (interrupt.interrupted() keeps it);
    returns the function that restores both."""
    import signal

    hook = sys.unraisablehook

    def quiet(unraisable):
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            hook(unraisable)

    try:
        previous = signal.signal(signal.SIGINT, handler)
    except ValueError:          # not the main thread: leave SIGINT alone
        return lambda: None
    sys.unraisablehook = quiet

    def restore() -> None:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
    return restore


def _fail(message: str, status: int) -> int:
    """Print `stewart-sim: error: message` on stderr and return the status."""
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return status


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with its subcommands (`command`, the one asked for: a command kept
    in its own module gets its full arguments only then, see _add_lazy)."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Dynamics of Stewart platforms (Kane's method).",
        epilog="Exit status: 0 ok, 2 usage error or bad scene/trajectory/pose, 1 a file could "
               "not be written.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(title="commands", required=True, metavar="COMMAND")

    p = sub.add_parser("inverse", help="actuator forces along a trajectory",
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
                   help="do not write the 3D view (by default FORCES.html beside FORCES.csv: stewart-sim view)")
    p.set_defaults(run=cmd_inverse)

    p = sub.add_parser("paper", help="rerun the paper's Section 3 experiments",
                       description="Rerun the paper's Section 3 experiments and write the report.")
    p.add_argument("scene", metavar="SCENE", nargs="?",
                   help=f"scene file (default: {DEFAULT_SCENE}, from the current directory or "
                        "the source checkout)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html: the six moves)")
    p.set_defaults(run=cmd_paper)

    p = sub.add_parser("demo", help="demonstration run (what `make demo` does)",
                       description="A smooth six-axis demonstration move, its forces and plot, "
                                   "and the paper rerun into DIR/paper/.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", type=positive_seconds, default=DEMO_DURATION, metavar="SECONDS",
                   help=f"length of the demonstration move (default {DEMO_DURATION:g} s, "
                        f"sampled at {DEMO_RATE:g} Hz)")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html and DIR/paper/view.html)")
    p.set_defaults(run=cmd_demo)

    p = sub.add_parser("run", help="closed-loop run: per-axis controllers around the plant",
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
    p.add_argument("--duration", type=positive_seconds, default=DEMO_DURATION, metavar="SECONDS",
                   help=f"length of the run (default {DEMO_DURATION:g} s): the move out and "
                        f"back take {100 * RUN_MOVE:g} %% of it each, the holds after them "
                        f"{100 * RUN_HOLD:g} %% each")
    p.add_argument("--format", choices=("csv", "parquet"), default="csv",
                   help="the run's table: run.csv (default) or run.parquet (smaller and much "
                        "faster to write for long runs; needs pyarrow: pip install "
                        "'stewart-sim[parquet]')")
    p.add_argument("--feedforward", choices=("none", "constant_load", "kane"),
                   help="override the scene's controller.feedforward")
    p.add_argument("--link", choices=("serial", "udp"),
                   help="run the controller against the emulated device (hil.device, in its "
                        "own process) over a pseudo-terminal (serial) or loopback UDP instead "
                        "of the in-process plant; writes run.csv and summary.md")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="with --link: lockstep (deterministic, one exchange per controller "
                        "step; default) or realtime (wall clock, link delays visible)")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html)")
    p.set_defaults(run=cmd_run)

    p = sub.add_parser("compare", help="constant-load vs Kane control over a gear-ratio sweep",
                       description="Sweep each scene's gear ratio (m_d / m_load over "
                                   "0.1-100), re-tune the per-axis PID at every point and track "
                                   "one reference with feedforward none, constant_load and "
                                   "kane; writes comparison.csv, comparison.png and report.md.")
    p.add_argument("scenes", metavar="SCENE", nargs="+", help="scene files (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--points", type=_sweep_points, default=8, metavar="N",
                   help="log-spaced sweep points per scene (default 8; the scene's own gear "
                        "ratio is added)")
    p.set_defaults(run=cmd_compare)

    p = sub.add_parser("accuracy", help="error against run time: integrators and the "
                                        "co-simulation step",
                       description="Work-precision report: forward simulations of the scene "
                                   "with every integrator over a range of steps or tolerances "
                                   "against a DOP853 reference at rtol 1e-13 (checked by "
                                   "Radau), the convergence order of the fixed-step methods, "
                                   "and the closed loop at several communication steps; "
                                   "writes open_loop.csv, closed_loop.csv, work_precision.png "
                                   "and summary.md into DIR.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--horizon", type=positive_seconds, default=HORIZON, metavar="SECONDS",
                   help=f"open-loop simulated time (default {HORIZON:g} s)")
    p.add_argument("--comm-step", type=positive_seconds, default=COMM_STEP, metavar="SECONDS",
                   help=f"open-loop communication step: the forces are held over it and the "
                        f"fixed-step methods divide it (default {COMM_STEP:g} s)")
    p.add_argument("--fine", action="store_true",
                   help="finer sweep: every decade of rtol from 1e-3 to 1e-12, more steps")
    p.add_argument("--repeats", type=_repeats, default=3, metavar="N",
                   help="time each run N times or more (runs under 0.2 s repeat until then), keep "
                        "the best; 1: a single timing (default 3)")
    p.add_argument("--closed-loop-duration", type=positive_seconds,
                   default=CLOSED_LOOP_DURATION, metavar="SECONDS",
                   help=f"length of the closed-loop runs (default {CLOSED_LOOP_DURATION:g} s)")
    p.add_argument("--no-closed-loop", action="store_true",
                   help="skip the closed loop (it needs the scene's [controller] table)")
    p.set_defaults(run=cmd_accuracy)
    p = sub.add_parser("sweep", help="design sweep (grid or Latin hypercube) on Dask",
                       description="Evaluate every point of GRID.toml (inverse dynamics, closed "
                                   "loop or workspace force envelope at scene and controller "
                                   "values) on all local cores, or on a Dask cluster with "
                                   "--scheduler; one row per point in DIR/sweep.csv, plots "
                                   "beside it. A rerun into the same DIR resumes where the last "
                                   "one stopped.")
    p.add_argument("scene", metavar="SCENE", help="the base scene file (TOML)")
    p.add_argument("--grid", required=True, metavar="GRID.toml",
                   help="evaluation, trajectory or pose grid, and the [axes] to vary (README)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (resumable)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run on this Dask distributed scheduler's workers")
    where.add_argument("--workers", type=_workers, metavar="N",
                       help="local worker processes (default: one per core)")
    p.add_argument("--no-plots", action="store_true", help="write the table only")
    p.set_defaults(run=cmd_sweep)

    p = sub.add_parser("scene-info", help="print the model a scene builds",
                       description="Print the model a scene file builds.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.set_defaults(run=cmd_scene_info)

    p = sub.add_parser("export-fmu", help="export the plant as an FMI co-simulation FMU",
                       description="Build a self-contained FMI 2.0 or 3.0 co-simulation FMU of "
                                   "the scene's plant: the C core and FMI layer compiled with "
                                   "this machine's C compiler (cc, gcc or clang; $CC first), "
                                   "its sources inside for other platforms. The FMU needs no "
                                   "Python, only the platform's C library.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("-o", "--out", required=True, metavar="PLANT.fmu", help="the FMU to write")
    p.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="FMI version of the FMU (default 2)")
    p.set_defaults(run=cmd_export_fmu)

    p = sub.add_parser("device", help="run the emulated micro-manipulator behind a MAVLink link",
                       description="Run the scene's plant and drive servo loops at the "
                                   "controller rate as an emulated device speaking MAVLink 2 "
                                   "(our dialect, hil/message_definitions/stewart.xml) over UDP "
                                   "on loopback or a pseudo-terminal, until interrupted (Ctrl-C "
                                   "exits 0). The first line printed is the pseudo-terminal's "
                                   "path, or the UDP address listened on.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [controller] table")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--udp", metavar="127.0.0.1:PORT",
                       help="listen on this loopback UDP port (0: any free port) and answer "
                            "whoever sends to it")
    where.add_argument("--pty", action="store_true",
                       help="open a pseudo-terminal and print its path on the first line")
    p.add_argument("--watchdog", type=positive_seconds, default=0.2, metavar="SECONDS",
                   help="safe stop (hold) after this long without a valid setpoint while armed "
                        "(default 0.2 s)")
    p.add_argument("--lockstep", action="store_true",
                   help="advance time only on LOCKSTEP messages (deterministic runs)")
    p.add_argument("--signing-key", metavar="HEX",
                   help="MAVLink 2 signing key, 64 hex digits: unsigned or badly signed frames "
                        "are rejected and counted")
    p.add_argument("--view", nargs="?", const=0, type=port, metavar="PORT",
                   help="serve a live 3D view of the device in the browser on 127.0.0.1:PORT "
                        "(no PORT or 0: any free port); the second line printed is its address")
    p.set_defaults(run=cmd_device)
    _add_lazy(sub, command, "simulate", "open-loop forward dynamics from rack forces")
    _add_lazy(sub, command, "trajectory", "write a trajectory file (waypoints or a named move)")
    _add_lazy(sub, command, "case", "run a stiff or extreme scene's [case] against its expectation")
    _add_lazy(sub, command, "view", "3D view of a run or trajectory as one HTML file")
    _add_lazy(sub, command, "cue", "motion cueing: vehicle motion -> platform trajectory, "
                                   "perception and limits")
    return parser


def _version() -> str:
    """The installed distribution's version (importlib.metadata: no package import)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("stewart-sim")
    except PackageNotFoundError:
        return "unknown (not installed)"


_sweep_points = number(int, "an integer", lambda v: 1 <= v <= 100, "1 to 100")
_repeats = number(int, "an integer", lambda v: 1 <= v <= 20, "1 to 20")
_workers = number(int, "an integer", lambda v: 1 <= v <= 1024, "1 to 1024")


# Each command imports its pipeline when it runs (start-up time of every other command); the
# layers allow it: our lower packages and the application's own modules only.

def _load(scene):
    """The scene's Model (stewart_fmu.scene: SceneError names the file and the key)."""
    from stewart_fmu.scene import load_scene

    return load_scene(scene)


def _written(stage: Path, out: Path, paths) -> list[Path]:
    """The paths written into the temporary `stage`, as they are in `out` now."""
    return [out / Path(p).relative_to(stage) for p in paths]


# --- inverse ---------------------------------------------------------------------------------

def cmd_inverse(args: argparse.Namespace) -> None:
    """`stewart-sim inverse SCENE --trajectory TRAJ.csv --out FORCES.csv [--parts]`."""
    from stewart_fmu.errors import StewartError
    from stewart_sim.inverse import run_inverse
    from stewart_sim.outputs import file_set
    from stewart_sim.progress import Progress

    model = _load(args.scene)
    out = Path(args.out)
    view = None if args.no_view else out.with_suffix(".html")
    if view == out:
        raise StewartError(f"--out {out}: the 3D view would be written over it: give a .csv "
                           "name, or --no-view")
    progress = Progress()
    try:   # the forces and their view: both files or neither (Ctrl-C: neither)
        with file_set(out, *([view] if view else [])) as staged:
            n, _ = run_inverse(model, Path(args.trajectory), staged[0], args.parts, progress,
                               view=staged[1] if view else None)
    finally:
        progress.close()
    print(f"wrote {args.out}: {n} samples" + (" with the breakdown by part" if args.parts else ""))
    if view is not None:
        print(f"wrote {view}")


# --- paper -----------------------------------------------------------------------------------

def cmd_paper(args: argparse.Namespace) -> None:
    """`stewart-sim paper [SCENE] --out DIR`."""
    from stewart_sim.outputs import result_set

    model = _load(resolve_scene(args.scene))
    out = Path(args.out)
    with result_set(out) as stage:
        report, results = run_paper(model, stage, view=not args.no_view)
    print_verdicts(results)
    print(f"wrote {out / report.relative_to(stage)}")


def resolve_scene(scene: str | None) -> Path:
    """The scene given, else DEFAULT_SCENE here, else the one in the source checkout."""
    from stewart_fmu.errors import SceneError

    if scene is not None:
        return Path(scene)
    if DEFAULT_SCENE.is_file():
        return DEFAULT_SCENE
    checkout = Path(__file__).resolve().parents[1] / DEFAULT_SCENE
    if checkout.is_file():
        return checkout
    raise SceneError("<file>", f"no scene given, and no {DEFAULT_SCENE} in the current directory "
                               f"({Path.cwd()}) or at {checkout}")


def run_paper(model, out: Path, view: bool = True):
    """Rerun the paper's experiments into the directory `out` (with the view of its six moves);
    returns (report.md, results)."""
    from stewart_fmu.io import writing
    from stewart_sim.paper.report import write_paper_report
    from stewart_sim.paper.study import run_paper_experiments
    from stewart_sim.view.command import VIEW_FILE, write_beside
    from stewart_sim.view.sources import paper_view

    results = run_paper_experiments(model)
    with writing(out):
        paths = write_paper_report(results, out)
    if view:
        write_beside(out / VIEW_FILE, paper_view(results, source="the paper rerun"))
    return next(p for p in paths if p.name == "report.md"), results


def print_verdicts(results) -> None:
    """One line per claim of the paper: agrees / does not agree."""
    print(f"paper rerun on '{results.scene}':")
    for v in results.verdicts:
        print(f"  {'agrees' if v.agrees else 'does not agree'}: {v.claim}")


# --- demo ------------------------------------------------------------------------------------

def cmd_demo(args: argparse.Namespace) -> None:
    """`stewart-sim demo SCENE --out DIR [--duration S]`."""
    from stewart_sim.limits import check_samples
    from stewart_sim.outputs import result_set

    model = _load(args.scene)
    check_samples("--duration", args.duration, DEMO_RATE)
    out = Path(args.out)
    with result_set(out) as stage:
        written, results = run_demo(model, stage, args.duration, view=not args.no_view)
    if results is not None:
        print_verdicts(results)
    for path in _written(stage, out, written):
        print(f"wrote {path}")


def run_demo(model, out: Path, duration: float, view: bool = True):
    """Demonstration trajectory, its forces (the `inverse` path), their plot, the 3D view, the
    paper rerun, into the directory `out`; returns (the files, the paper's results or None)."""
    import numpy as np

    from controller.moves import demo_trajectory
    from stewart_fmu import io
    from stewart_fmu.dynamics import present_parts
    from stewart_fmu.io import writing
    from stewart_sim.inverse import run_inverse
    from stewart_sim.plots import forces_figure, save_figure
    from stewart_sim.progress import Progress
    from stewart_sim.view.command import VIEW_FILE, write_beside
    from stewart_sim.view.sources import trajectory_view

    t, q, qd, qdd = demo_trajectory(model, duration)
    traj = out / "demo_trajectory.csv"
    with writing(traj):
        io.write_csv(traj, io.trajectory_table(t, q, qd, qdd))
    forces = out / "demo_forces.csv"
    progress = Progress()
    try:
        _, table = run_inverse(model, traj, forces, True, progress, keep=True)
    finally:
        progress.close()
    title = f"{model.name}: demonstration move ({duration:g} s, {DEMO_RATE:g} Hz)"
    png = out / "demo_forces.png"
    with writing(png):
        save_figure(forces_figure(table, present_parts(model), title), png)
    written, results = [traj, forces, png], None
    if view:
        sigma = np.column_stack([table[f"sigma{i}"] for i in range(1, 7)])
        write_beside(out / VIEW_FILE, trajectory_view(
            model, t, q, qd, qdd, forces=sigma, title=title, source=forces.name))
        written.append(out / VIEW_FILE)
    if model.legs is None or model.drive is None:
        print("paper rerun skipped: it needs the scene's [legs] and [drive]", file=sys.stderr)
    else:
        report, results = run_paper(model, out / "paper", view)
        written.append(report)
        if view:
            written.append(out / "paper" / VIEW_FILE)
    return written, results


# --- run -------------------------------------------------------------------------------------

def cmd_run(args: argparse.Namespace) -> None:
    """`stewart-sim run SCENE [--fmu PLANT.fmu | --link serial|udp [--mode lockstep|realtime]]
    --out DIR [--duration S] [--feedforward F] [--format csv|parquet]`."""
    from dataclasses import replace

    model = _load(args.scene)        # a bad scene file fails before the heavy imports
    from controller.config import controller_config
    from stewart_fmu.errors import StewartError
    from stewart_sim.limits import check_samples
    from stewart_sim.outputs import result_set
    from stewart_sim.run import ANY_RUN_FILES, check_format, run_closed_loop_files, run_files
    from stewart_sim.view.command import VIEW_FILE

    config = controller_config(model)
    if args.feedforward is not None:
        config = replace(config, feedforward=args.feedforward)
    if args.link is not None and args.fmu:
        raise StewartError("run: --fmu and --link exclude each other (the device over the "
                           "link runs its own in-process plant)")
    if args.link is None and args.mode != "lockstep":
        raise StewartError("run: --mode needs --link serial|udp")
    check_samples("--duration", args.duration, config.rate)
    check_format(args.format)
    out = Path(args.out)
    if args.link is not None:
        # hil (pymavlink, the device process): only for --link
        from stewart_sim.link_run import LINK_FILES, run_link_files

        if args.format != "csv":
            raise StewartError("run --link: --format parquet is not supported over the link")
        with result_set(out, ANY_RUN_FILES) as stage:
            run_link_files(model, config, args.duration, stage, args.link, args.mode,
                           view=not args.no_view)
        names = [n for n in LINK_FILES if not (args.no_view and n == VIEW_FILE)]
    else:
        names = run_files(args.format, not args.no_view)
        with result_set(out, ANY_RUN_FILES) as stage:
            run_closed_loop_files(model, config, args.duration, stage,
                                  Path(args.fmu) if args.fmu else None, args.format,
                                  not args.no_view)
    print((out / "summary.md").read_text(encoding="utf-8"), end="")
    for name in names:
        print(f"wrote {out / name}")


# --- compare ---------------------------------------------------------------------------------

def cmd_compare(args: argparse.Namespace) -> None:
    """`stewart-sim compare SCENE... --out DIR [--points N]`."""
    from stewart_sim.outputs import result_set
    from stewart_sim.run import run_compare

    out = Path(args.out)
    with result_set(out) as stage:
        written = run_compare([Path(s) for s in args.scenes], stage, args.points)
    for path in _written(stage, out, written):
        print(f"wrote {path}")


# --- accuracy --------------------------------------------------------------------------------

def cmd_accuracy(args: argparse.Namespace) -> None:
    """`stewart-sim accuracy SCENE --out DIR [--horizon S] [--comm-step S] [--fine]
    [--repeats N] [--closed-loop-duration S | --no-closed-loop]`."""
    model = _load(args.scene)        # a bad scene file fails before the heavy imports
    from stewart_fmu.io import writing
    from stewart_sim.accuracy.report import write_accuracy_report
    from stewart_sim.accuracy.study import CLOSED_LOOP_REFERENCE, accuracy_study
    from stewart_sim.limits import check_samples
    from stewart_sim.outputs import result_set
    from stewart_sim.progress import Progress

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
                model, args.horizon, args.comm_step, "fine" if args.fine else "default",
                args.repeats, None if args.no_closed_loop else args.closed_loop_duration,
                lambda stage_, done, total: progress.update(stage_, done, total, unit="runs"))
        finally:
            progress.close()
        with writing(out):
            paths = write_accuracy_report(results, stage)
    for path in _written(stage, out, paths):
        print(f"wrote {path}")


# --- sweep -----------------------------------------------------------------------------------

def cmd_sweep(args: argparse.Namespace) -> None:
    """`stewart-sim sweep SCENE --grid GRID.toml --out DIR [--scheduler tcp://HOST:PORT |
    --workers N] [--no-plots]`."""
    from stewart_sim.sweep.files import run_sweep_files  # dask: only for this command

    args.kept = (f"the points finished so far are kept in {args.out} (its chunk files), "
                 "the same command resumes from there")
    summary, written = run_sweep_files(Path(args.scene), Path(args.grid), Path(args.out),
                                       args.scheduler, args.workers, not args.no_plots)
    where = args.scheduler or "local cluster"
    print(f"sweep: {summary.points} points, {summary.resumed} already done, {summary.computed} "
          f"computed on {summary.workers} workers ({where}) in {summary.wall:.3g} s "
          f"({summary.rate:.4g} points/s); {summary.failed} failed")
    for path in written:
        print(f"wrote {path}")


# --- export-fmu ------------------------------------------------------------------------------

def cmd_export_fmu(args: argparse.Namespace) -> None:
    """`stewart-sim export-fmu SCENE -o PLANT.fmu [--fmi-version 2|3]`: -o names the file; a
    directory is refused (the FMU's name is the user's choice, not ours)."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.fmu.export import export_fmu
    from stewart_fmu.io import writing

    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the FMU's file name, e.g. "
                           f"{out / 'StewartPlant.fmu'}")
    _load(args.scene)   # the scene checked (file, keys) before the compiler runs
    with writing(out):
        export_fmu(args.scene, out, args.fmi_version)
    print(f"wrote {out}")


# --- device ----------------------------------------------------------------------------------

def cmd_device(args: argparse.Namespace) -> None:
    """`stewart-sim device SCENE (--udp 127.0.0.1:PORT | --pty) [--watchdog S] [--lockstep]
    [--signing-key HEX] [--view [PORT]]`: serve until SIGINT or SIGTERM, then return (exit
    status 0). With --view the live view (stewart_sim.view.live) listens on loopback from before
    the device starts (a taken port fails at once) until the device stops; its address is the
    line after the device's own."""
    from hil.spawn import serve_device  # pymavlink: only for this command

    model = _load(args.scene)
    if args.view is None:
        serve_device(model, args.udp, args.watchdog, args.lockstep, args.signing_key)
        return
    from hil.observe import Latest
    from stewart_sim.view.live import LiveView, live_page

    latest = Latest()
    with LiveView(live_page(model), latest, args.view) as view:
        def ready() -> None:
            view.start()
            print(f"view: {view.url}", flush=True)
        serve_device(model, args.udp, args.watchdog, args.lockstep, args.signing_key,
                     observer=latest, ready=ready)


# --- scene-info ------------------------------------------------------------------------------

def cmd_scene_info(args: argparse.Namespace) -> None:
    """`stewart-sim scene-info SCENE`: checks what run and inverse check."""
    model = _load(args.scene)        # a bad scene file fails before the heavy imports
    from stewart_sim.scene_info import describe_model

    print(describe_model(model))


_LAZY = {"simulate": "stewart_sim.simulate", "trajectory": "stewart_sim.trajectory",
         "case": "stewart_sim.case_report", "view": "stewart_sim.view.command",
         "cue": "stewart_sim.cueing.command"}


def _add_lazy(sub, command: str | None, name: str, help_text: str) -> None:
    """A command defined by its own module's add_parser (stewart_sim.simulate, .trajectory,
    .case_report): that module (and numpy, scipy, matplotlib with it) is imported only when the
    command is the one asked for, so `--help` stays fast; otherwise a stub lists it."""
    if command == name:
        importlib.import_module(_LAZY[name]).add_parser(sub)
    else:
        sub.add_parser(name, help=help_text)
