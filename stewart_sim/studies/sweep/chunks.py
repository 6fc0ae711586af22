"""A sweep's chunk files: the rows of one finished task (`write_chunk`), and the rows a resumed
sweep takes back from them (`resume_rows`): only rows this sweep wrote, whole and plausible.

A chunk file, DIR/chunks/part-NNNNNNNNN.csv (NNNNNNNNN: its first point id, nine digits):

    #stewart-sim sweep chunk 1 FINGERPRINT ROWS SHA256
    point,AXIS...,status,error,RESULT...          the table's header
    ROWS rows, as sweep.csv has them

FINGERPRINT is the sweep's (DIR/sweep.json: grid, scene, trajectory files), ROWS the number of
rows (1 to the grid's `batch`), SHA256 the hex digest of every byte after the first line. A
resumed sweep refuses a chunk that is not a regular file, is larger than its rows can be
(ROW_BYTES a row), lacks that first line, was written for another sweep, fails its checksum, is
not UTF-8 CSV in the form write_chunk writes, or has a row for an unknown point, a point twice
(in it or in an earlier chunk), axis values that are not the point's, or results that break
evaluate.result_problem. A refused chunk is moved to DIR/refused/ with one line naming it and
the reason, and its points are computed again: a sweep resumed after a crash finishes, and no
row of a damaged or foreign file reaches sweep.csv. The checksum detects damage (a torn copy, an
edit), not forgery: a file edited and given a new checksum is still held to the rows' rules.

A task's rows are held to the same rules and made into a chunk's text on the worker that
evaluated them (checked_cells, chunk_text); the client that runs the sweep checks only its
form (check_task_text: the points it sent, the sweep's columns) and writes it
(write_chunk_text), so its share of a point stays small however many workers there are. Every
chunk is read and checked again when sweep.csv is merged (merge_chunks).

A sweep of millions of points keeps no rows in memory: `resume_ledger` and a run's finished
tasks record which points the accepted chunks hold (a Ledger: one byte per point), and
`merge_chunks` writes sweep.csv from the chunk files, read again (and checked again) in point
order, a few at a time.
"""
from __future__ import annotations

import csv
import hashlib
import heapq
import io as textio
import math
import os
import re
import stat
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from stewart_fmu.errors import SweepError
from stewart_fmu.io import OutputError, atomic_write
from stewart_sim.studies.sweep.evaluate import result_bounds, result_problem
from stewart_sim.studies.sweep.result_table import CHUNKS, cell, csv_text, write_table

MAGIC = "#stewart-sim sweep chunk 1"
REFUSED = "refused"      # DIR/refused/: chunks set aside on resume
ROW_BYTES = 64 * 1024    # the most bytes a row (or the header) may take in a chunk file
_HEAD_BYTES = 256        # the first line's bound
_ID = re.compile(r"0|[1-9][0-9]{0,18}")
_HEX = re.compile(r"[0-9a-f]{64}")


@dataclass(frozen=True)
class ChunkRules:
    """What this sweep's chunks must be (see the module doc)."""

    fingerprint: str
    columns: tuple[str, ...]
    axes: Sequence[tuple[str, ...]]   # by point id - first: the point's axis values as cells
    max_rows: int                     # rows in one chunk (the grid's batch)
    drive: bool                       # the scene has a [drive] table (evaluate.has_drive)
    first: int = 0                    # the first point id (a refinement round's: adaptive.py)

    @cached_property
    def results_from(self) -> int:
        """The first result column's index: point, axes, status and error come before."""
        return self.columns.index("status") + 2

    @cached_property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """Each result column's evaluate.result_bounds, in order."""
        return tuple(result_bounds(name) for name in self.columns[self.results_from:])


class AxisCells(Sequence):
    """The points' axis values as cells, by position (point id - the first's), made when asked
    for (no list of them)."""

    def __init__(self, points: Sequence[tuple[int, Mapping[str, Any]]]) -> None:
        self.points = points

    def __len__(self) -> int:
        return len(self.points)

    def __getitem__(self, i: int) -> tuple[str, ...]:   # type: ignore[override]
        return tuple(cell(v) for v in self.points[i][1].values())


