"""Trajectory and result files (CSV, the contract's columns), written atomically at full precision."""
from __future__ import annotations

import csv
import errno
import io as _io
import itertools
import os
import re
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Callable, Iterable, Iterator

import numpy as np

from .budget import CSV_BYTES, LINE_BYTES, InputFileError, check_count, open_input
from .errors import TrajectoryError

POSE = ("x", "y", "z", "thx", "thy", "thz")
TRAJECTORY_COLUMNS = ("t", *POSE, *(f"d{c}" for c in POSE), *(f"dd{c}" for c in POSE))
FORCE_COLUMNS = ("t", *(f"sigma{i}" for i in range(1, 7)))
CHUNK_ROWS = 50_000  # rows per block when reading and writing long files


class OutputError(Exception):
    """An output file or directory cannot be written (exit status 1)."""


def named_array(columns: dict[str, np.ndarray]) -> np.ndarray:
    """A structured array with one float64 field per column (like fmpy's simulate_fmu result)."""
    n = len(next(iter(columns.values())))
    out = np.empty(n, dtype=[(name, "f8") for name in columns])
    for name, values in columns.items():
        out[name] = values
    return out


def write_csv(path: str | Path, table: np.ndarray,
              progress: Callable[[int, int], None] | None = None) -> Path:
    """Write a structured array as CSV with repr-exact floats (and text fields, e.g. a method
    name, as they are); an existing file survives a failure. `progress(rows_written, rows)` is
    called after each block of CHUNK_ROWS rows (long tables take seconds to write)."""
    starts = range(0, max(len(table), 1), CHUNK_ROWS)  # an empty table still gets its header

    def chunks():
        for i in starts:
            yield table[i:i + CHUNK_ROWS]
            if progress is not None:
                progress(min(i + CHUNK_ROWS, len(table)), len(table))
    return write_csv_chunks(path, chunks())


def write_csv_chunks(path: str | Path, chunks: Iterable[np.ndarray]) -> Path:
    """Write structured arrays with the same float64 fields as one CSV, atomically.

    The chunks may be computed while the file is written (long runs need not hold every row);
    any failure, also one raised by `chunks`, leaves an existing file untouched.
    """
    def write(fh) -> None:
        names = None
        for chunk in chunks:
            if names is None:
                names = chunk.dtype.names
                csv.writer(fh).writerow(names)
            elif chunk.dtype.names != names:
                raise ValueError(f"chunk columns {chunk.dtype.names} differ from {names}")
            fh.write("".join(",".join(map(_cell, row)) + "\r\n" for row in chunk.tolist()))
        if names is None:
            raise ValueError(f"{path}: nothing to write (no chunks)")

    return atomic_write(path, write)


def _cell(value) -> str:
    """A CSV cell: numbers repr-exact, text (a label column) as it is."""
    return value if isinstance(value, str) else repr(value)


def atomic_write(path: str | Path, write: Callable[[IO], object], binary: bool = False) -> Path:
    """Write a file through a temporary one beside it; a failure leaves an existing file as it was.

    `path` must be a new path or a regular file (check_output); a full disk, a missing
    permission or a read-only file system while writing is an OutputError naming `path`."""
    path = Path(path)
    check_output(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(path)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=partial_prefix(path), suffix=".tmp")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        with (os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="", encoding="utf-8")) as fh:
            write(fh)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; results are for everyone
        os.replace(tmp, path)
    except BaseException as exc:
        os.unlink(tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return path


# what an OSError while writing an output means: the disk is full, a quota is reached, the
# file system is read-only, or writing there is not allowed (one line, exit status 1)
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                          errno.EFBIG, errno.EIO})
# trees of the kernel and the devices: no output of ours belongs there (/dev/shm is an
# ordinary file system)
SYSTEM_TREES = ("/proc", "/sys", "/dev")
_ORDINARY = ("/dev/shm",)


class SpecialOutputError(OutputError):
    """An output path that names no file the command may own: a device, FIFO or socket, or a
    path in /proc, /sys or /dev (refused before any work: exit status 2)."""


