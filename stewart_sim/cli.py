"""The stewart-sim command line: the command table, exit statuses and Ctrl-C.

Each command is a module of stewart_sim.commands (its arguments and its run function); COMMANDS
below is the one list of them. Exit status: 0 on success (a command may return its own, documented: `design` 3 when no
design meets every requirement); 2 on a usage error or on an error in
the inputs (every StewartError: scene, trajectory, pose); 1 when an output cannot be written
(OutputError, or a full disk, a missing permission, a read-only file system); 130 on Ctrl-C,
143 on SIGTERM, 129 on SIGHUP (all three end a command alike); 141, quietly, when standard
output is a pipe whose reader is gone (`| head -1`). Every output file is written
atomically: an error leaves an existing file as it was. What `--out` (or `--record`) names
must be a new path, a regular file or a directory: a device, FIFO, socket or a path in
/proc, /sys or /dev is refused before any work (exit 2: stewart_fmu.io.check_output).
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
    "check-ssp": "check an SSP's parameter values against their declared ranges",
    "device": "run the emulated micro-manipulator behind a MAVLink link",
    "simulate": "open-loop forward dynamics from rack forces",
    "trajectory": "write a smooth reference trajectory (the `inverse` input format)",
    "case": "run a stiff or extreme scene's [case] and check its outcome",
    "view": "3D view of a run or trajectory as one HTML file (opens offline)",
    "cue": "motion cueing: vehicle motion -> platform trajectory, perception, limits",
    "calibrate": "kinematic calibration: joints and leg offsets from measured poses",
    "identify": "identify inertial and friction parameters from measured runs",
    "excite": "excitation trajectory for identification (optimised regressor condition)",
    "size": "actuator sizing: what the motions ask of the drives, a catalogue ranked",
    "telemetry-replay": "stream a recorded vehicle motion as UDP telemetry in real time",
    "cue-live": "live motion simulator: UDP telemetry -> washout -> envelope -> the device",
    "workspace": "what the mechanism reaches: limits' margins at poses, travel, ranges",
    "modes": "natural frequencies, mode shapes and stiffness at a pose ([stiffness])",
    "design": "a hexapod's geometry from its requirements (NSGA-II on Dask, densely checked)",
}
KEPT = "nothing new written (an earlier output is left as it was)"  # on Ctrl-C
# the arguments that name what a command writes (the output rule checks them before any work)
OUTPUT_ARGS = ("out", "record")
# build_parser(EVERY): every command with its full arguments (the command reference of docs/)
EVERY = "*"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 I/O failure, 2 bad input,
    128 + the signal on SIGINT, SIGTERM or SIGHUP, 141 on a closed pipe)."""
    # Ctrl-C is caught from the start, before anything beyond the standard library is imported
    # (an interrupt inside an import waits for it to return: stewart_sim/shell/interrupt.py)
    from stewart_sim.shell import interrupt, terminal

    interrupt.reset_interrupt()
    restore = _catch_sigint(interrupt.sigint_handler)
    try:
        # every line printed from here on has its control characters escaped (a scene name,
        # a file name, a message quoting an input): stewart_sim/shell/terminal.py
        with terminal.escaping():
            argv = list(sys.argv[1:] if argv is None else argv)
            parser = build_parser(argv[0] if argv else None)
            try:
                args = parser.parse_args(argv)
            except SystemExit as exc:  # --help, usage errors: argparse has printed the message
                return exc.code if isinstance(exc.code, int) else 2
            return _run(args)
    except KeyboardInterrupt:          # while parsing, or while the packages were imported
        return _interrupted(KEPT)
    except BrokenPipeError:            # `stewart-sim ... | head -1`: the reader is gone
        return _closed_pipe()
    finally:
        restore()


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every command of COMMANDS listed, and `command` (the one asked for)
    with its full arguments from its module, so that `--help` imports no command module
    (EVERY: every command with its full arguments)."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Dynamics of Stewart platforms (Kane's method).",
        epilog="Exit status: 0 ok, 2 usage error or bad scene/trajectory/pose, 1 a file could "
               "not be written.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(title="commands", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        if command in (name, EVERY):
            command_module(name).add_parser(sub, help_text)
        else:
            sub.add_parser(name, help=help_text)
    return parser