def chunk_rules(fingerprint: str, columns: Sequence[str],
                points: Sequence[tuple[int, Mapping[str, Any]]], batch: int,
                drive: bool) -> ChunkRules:
    """The rules for the chunks of a sweep of `points` (ids first..first+n-1 in order: the
    grid's from 0; a list, or a grid.PointSequence)."""
    first = points[0][0] if len(points) else 0
    return ChunkRules(fingerprint, tuple(columns), AxisCells(points), min(batch, len(points)),
                      drive, first)


def chunk_path(out: Path, first: int) -> Path:
    """The chunk file of the task whose first point is `first`."""
    return out / CHUNKS / f"part-{first:09d}.csv"


class Ledger:
    """Which points the accepted chunk files of a sweep hold, without their rows: a flag per
    point (`done`, by point id - `first`), and each file with its first and last point and its
    rows."""

    def __init__(self, points: int, first: int = 0) -> None:
        self.done = bytearray(points)
        self.first = first
        self.files: list[tuple[int, int, int, Path]] = []   # first, last, rows, path
        self.count = 0

    def add(self, path: Path, ids: Iterator[int] | Sequence[int]) -> None:
        """Record a chunk file that holds the points `ids` (none of them recorded before)."""
        ids = sorted(ids)
        for pid in ids:
            self.done[pid - self.first] = 1
        self.files.append((ids[0], ids[-1], len(ids), path))
        self.count += len(ids)

    def has(self, pid: int) -> bool:
        return bool(self.done[pid - self.first])


def write_chunk(out: Path, rules: ChunkRules, rows: Sequence[Mapping[str, Any]]
                ) -> dict[int, list[str]]:
    """Write the rows of one finished task as a chunk file (checked_cells, then
    write_chunk_text); returns them as cell texts by point id (what a resume reads back)."""
    cells = checked_cells(rules, rows)
    write_chunk_text(out, rules, list(cells), chunk_text(rules, cells))
    return cells


def checked_cells(rules: ChunkRules, rows: Sequence[Mapping[str, Any]]
                  ) -> dict[int, list[str]]:
    """A task's rows (dicts by column: evaluate.evaluate_point) as cell texts by point id,
    held to the rules a resume applies (_row_cells) before they go anywhere: a task's row that
    breaks them comes from other code on the workers (SweepError)."""
    try:
        return dict(_row_cells(r, rules) for r in rows)
    except _Refused as exc:
        raise SweepError(None, f"a task returned a row the sweep cannot take ({exc}): do "
                               "the workers run this version of stewart-sim?") from None


def chunk_text(rules: ChunkRules, cells: Mapping[int, Sequence[str]]) -> bytes:
    """The bytes of a chunk file after its first line: the header and the rows."""
    return csv_text(rules.columns, cells.values()).encode()


def check_task_text(rules: ChunkRules, sent: Sequence[int], got: Sequence[int],
                    body: bytes) -> None:
    """A worker's chunk text (evaluate_task's) as far as its form shows, before it is written:
    the ids it names are those sent, in order, and the text is CSV with the sweep's columns and
    a row for each of them, in that order. What the rows say was checked on the worker, and
    is checked again when the chunk is read back (merge_chunks). SweepError else: the workers
    run other code."""
    problem = None
    if list(got) != list(sent):
        problem = "the rows of other points"
    else:
        try:
            records = csv.reader(textio.StringIO(body.decode("utf-8"), newline=""))
            head = next(records, None)
            first = [r[0] if r else "" for r in records]
        except (UnicodeDecodeError, csv.Error) as exc:
            problem = f"text that is not UTF-8 CSV ({exc})"
        else:
            if head is None or tuple(head) != rules.columns:
                problem = "rows with other columns than the sweep's"
            elif first != [str(pid) for pid in sent]:
                problem = f"{len(first)} rows that are not those of its {len(sent)} points"
    if problem is not None:
        raise SweepError(None, f"a task returned {problem}: do the workers run this version of "
                               "stewart-sim?")


def write_chunk_text(out: Path, rules: ChunkRules, ids: Sequence[int], body: bytes) -> Path:
    """Write a chunk file of the rows `body` (chunk_text) of the points `ids`, atomically and
    durably: its first line (the sweep's fingerprint, the rows, the body's SHA-256), then the
    body. Returns its path."""
    head = f"{MAGIC} {rules.fingerprint} {len(ids)} {hashlib.sha256(body).hexdigest()}\n"

    def write(fh) -> None:
        fh.write(head.encode() + body)
        fh.flush()
        os.fsync(fh.fileno())

    path = atomic_write(chunk_path(out, min(ids)), write, binary=True)
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)  # the rename itself survives a crash
    finally:
        os.close(fd)
    return path


