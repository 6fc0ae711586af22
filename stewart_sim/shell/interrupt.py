"""Ctrl-C as KeyboardInterrupt, but never in the middle of an import.

`sigint_handler` (installed by cli.main before it imports anything beyond the standard library)
records the signal and raises KeyboardInterrupt, as Python's default handler does, except while
a module is being imported. There an exception does damage the program cannot undo: CPython
turns it into another error (numpy: ImportError "PyCapsule_Import could not import module
datetime"; a class body: RuntimeError "Error calling __set_name__"), a C extension is left half
initialised (matplotlib's pybind11 ft2font: "ImportError: initialization failed", then "Fatal
Python error: PyThreadState_Get" and an abort when the interpreter finalises), or, escaping an
exec of source text (dataclasses, namedtuple), it marks the interrupt unhandled so that Python
ends the process by SIGINT after our exit status 130 was chosen. So inside an import the
handler only arms a profile hook that raises the KeyboardInterrupt when the outermost import
returns: the module is then whole, and the interrupt leaves the command as simply as anywhere
else. Only the standard library is imported here (cli.main imports this module first).
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

# the signals that end a command as Ctrl-C does (a shell's `kill`, a closed terminal): the
# partial output removed, the earlier one left as it was, exit status 128 + the signal
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                     if hasattr(signal, name))

_interrupted = threading.Event()
_received: list[int] = []   # the first stop signal that came (at most one kept)
_deferred: list[FrameType] = []   # the import frame a SIGINT waits for (one at a time)

# the files of the frozen import system: a frame of theirs on the stack means an import runs
_IMPORT_FILES = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")


def sigint_handler(signum: int, frame: FrameType | None) -> None:
    """SIGINT (or another of STOP_SIGNALS): remember it, then interrupt like Python's default
    for SIGINT, or, inside an import, as soon as the import returns (see the module doc)."""
    if not _received:
        _received.append(signum)
    _interrupted.set()
    outermost = _outermost_import(frame)
    if outermost is None:
        raise KeyboardInterrupt
    _raise_on_return(outermost)


def note_signal(signum: int) -> None:
    """Record a stop signal that was held back (not raised), as sigint_handler would."""
    if not _received:
        _received.append(signum)
    _interrupted.set()


def reset_interrupt() -> None:
    """Forget an earlier SIGINT (a new command starts)."""
    _interrupted.clear()
    _received.clear()


def exit_status() -> int:
    """The exit status of a command the stop signal ended: 128 + its number (130 for SIGINT,
    143 for SIGTERM, 129 for SIGHUP), as a shell reports a process the signal killed."""
    return 128 + (_received[0] if _received else signal.SIGINT)


def signal_name() -> str:
    """The stop signal that came ("SIGINT" when none was recorded)."""
    return signal.Signals(_received[0] if _received else signal.SIGINT).name


def interrupted() -> bool:
    """Whether SIGINT arrived since the command started (also when it was swallowed)."""
    return _interrupted.is_set()


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if SIGINT arrived, even if the exception was swallowed."""
    if _interrupted.is_set():
        raise KeyboardInterrupt


@contextmanager
def signals_held() -> Iterator[list]:
    """SIGINT, SIGTERM and SIGHUP (STOP_SIGNALS) only recorded (not raised) inside: for a step
    that must not be cut in two (a result set's swap, a cluster's start-up). The list yielded
    is non-empty if one came, and the command's exit status then names it (note_signal). Off
    the main thread, where no handler can be set, nothing is held."""
    held: list = []
    if threading.current_thread() is not threading.main_thread():
        yield held
        return
    previous = {s: signal.signal(s, lambda n, f: held.append(n)) for s in STOP_SIGNALS}
    try:
        yield held
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if held:     # the command's exit status names the signal that came
            note_signal(held[0])


def _outermost_import(frame: FrameType | None) -> FrameType | None:
    """The oldest frame of the import system on the stack of `frame`, or None: imports nest
    (a module's body, or a C extension's initialisation, imports others), and only when the
    outermost returns is every module it started whole."""
    outermost = None
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_FILES:
            outermost = frame
        frame = frame.f_back
    return outermost


def _raise_on_return(frame: FrameType) -> None:
    """Raise KeyboardInterrupt when `frame` returns (or ends by an exception): a profile hook,
    not a trace hook, so that a coverage tracer or debugger keeps working; a profiler that was
    running is put back."""
    if _deferred:          # a second Ctrl-C in the same import: the first already waits
        return
    previous = sys.getprofile()

    def hook(f: FrameType, event: str, arg: object) -> None:
        if f is frame and event == "return":
            sys.setprofile(previous)
            _deferred.clear()
            raise KeyboardInterrupt

    _deferred.append(frame)
    sys.setprofile(hook)