def check_output(path: str | Path) -> None:
    """Refuse (SpecialOutputError) an output path that is, or resolves to, anything but a new
    path, a regular file or a directory: writing there would replace a device node or feed a
    kernel file. Checked before any work by the command line, and again by every writer."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except OSError:     # a new path (or one the write will report)
        mode = stat.S_IFREG
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise SpecialOutputError(f"cannot write {path}: it is a device, pipe or socket, not a "
                                 "file or directory a command may write")
    real = os.path.realpath(path)
    for tree in SYSTEM_TREES:
        if (real == tree or real.startswith(tree + "/")) and not any(
                real == o or real.startswith(o + "/") for o in _ORDINARY):
            raise SpecialOutputError(f"cannot write {path}: it is in {tree}, not a file or "
                                     "directory a command may write")


PARTIAL = ".partial-"   # in the name of a temporary output: .NAME.partial-PID-XXXX


def partial_prefix(path: str | Path) -> str:
    """The name prefix of the temporaries that stand for `path` while it is written: they
    carry this process's id, so that the next writer can tell an abandoned one."""
    return f".{Path(path).name}{PARTIAL}{os.getpid()}-"


def remove_stale_partials(path: str | Path) -> list[Path]:
    """Remove the temporaries (partial_prefix) in the directory of `path` left by a process
    that is gone (killed before it could clean up); returns them. Those of a live process are
    left alone. A directory is looked at once per process: a writer dying later leaves its
    temporaries to the next command (a sweep writes thousands of chunks into one directory)."""
    directory = os.path.realpath(Path(path).parent)
    if directory in _SWEPT:
        return []
    removed = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    _SWEPT.add(directory)
    for entry in entries:
        match = _PARTIAL_NAME.match(entry.name)
        if match is None or process_alive(int(match.group(1))):
            continue
        target = Path(entry.path)
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(target, ignore_errors=True)
        else:
            try:
                target.unlink()
            except OSError:
                continue
        removed.append(target)
    return removed


_SWEPT: set[str] = set()    # directories whose stale temporaries this process removed
_PARTIAL_NAME = re.compile(r"^\..+" + re.escape(PARTIAL) + r"(\d{1,10})-[^/]*$")


def process_alive(pid: int) -> bool:
    """Whether a process `pid` exists (one of another user's counts)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return pid > 0
    return True


def write_text(path: str | Path, text: str) -> Path:
    """Write a text file atomically."""
    return atomic_write(path, lambda fh: fh.write(text))


def read_trajectory(path: str | Path, progress: Callable[[int], None] | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read a trajectory CSV: returns t (N,), q, qd, qdd (N, 6); errors name the row and column.

    Rows are parsed in blocks of CHUNK_ROWS; `progress(rows_read)` is called after each block.
    """
    data = read_samples(path, TRAJECTORY_COLUMNS, "trajectory", progress=progress)
    return data[:, 0].copy(), data[:, 1:7].copy(), data[:, 7:13].copy(), data[:, 13:19].copy()


def read_samples(path: str | Path, columns: tuple[str, ...], what: str, *, prefix: bool = False,
                 anywhere: bool = False, min_rows: int = 1,
                 progress: Callable[[int], None] | None = None) -> np.ndarray:
    """The (N, len(columns)) numbers of a time-indexed CSV (trajectories, forces, waypoints, run
    tables), columns[0] the time: its header is `columns` (with `prefix`, starts with them;
    with `anywhere`, holds each of them once, in any order; further columns are ignored), every
    value finite, time strictly increasing, at least `min_rows` samples. Errors
    (TrajectoryError) name the file, the line and the column.

    Blocks of CHUNK_ROWS lines of plain numbers are parsed by numpy (np.loadtxt, about twice as
    fast as csv + float()); a block numpy refuses is read again row by row, which
    says where and why (or reads what numpy does not: quoted cells, digits with underscores),
    so the values and the errors are those of csv + float() alone. `progress(rows_read)` is
    called after each block."""
    if prefix and anywhere:
        raise ValueError("read_samples: prefix and anywhere exclude each other")
    path = Path(path)
    with _reading(path, what) as fh:
        data = _read_rows(path, fh, columns, prefix, anywhere, progress)
    if data.shape[0] < min_rows:
        count = {1: "one", 2: "two"}.get(min_rows, str(min_rows))
        raise TrajectoryError(f"{path}: need {count} or more samples, got {data.shape[0]}")
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        raise TrajectoryError(
            f"{path}: line {r + 2}, column '{columns[c]}': non-finite value {data[r, c]}")
    t = data[:, 0]
    if np.any(np.diff(t) <= 0):
        r = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 3
        raise TrajectoryError(
            f"{path}: line {r}, column '{columns[0]}': time must increase strictly")
    return data