def resume_rows(out: Path, rules: ChunkRules, notice: Callable[[str], None]
                ) -> dict[int, list[str]]:
    """The rows of every chunk in `out` that passes the rules, by point id (cell texts); each
    chunk refused is moved to DIR/refused/ and `notice` gets one line naming it and why."""
    rows: dict[int, list[str]] = {}
    for _, got in _accepted(out, rules, notice, rows.__contains__):
        rows.update(got)
    return rows


def resume_ledger(out: Path, rules: ChunkRules, notice: Callable[[str], None]) -> Ledger:
    """resume_rows without the rows: which points the accepted chunks hold."""
    ledger = Ledger(len(rules.axes), rules.first)
    for path, got in _accepted(out, rules, notice, ledger.has):
        ledger.add(path, got.keys())
    return ledger


def _accepted(out: Path, rules: ChunkRules, notice: Callable[[str], None],
              seen: Callable[[int], bool]) -> Iterator[tuple[Path, dict[int, list[str]]]]:
    """Each chunk in `out` that passes the rules with its rows, in name order; `seen` tells a
    point an earlier chunk holds (the caller records each chunk before the next is read)."""
    for path in sorted((out / CHUNKS).glob("part-*.csv")):
        try:
            got = _read(path, rules)
            again = sorted(pid for pid in got if seen(pid))
            if again:
                raise _Refused(f"point {again[0]} is in an earlier chunk too")
        except _Refused as exc:
            where = _set_aside(out, path)
            notice(f"{_printable(str(path))}: refused ({exc}); moved to "
                   f"{_printable(str(where))}, its points are computed again")
            continue
        yield path, got


def merge_chunks(out: Path, rules: ChunkRules, ledger: Ledger,
                 more: Sequence[tuple[ChunkRules, Ledger]] = (), part: str | None = None
                 ) -> tuple[int, int]:
    """Write DIR/sweep.csv, all or nothing, from the ledger's chunk files: each read again and
    held to the rules again (a file changed since it was recorded stops the merge), rows in
    point order; returns (rows, rows with status "error"). `more`: further parts of the sweep,
    each with its rules and ledger, whose ids follow the part before (a refinement round's:
    stewart_sim/studies/sweep/adaptive.py), their rows after; `part`: the name of a last column
    whose cell is the index of the row's part (0 for `ledger`'s)."""
    status = rules.columns.index("status")
    parts = [(rules, ledger), *more]
    counts = [0, 0]

    def rows() -> Iterator[list[str]]:
        last = -1
        for k, (r, book) in enumerate(parts):
            for pid, row in ledger_rows(book, r):
                if pid <= last:
                    raise SweepError(None, f"point {pid} twice in the chunk files of {out}")
                last = pid
                counts[0] += 1
                counts[1] += row[status] != "ok"
                yield row if part is None else [*row, str(k)]

    cols = rules.columns if part is None else (*rules.columns, part)
    write_table(out, cols, rows())
    held = sum(book.count for _, book in parts)
    if counts[0] != held:
        raise SweepError(None, f"{out}: {counts[0]} rows merged from chunk files that held "
                               f"{held}")
    return counts[0], counts[1]


def ledger_rows(ledger: Ledger, rules: ChunkRules) -> Iterator[tuple[int, list[str]]]:
    """The rows of the ledger's files by point id (cell texts), each file read again and held to
    the rules again: a file is read when the reader reaches its first point, and dropped after
    its last (chunks of a run hold runs of ids: few at once)."""
    files = sorted(ledger.files, key=lambda f: f[0])
    heap: list[tuple[int, int, int, list[tuple[int, list[str]]]]] = []  # pid, file, at, rows
    nxt = 0
    while heap or nxt < len(files):
        while nxt < len(files) and (not heap or files[nxt][0] <= heap[0][0]):
            first, last, count, path = files[nxt]
            got = sorted(_reread(path, rules).items())
            if (got[0][0], got[-1][0], len(got)) != (first, last, count):
                raise SweepError(None, f"{path}: changed during the sweep (other points)")
            heapq.heappush(heap, (first, nxt, 0, got))
            nxt += 1
        pid, k, at, got = heapq.heappop(heap)
        yield pid, got[at][1]
        if at + 1 < len(got):
            heapq.heappush(heap, (got[at + 1][0], k, at + 1, got))


