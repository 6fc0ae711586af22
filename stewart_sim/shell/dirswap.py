"""One directory put in the place of another by one rename, so that a reader, or a process
killed at any instant, finds the earlier directory whole or the new one whole.

`swap_in(stage, out)`: where the C library has renameat2 and the kernel and file system have
RENAME_EXCHANGE (Linux >= 3.15; ext4, xfs, btrfs, tmpfs, ...), the two names are exchanged by
one system call: no instant exists at which `out` is missing or mixed. The earlier directory
is then at the stage's name (a temporary `.DIR.partial-PID-XXXX`): the caller removes it, and
if the process is killed first the next writer beside it does (it is a temporary of a process
that is gone: stewart_fmu.io.remove_stale_partials).

Elsewhere (no renameat2: macOS, Windows, musl before 1.2.3 or glibc before 2.28; a file
system answering ENOSYS or EINVAL to the flag) two renames: `out` aside to `.DIR.old-PID-XXXX`,
then the stage to `out`. Between the two a reader finds no `out` at all, never a mixed one. A
process killed there leaves the aside: the next writer into `out` puts it back (`recover`,
`out` missing: the earlier set, whole) or removes it (`out` present: the new set, whole).
"""
from __future__ import annotations

import ctypes
import errno
import os
import re
import secrets
import shutil
from pathlib import Path

from stewart_fmu.io import process_alive

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
ASIDE = ".old-"                # in the name of an earlier directory moved aside: .DIR.old-PID-XXXX
_UNSUPPORTED = frozenset({errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP})


def _load_renameat2():
    try:
        function = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError, TypeError):   # no such symbol, or no C library by that name
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                         ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


_RENAMEAT2 = _load_renameat2()


def exchange(a: Path, b: Path) -> bool:
    """Exchange the directories `a` and `b` atomically; False (nothing done) where the C
    library, kernel or file system cannot; OSError for any other refusal."""
    if _RENAMEAT2 is None:
        return False
    if _RENAMEAT2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in _UNSUPPORTED:
        return False
    raise OSError(code, os.strerror(code), str(b))


def swap_in(stage: Path, out: Path) -> None:
    """Put the directory `stage` in the place of the existing directory `out`; afterwards the
    earlier `out` is gone from view (at `stage` after an exchange, removed after the fallback).
    On an OSError `out` is as it was."""
    if exchange(stage, out):
        return
    aside = out.parent / f".{out.name}{ASIDE}{os.getpid()}-{secrets.token_hex(4)}"
    os.rename(out, aside)
    try:
        os.rename(stage, out)
    except OSError:
        os.rename(aside, out)
        raise
    shutil.rmtree(aside, ignore_errors=True)


def recover(out: Path) -> None:
    """Undo what a process killed between the fallback's two renames left: its aside goes
    back to `out` if `out` is missing (the earlier set, whole), else it is removed."""
    pattern = re.compile(r"^\." + re.escape(out.name) + re.escape(ASIDE) + r"(\d{1,10})-[0-9a-f]{8}$")
    try:
        entries = sorted(os.scandir(out.parent), key=lambda e: e.name)
    except OSError:
        return
    for entry in entries:
        match = pattern.match(entry.name)
        if match is None or process_alive(int(match.group(1))):
            continue
        if not os.path.lexists(out):
            os.rename(entry.path, out)
        else:
            shutil.rmtree(entry.path, ignore_errors=True)