def read_table(path: str | Path, columns: tuple[str, ...], what: str) -> np.ndarray:
    """The (N, len(columns)) numbers of a CSV that is no time series (poses: `workspace
    --check`): its header holds each of `columns` once, in any order (further columns are
    ignored), at least one row, every value finite; errors (TrajectoryError) name the file, the
    line and the column, as read_samples'."""
    path = Path(path)
    with _reading(path, what) as fh:
        data = _read_rows(path, fh, columns, False, True, None)
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        raise TrajectoryError(
            f"{path}: line {r + 2}, column '{columns[c]}': non-finite value {data[r, c]}")
    return data


def csv_header(path: str | Path, what: str) -> tuple[str, ...]:
    """The column names of a CSV's header, stripped (none for an empty file); the errors of
    read_samples for a file that cannot be read."""
    path = Path(path)
    with _reading(path, what) as fh:
        header, _ = _header(path, fh)
    return header or ()


@contextmanager
def _reading(path: Path, what: str) -> Iterator[IO[str]]:
    """The text of the CSV input `path`, read within the input rule (stewart_fmu.budget: a
    regular file of at most CSV_BYTES); a file that cannot be opened, read or decoded, or that
    is a device, pipe or socket (reading one may never end: /dev/zero): TrajectoryError
    naming it."""
    try:
        with open_input(path, CSV_BYTES) as raw, \
                _io.TextIOWrapper(raw, encoding="utf-8", newline="") as fh:
            yield fh
    except InputFileError as exc:
        raise TrajectoryError(f"{path}: cannot read {what}: {exc.reason}") from None
    except OSError as exc:
        raise TrajectoryError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise TrajectoryError(f"{path}: not a text file: {exc}") from None


def _bounded_lines(path: Path, fh: IO[str]) -> Iterator[str]:
    """The lines of `fh`, each at most LINE_BYTES characters (a longer one: TrajectoryError
    naming its line; a file of one endless line would otherwise be held whole)."""
    for number in itertools.count(1):
        line = fh.readline(LINE_BYTES + 1)
        if not line:
            return
        if len(line) > LINE_BYTES:
            raise TrajectoryError(f"{path}: line {number} is longer than {LINE_BYTES:,} "
                                  "characters")
        yield line


def _header(path: Path, fh: IO[str]) -> tuple[tuple[str, ...] | None, int]:
    """The first record of `fh`, stripped (None: an empty file), and the lines it took."""
    reader = csv.reader(_bounded_lines(path, fh))
    try:
        row = next(reader, None)
    except csv.Error as exc:
        raise TrajectoryError(f"{path}: line {reader.line_num}: not valid CSV: {exc}") from None
    return (None if row is None else tuple(c.strip() for c in row)), reader.line_num


def _read_rows(path: Path, fh: IO[str], columns: tuple[str, ...], prefix: bool, anywhere: bool,
               progress: Callable[[int], None] | None) -> np.ndarray:
    """Check the header, then parse the rows block by block into an (N, len(columns)) array:
    numpy while the blocks are plain numbers, from the first block that is not row by row."""
    header, lines_before = _header(path, fh)
    if header is None:
        raise TrajectoryError(f"{path}: empty file, expected header {','.join(columns)}")
    picks = _picks(path, header, columns, prefix, anywhere)
    blocks: list[np.ndarray] = []
    rows = 0
    source = _bounded_lines(path, fh)
    while lines := list(itertools.islice(source, CHUNK_ROWS)):
        # the rows and their one copy (np.concatenate) must fit before they are parsed
        check_count(f"{path}: samples", rows + len(lines), 2 * 8 * len(columns))
        block = _numbers(lines, len(header), picks)
        if block is None:   # the rest row by row (a quoted cell may span the block's end)
            blocks += _rows_one_by_one(path, itertools.chain(lines, source), columns, picks,
                                       len(header), rows, lines_before + rows, progress)
            break
        blocks.append(block)
        rows += len(lines)
        if len(lines) == CHUNK_ROWS and progress is not None:
            progress(rows)
    if not blocks:
        raise TrajectoryError(f"{path}: no samples after the header")
    return np.concatenate(blocks)