def _reread(path: Path, rules: ChunkRules) -> dict[int, list[str]]:
    """A recorded chunk's rows, held to the rules again."""
    try:
        return _read(path, rules)
    except _Refused as exc:
        raise SweepError(None, f"{_printable(str(path))}: changed during the sweep ({exc})"
                         ) from None


class _Refused(Exception):
    """Why a chunk file cannot be resumed from (its text is the reason)."""


def _set_aside(out: Path, path: Path) -> Path:
    """Move a refused chunk to DIR/refused/ (replacing one of the same name)."""
    where = out / REFUSED / path.name
    try:
        where.parent.mkdir(exist_ok=True)
        os.replace(path, where)
    except OSError as exc:
        raise OutputError(f"cannot move the refused chunk {path} to {where}: "
                          f"{exc.strerror or exc}") from None
    return where


def _read(path: Path, rules: ChunkRules) -> dict[int, list[str]]:
    """The rows of one chunk file, by point id; _Refused says why not."""
    head, n, digest, body = _read_bounded(path, rules)
    if hashlib.sha256(body).hexdigest() != digest:
        raise _Refused("its rows do not match its checksum (damaged or edited)")
    try:
        text = body.decode("utf-8")
        records = list(csv.reader(textio.StringIO(text, newline="")))
    except UnicodeDecodeError as exc:
        raise _Refused(f"not UTF-8 text at byte {len(head) + exc.start}") from None
    except csv.Error as exc:
        raise _Refused(f"not CSV: {exc}") from None
    if not records or tuple(records[0]) != rules.columns:
        raise _Refused("its columns are not the sweep's")
    if len(records) - 1 != n:
        raise _Refused(f"{len(records) - 1} rows, not the {n} its first line declares")
    if csv_text(rules.columns, records[1:]) != text:
        raise _Refused("not CSV as the sweep writes it (quoting, line ends)")
    rows: dict[int, list[str]] = {}
    for row in records[1:]:
        pid = _check_row(row, rules)
        if pid in rows:
            raise _Refused(f"point {pid} twice")
        rows[pid] = row
    if path.name != f"part-{min(rows):09d}.csv":
        raise _Refused(f"its first point is {min(rows)}, not the one its name gives")
    return rows


