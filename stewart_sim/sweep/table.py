"""A sweep's files in its output directory: rows land in chunk files as tasks finish (each
written atomically and fsynced, so an interruption at any moment keeps every finished row and no
half row), and are merged, sorted by point id, into one CSV table.

    DIR/sweep.json       the sweep's fingerprint (scene + grid), columns and size
    DIR/chunks/*.csv     one file per finished task
    DIR/sweep.csv        every row so far, one per point, sorted by point id
"""
from __future__ import annotations

import csv
import io as textio
import json
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from stewart_fmu.errors import SweepError
from stewart_fmu.io import atomic_write, write_text

TABLE = "sweep.csv"
MANIFEST = "sweep.json"
CHUNKS = "chunks"


def cell(v: Any) -> str:
    """A value as CSV text: floats repr-exact, everything else as str."""
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def csv_text(columns: Sequence[str], rows: Iterable[Mapping[str, Any] | Sequence[str]],
             header: bool = True) -> str:
    """Rows (dicts by column, or lists of cell texts) as CSV text."""
    buf = textio.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    if header:
        w.writerow(columns)
    for r in rows:
        w.writerow([cell(r[c]) for c in columns] if isinstance(r, Mapping) else r)
    return buf.getvalue()


def open_sweep(out: Path, fingerprint: str, columns: Sequence[str], total: int) -> None:
    """Start or resume the sweep in `out`; a directory holding another sweep is refused."""
    manifest = out / MANIFEST
    info = {"fingerprint": fingerprint, "columns": list(columns), "points": total}
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise SweepError(None, f"{manifest}: unreadable ({exc}); remove it or choose another --out") from None
        if old != info:
            raise SweepError(None, f"{out} holds the rows of another sweep (different scene or "
                                   f"grid): choose another --out or remove the directory")
        return
    (out / CHUNKS).mkdir(parents=True, exist_ok=True)
    write_text(manifest, json.dumps(info, indent=1) + "\n")


def write_chunk(out: Path, columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> Path:
    """Write the rows of one finished task as a chunk file, atomically and durably."""
    text = csv_text(columns, rows)
    first = min(int(r["point"]) for r in rows)

    def write(fh) -> None:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())

    path = atomic_write(out / CHUNKS / f"part-{first:09d}.csv", write)
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)  # the rename itself survives a crash
    finally:
        os.close(fd)
    return path


def chunk_rows(out: Path, columns: Sequence[str]) -> dict[int, list[str]]:
    """Every finished row in the chunk files, by point id (cell texts)."""
    rows: dict[int, list[str]] = {}
    for path in sorted((out / CHUNKS).glob("part-*.csv")):
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            if next(reader, None) != list(columns):
                raise SweepError(None, f"{path}: columns differ from the sweep's; remove the directory")
            for r in reader:
                rows.setdefault(int(r[0]), r)
    return rows


def merge(out: Path, columns: Sequence[str]) -> int:
    """Write DIR/sweep.csv from the chunks, one row per point sorted by id; returns the rows."""
    rows = chunk_rows(out, columns)
    text = csv_text(columns, (rows[k] for k in sorted(rows)))
    write_text(out / TABLE, text)
    return len(rows)


def read_table(path: Path) -> dict[str, np.ndarray]:
    """A sweep table as columns: float arrays where every cell is a number, else strings."""
    with Path(path).open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        cols = list(zip(*reader)) or [()] * len(header)
    out = {}
    for name, cells in zip(header, cols):
        try:
            out[name] = np.array([float(c) for c in cells])
        except ValueError:
            out[name] = np.array(cells, dtype=object)
    return out