def _picks(path: Path, header: tuple[str, ...], columns: tuple[str, ...], prefix: bool,
           anywhere: bool) -> list[int]:
    """Where each of `columns` stands in the header (which must hold them, see read_samples)."""
    if not anywhere:
        _check_header(path, header[:len(columns)] if prefix else header, columns, prefix)
        return list(range(len(columns)))
    missing = [c for c in columns if c not in header]
    twice = [c for c in columns if header.count(c) > 1]
    if missing or twice:
        raise TrajectoryError(
            f"{path}: header must hold {','.join(columns)} (in any order); "
            f"missing {missing or 'none'}, more than once {twice or 'none'}")
    return [header.index(c) for c in columns]


def _numbers(lines: list[str], width: int, picks: list[int]) -> np.ndarray | None:
    """The picked columns of `lines` if each is `width` plain numbers (no quotes), else None.

    np.loadtxt converts a cell with PyOS_string_to_double, the function float() ends in, and
    accepts a subset of what float() does (no underscores, ASCII digits only): where it
    succeeds the values are float()'s. It skips blank lines, ignores extra fields and has no
    field size limit, where the row-by-row reader refuses: hence the checks of each line."""
    commas, limit = width - 1, csv.field_size_limit()
    for line in lines:
        if (line.count(",") != commas or '"' in line or len(line) > limit
                or (not commas and not line.strip())):
            return None
    try:
        return np.loadtxt(lines, dtype=float, delimiter=",", comments=None, usecols=picks,
                          ndmin=2)
    except ValueError:
        return None


def _rows_one_by_one(path: Path, lines: Iterable[str], columns: tuple[str, ...],
                     picks: list[int], width: int, done: int, lines_before: int,
                     progress: Callable[[int], None] | None) -> list[np.ndarray]:
    """csv + float() on each row from sample `done` on (`lines_before` lines precede them):
    the first row that is not `width` numbers raises TrajectoryError naming its line."""
    reader = csv.reader(lines)
    blocks, block = [], []
    try:
        for r, row in enumerate(reader, start=done + 2):
            if len(row) != width:
                raise TrajectoryError(f"{path}: line {r} has {len(row)} fields, expected {width}")
            try:
                block.append([float(row[k]) for k in picks])
            except ValueError:
                raise _bad_cell(path, r, [row[k] for k in picks], columns) from None
            if len(block) == CHUNK_ROWS:
                check_count(f"{path}: samples", done + CHUNK_ROWS * (len(blocks) + 1),
                            2 * 8 * len(columns))
                blocks.append(np.array(block))
                block = []
                if progress is not None:
                    progress(done + CHUNK_ROWS * len(blocks))
    except csv.Error as exc:
        raise TrajectoryError(
            f"{path}: line {lines_before + reader.line_num}: not valid CSV: {exc}") from None
    if block:
        blocks.append(np.array(block))
    return blocks


def _check_header(path: Path, header: tuple[str, ...], columns: tuple[str, ...],
                  prefix: bool) -> None:
    """The header must be exactly `columns`, in order (with prefix: start with them)."""
    if header != columns:
        missing = [c for c in columns if c not in header]
        extra = [c for c in header if c not in columns]
        raise TrajectoryError(
            f"{path}: header must {'start with' if prefix else 'be'} {','.join(columns)}; "
            f"missing {missing or 'none'}, unexpected {extra or 'none'}"
            + ("" if missing or extra else ", columns out of order"))


def _bad_cell(path: Path, line: int, row: list[str], columns: tuple[str, ...]) -> TrajectoryError:
    """The error for the first cell of a row that is not a number."""
    for c, cell in enumerate(row[:len(columns)]):
        try:
            float(cell)
        except ValueError:
            return TrajectoryError(
                f"{path}: line {line}, column '{columns[c]}': not a number: {cell!r}")
    return TrajectoryError(f"{path}: line {line}: not a number")


def trajectory_table(t, q, qd, qdd) -> np.ndarray:
    """The trajectory as a structured array with the contract's columns."""
    cols = np.column_stack([t, q, qd, qdd])
    return named_array({name: cols[:, k] for k, name in enumerate(TRAJECTORY_COLUMNS)})


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def writing(path: Path) -> Iterator[None]:
    """Turn an OSError while writing `path` into an OutputError naming it (not a temporary)."""
    try:
        yield
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