def reference_parser() -> argparse.ArgumentParser:
    """Every command with its full arguments: what the command reference of docs/ is generated
    from (docs/reference/commands.md)."""
    return build_parser(EVERY)


def command_module(name: str):
    """The module of the command `name` (stewart_sim.commands)."""
    return importlib.import_module(f"stewart_sim.commands.{name.replace('-', '_')}")


def _run(args: argparse.Namespace) -> int:
    """Run the command parsed, SIGINT caught; returns the exit status (see main)."""
    # imported after parsing: --help, --version and usage errors need none of the packages
    from numpy.linalg import LinAlgError

    from stewart_fmu.errors import StewartError
    from stewart_fmu.io import WRITE_ERRNOS, OutputError, SpecialOutputError, check_output
    from stewart_sim.shell import interrupt, outputs

    try:
        for name in OUTPUT_ARGS:        # the output rule, before any work
            if isinstance(getattr(args, name, None), str):
                check_output(getattr(args, name))
        status = args.run(args)         # None: 0; a command's own status (design: 3)
        interrupt.check_interrupted()   # a Ctrl-C swallowed in a callback still ends with 130
        sys.stdout.flush()              # a closed pipe shows here, not at the exit
    except outputs.Interrupted as exc:   # one line: interrupted, and what was kept
        return _interrupted(exc.kept)
    except KeyboardInterrupt:
        if hasattr(args, "kept"):          # sweep: its note, then the line scripts look for
            print(f"{PROG}: {args.kept}", file=sys.stderr)
            return _interrupted(None)
        return _interrupted(KEPT)
    except SpecialOutputError as exc:      # an output that is no file to write: bad input
        return _fail(str(exc), 2)
    except StewartError as exc:
        return _fail(str(exc), 2)
    except OutputError as exc:
        return _fail(str(exc), 1)
    except OSError as exc:
        if isinstance(exc, BrokenPipeError):
            raise
        if exc.errno not in WRITE_ERRNOS:   # not an output that cannot be written: a bug
            raise
        return _fail(f"cannot write {exc.filename or 'the output'}: {exc.strerror or exc}", 1)
    except (ArithmeticError, LinAlgError) as exc:   # inputs within their bounds still overflowed
        return _fail(f"the inputs are beyond what the computation holds in float64 "
                     f"({type(exc).__name__}: {exc})", 2)
    return status if isinstance(status, int) else 0


def _interrupted(kept: str | None) -> int:
    """The line for a command a stop signal ended (what was kept), and its exit status."""
    from stewart_sim.shell import interrupt

    name = interrupt.signal_name()
    how = "interrupted" if name == "SIGINT" else f"interrupted ({name})"
    return _fail(how if kept is None else f"{how}: {kept}", interrupt.exit_status())


def _closed_pipe() -> int:
    """The reader of standard output went away: end quietly, as a POSIX tool that SIGPIPE
    ends (status 141); standard output is pointed at /dev/null so that the interpreter's
    last flush at exit does not report the lost lines."""
    import os
    import signal

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):   # no real stdout (captured): nothing to do
        pass
    return 128 + signal.SIGPIPE


def _catch_sigint(handler):
    """Install `handler` for SIGINT, SIGTERM and SIGHUP (interrupt.STOP_SIGNALS; main thread
    only) and hide the "Exception ignored" report of a KeyboardInterrupt raised inside a
    callback (interrupt.interrupted() keeps it); returns the function that restores both."""
    import signal

    from stewart_sim.shell.interrupt import STOP_SIGNALS

    hook = sys.unraisablehook

    def quiet(unraisable):
        if not isinstance(unraisable.exc_value, (KeyboardInterrupt, BrokenPipeError)):
            hook(unraisable)

    try:
        previous = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    except ValueError:          # not the main thread: leave the signals alone
        return lambda: None
    sys.unraisablehook = quiet

    def restore() -> None:
        for s, old in previous.items():
            signal.signal(s, old)
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
