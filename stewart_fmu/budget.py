"""What an input may cost: the one place for the size of each kind of input file and for the
memory a count derived from an input (samples, frames, waypoints, grid points) may take.

Input files (scene, grid, trajectory, motion, run, force, pose files) are read through
`open_input` / `read_input`: the path must name a regular file (a device, FIFO or socket is
refused by fstat on the opened descriptor, before any read; the open itself cannot wait for a
FIFO's writer: O_NONBLOCK), no larger than its budget, and the read stops at the budget even where the size the file system
reports is wrong (/proc reports 0). A count is checked by `check_count` before anything of
that size is allocated, so that an input cannot make a command ask for terabytes.

Budgets (bytes):
  SCENE_BYTES   1 MiB: TOML files (scenes, grids) and the small text files a command reads
                (a result directory's summary.md); the largest shipped scene is ~5 KB.
  CSV_BYTES     1 GiB: CSV inputs; a 35-minute 1 kHz trajectory (2.1 M rows, 19 columns at
                full precision) is ~0.9 GB.
  LINE_BYTES    1 MiB: one CSV line (a few hundred columns at full precision).
  MEMORY_BUDGET 2 GiB: what the arrays a command builds from one input may take.
"""
from __future__ import annotations

import errno
import io
import os
import stat
from pathlib import Path
from typing import BinaryIO

from .errors import StewartError

MEMORY_BUDGET = 2 * 1024**3
SCENE_BYTES = 1024**2
CSV_BYTES = 1024**3
LINE_BYTES = 1024**2


class BudgetError(StewartError):
    """A count derived from an input exceeds the memory budget (the message says which)."""


class InputFileError(StewartError):
    """An input file that cannot be read as one: `path`, the `reason` (one line) and its
    `kind`: "missing", "directory", "special" (device, FIFO, socket), "large" or "other"."""

    def __init__(self, path: str | Path, reason: str, kind: str = "other"):
        self.path, self.reason, self.kind = str(path), reason, kind
        super().__init__(f"{path}: {reason}")


def check_count(what: str, count: float, bytes_each: float, hint: str = "") -> int:
    """`count` (of `what`, e.g. "view frames") as an int, after checking that count items of
    `bytes_each` bytes fit MEMORY_BUDGET (BudgetError naming what, and `hint`: how to ask for
    fewer). Call it before the allocation: a non-finite count is refused as well."""
    if not (count == count and count >= 0):      # NaN or negative: no such count
        raise BudgetError(f"{what}: {count} is not a count")
    if count * bytes_each > MEMORY_BUDGET:
        most = int(MEMORY_BUDGET // max(bytes_each, 1))
        raise BudgetError(f"{what}: {count:.4g} are more than the {most:,} that fit the memory "
                          f"budget of {MEMORY_BUDGET / 1024**3:g} GiB"
                          + (f"; {hint}" if hint else ""))
    return int(count)


def open_input(path: str | Path, limit: int) -> BinaryIO:
    """A binary stream of the regular file `path` that raises InputFileError past `limit`
    bytes. InputFileError also for a missing file, a directory, a device, FIFO or socket, or
    a file larger than `limit`."""
    path = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO with no writer would wait forever; fstat then refuses it
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError as exc:
        raise InputFileError(path, exc.strerror, "missing") from None
    except IsADirectoryError as exc:
        raise InputFileError(path, exc.strerror, "directory") from None
    except OSError as exc:
        raise InputFileError(path, exc.strerror or str(exc)) from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputFileError(path, os.strerror(errno.EISDIR), "directory")
        if not stat.S_ISREG(info.st_mode):
            raise InputFileError(path, "not a regular file (a device, pipe or socket)",
                                 "special")
        if info.st_size > limit:
            raise InputFileError(path, _too_large(info.st_size, limit), "large")
        return io.BufferedReader(_Bounded(fd, path, limit), buffer_size=1024**2)
    except BaseException:
        os.close(fd)
        raise


def read_input(path: str | Path, limit: int) -> bytes:
    """The bytes of the regular file `path`, at most `limit` of them (see open_input)."""
    with open_input(path, limit) as fh:
        try:
            return fh.read()
        except OSError as exc:
            raise InputFileError(path, exc.strerror or str(exc)) from None


def _too_large(size: float, limit: int) -> str:
    return (f"larger than the {_size(limit)} an input of this kind may be"
            + (f" ({_size(size)})" if size > limit else ""))


def _size(n: float) -> str:
    for unit, scale in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if n >= scale:
            return f"{n / scale:g} {unit}"
    return f"{n:g} bytes"


class _Bounded(io.RawIOBase):
    """The bytes of an open file descriptor, refused once more than `limit` have been read
    (a file that grows, or whose reported size is wrong)."""

    def __init__(self, fd: int, path: Path, limit: int):
        self._fd, self._path, self._limit, self._read = fd, path, limit, 0
        self.name = str(path)

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        n = os.readv(self._fd, [buffer])
        self._read += n
        if self._read > self._limit:
            raise InputFileError(self._path, _too_large(self._read, self._limit), "large")
        return n

    def close(self) -> None:
        if not self.closed:
            os.close(self._fd)
        super().close()
