"""The stewart-sim command line: the command table, exit statuses and Ctrl-C.

Each command is a module of stewart_sim.commands (its arguments and its run function); COMMANDS
below is the one list of them. Exit status: 0 on success; 2 on a usage error or on an error in
the inputs (every StewartError: scene, trajectory, pose); 1 when an output cannot be written
(OutputError); 130 on Ctrl-C. Every output file is written atomically: an error leaves an
existing file as it was.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from typing import Sequence

# Only the standard library here: `--help` and `--version` must answer at once. The command
# asked for is the only module of stewart_sim.commands imported, and it imports what its work
# needs (numpy, the C core, matplotlib, scipy, dask, fmpy, pymavlink) when it runs.
PROG = "stewart-sim"

# command -> its one line in `stewart-sim --help`; the module is stewart_sim.commands.<command>
# with "-" as "_"
COMMANDS = {
    "inverse": "actuator forces along a trajectory",
    "paper": "rerun the paper's Section 3 experiments",
    "demo": "demonstration run (what `make demo` does)",
    "run": "closed-loop run: per-axis controllers around the plant",
    "compare": "constant-load vs Kane control over a gear-ratio sweep",
    "accuracy": "error against run time: integrators and the co-simulation step",
    "sweep": "design sweep (grid or Latin hypercube) on Dask",
    "scene-info": "print the model a scene builds",
    "export-fmu": "export the plant (or --controller) as an FMI co-simulation FMU",
    "export-ssp": "export the closed loop (plant and controller FMUs) as an SSP",
    "device": "run the emulated micro-manipulator behind a MAVLink link",
    "simulate": "open-loop forward dynamics from rack forces",
    "trajectory": "write a smooth reference trajectory (the `inverse` input format)",
    "case": "run a stiff or extreme scene's [case] and check its outcome",
    "view": "3D view of a run or trajectory as one HTML file (opens offline)",
    "cue": "motion cueing: vehicle motion -> platform trajectory, perception, limits",
    "calibrate": "kinematic calibration: joints and leg offsets from measured poses",
    "identify": "identify inertial and friction parameters from measured runs",
    "excite": "excitation trajectory for identification (optimised regressor condition)",
}
KEPT = "nothing new written (an earlier output is left as it was)"  # on Ctrl-C


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


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every command of COMMANDS listed, and `command` (the one asked for)
    with its full arguments from its module, so that `--help` imports no command module."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Dynamics of Stewart platforms (Kane's method).",
        epilog="Exit status: 0 ok, 2 usage error or bad scene/trajectory/pose, 1 a file could "
               "not be written.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(title="commands", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        if name == command:
            command_module(name).add_parser(sub, help_text)
        else:
            sub.add_parser(name, help=help_text)
    return parser


def command_module(name: str):
    """The module of the command `name` (stewart_sim.commands)."""
    return importlib.import_module(f"stewart_sim.commands.{name.replace('-', '_')}")


def _run(args: argparse.Namespace) -> int:
    """Run the command parsed, SIGINT caught; returns the exit status (see main)."""
    # imported after parsing: --help, --version and usage errors need none of the packages
    from numpy.linalg import LinAlgError

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
    except (ArithmeticError, LinAlgError) as exc:   # inputs within their bounds still overflowed
        return _fail(f"the inputs are beyond what the computation holds in float64 "
                     f"({type(exc).__name__}: {exc})", 2)
    return 0


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


def _version() -> str:
    """The installed distribution's version (importlib.metadata: no package import)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("stewart-sim")
    except PackageNotFoundError:
        return "unknown (not installed)"