def _read_bounded(path: Path, rules: ChunkRules) -> tuple[bytes, int, str, bytes]:
    """A chunk's first line, the rows and checksum it declares, and the bytes after it, read
    no further than those rows can take."""
    try:  # no link followed, and a FIFO's open does not wait for a writer
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as exc:
        raise _Refused("a symbolic link" if os.path.islink(path)
                       else f"cannot be read: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "rb") as fh:
            size = os.fstat(fh.fileno())
            if not stat.S_ISREG(size.st_mode):
                raise _Refused("not a regular file")
            head = fh.readline(_HEAD_BYTES)
            n, digest = _header(head, rules)
            limit = (n + 1) * ROW_BYTES
            if size.st_size - len(head) > limit:
                raise _Refused(f"{size.st_size:,} bytes: more than {n} rows can take")
            body = fh.read(limit + 1)
    except OSError as exc:
        raise _Refused(f"cannot be read: {exc.strerror or exc}") from None
    if len(body) > limit:
        raise _Refused(f"more than {limit:,} bytes after its first line (it grew)")
    return head, n, digest, body


def _header(head: bytes, rules: ChunkRules) -> tuple[int, str]:
    """The rows and checksum its first line declares, checked against the rules."""
    words = head.rstrip(b"\n").split(b" ")
    magic = MAGIC.encode()
    if not head.endswith(b"\n") or len(words) != 7 or b" ".join(words[:4]) != magic:
        raise _Refused(f"its first line is not '{MAGIC} FINGERPRINT ROWS SHA256' (not a "
                       "chunk file of this version)")
    fingerprint, rows, digest = (w.decode("ascii", "replace") for w in words[4:])
    if fingerprint != rules.fingerprint:
        raise _Refused("written for another sweep (its fingerprint is not this sweep's)")
    if not _ID.fullmatch(rows) or not 1 <= int(rows) <= rules.max_rows:
        raise _Refused(f"its first line declares {_short(rows)} rows: 1 to {rules.max_rows} "
                       "(the grid's batch) expected")
    if not _HEX.fullmatch(digest):
        raise _Refused("its first line's checksum is not 64 hex digits")
    return int(rows), digest


def _check_row(row: list[str], rules: ChunkRules) -> int:
    """The point id of a row of cell texts (a chunk file's) that passes the rules
    (_check_values); _Refused names the row's fault."""
    cols = rules.columns
    if len(row) != len(cols):
        raise _Refused(f"a row of {len(row)} cells, not {len(cols)}")
    if not _ID.fullmatch(row[0]):
        raise _Refused(_not_a_point(row[0], rules))
    pid, k = int(row[0]), rules.results_from
    _check_values(rules, pid, tuple(row[1:k - 2]), row[k - 2], row[k - 1],
                  _numbers(pid, cols[k:], row[k:]))
    return pid


def _numbers(pid: int, names: Sequence[str], texts: Sequence[str]) -> Iterator[float]:
    """A row's result texts as numbers, each written as repr writes it (the text is the
    value), read as they are asked for."""
    for name, text in zip(names, texts):
        try:
            value = float(text)
        except ValueError:
            raise _Refused(f"point {pid}: {name} = {_short(text)} is not a number") from None
        if repr(value) != text:
            raise _Refused(f"point {pid}: {name} = {_short(text)} is not written as the sweep "
                           "writes numbers")
        yield value


def _row_cells(row: Mapping[str, Any], rules: ChunkRules) -> tuple[int, list[str]]:
    """A task's row (a dict by column: evaluate.evaluate_point) as its point id and cell
    texts, held to the rules first (_check_values); its results must be floats (each then
    written as repr writes it, what _check_row takes back)."""
    cols, k = rules.columns, rules.results_from
    pid, status, error = row["point"], row["status"], row["error"]
    if (not isinstance(pid, (int, np.integer)) or isinstance(pid, bool)
            or not isinstance(status, str) or not isinstance(error, str)):
        raise _Refused(f"a row whose point, status or error is not of the sweep's types "
                       f"({_short(repr(pid))})")
    pid = int(pid)
    values = [row[c] for c in cols[k:]]
    if not all(type(v) is float for v in values):   # the usual case, checked at once
        for name, v in zip(cols[k:], values):
            if not isinstance(v, (float, np.floating)):
                raise _Refused(f"point {pid}: {name} = {_short(repr(v))} is not a number")
        values = [float(v) for v in values]
    axes = tuple(cell(row[c]) for c in cols[1:k - 2])
    _check_values(rules, pid, axes, status, error, values)
    return pid, [str(pid), *axes, status, error, *map(repr, values)]


def _check_values(rules: ChunkRules, pid: int, axes: tuple[str, ...], status: str,
                  error: str, results: Iterable[float]) -> None:
    """The rules of a row past its form (one set, for the texts a resume reads and the values
    a task returns), in this order: a point of the sweep, the grid's axis values (as cells),
    status "ok" with plausible results (evaluate.result_problem) and no error text, or "error"
    with its text and NaN results."""
    last = rules.first + len(rules.axes) - 1
    if not rules.first <= pid <= last:
        raise _Refused(_not_a_point(str(pid), rules))
    if axes != rules.axes[pid - rules.first]:
        raise _Refused(f"point {pid}: its axis values are not the grid's")
    names = rules.columns[rules.results_from:]
    if status == "error":
        if not error or not all(math.isnan(v) for v in results):
            raise _Refused(f"point {pid}: an error row needs its text and NaN results")
        return
    if status != "ok" or error:
        raise _Refused(f"point {pid}: status {_short(status)} (ok or error, the text only "
                       "with error)")
    for name, value, (low, high) in zip(names, results, rules.bounds):
        if low <= value <= high and math.isfinite(value):
            continue      # plausible whatever the result (result_problem's doc)
        problem = result_problem(name, value, rules.drive)
        if problem is not None:
            raise _Refused(f"point {pid}: {name} = {_short(repr(value))}: {problem}")


def _not_a_point(text: str, rules: ChunkRules) -> str:
    return (f"a row for point {_short(text)}, not a point of the sweep ({rules.first} to "
            f"{rules.first + len(rules.axes) - 1})")


def _printable(text: str) -> str:
    """A file name for a line on the terminal: control characters escaped."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def _short(text: str) -> str:
    """A cell for a message: quoted, control characters escaped, cut to 40 characters."""
    return repr(text if len(text) <= 40 else text[:37] + "...")
