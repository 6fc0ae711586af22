"""A sweep's files in its output directory: rows land in chunk files as tasks finish (each
written atomically and fsynced, so an interruption at any moment keeps every finished row and no
half row: stewart_sim/studies/sweep/chunks.py), and are merged, sorted by point id, into one CSV
table.

    DIR/sweep.json       the sweep's fingerprint (scene + grid), columns and size
    DIR/chunks/*.csv     one file per finished task
    DIR/refused/*.csv    chunks a resumed sweep refused (set aside, their points computed again)
    DIR/sweep.csv        every row so far, one per point, sorted by point id (written atomically)
"""
from __future__ import annotations

import csv
import io as textio
import json
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from stewart_fmu.budget import InputFileError, read_input
from stewart_fmu.errors import SweepError
from stewart_fmu.io import atomic_write, write_text

TABLE = "sweep.csv"
MANIFEST = "sweep.json"
CHUNKS = "chunks"
MANIFEST_BYTES = 1024 * 1024   # sweep.json is a fingerprint and the column names


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
    if os.path.lexists(manifest):
        try:
            old = json.loads(read_input(manifest, MANIFEST_BYTES).decode("utf-8"))
        except (InputFileError, ValueError, RecursionError) as exc:
            reason = exc.reason if isinstance(exc, InputFileError) else exc
            raise SweepError(None, f"{manifest}: unreadable ({reason}); remove it or choose another --out") from None
        if old != info:
            raise SweepError(None, f"{out} holds the rows of another sweep (different scene or "
                                   f"grid): choose another --out or remove the directory")
        return
    (out / CHUNKS).mkdir(parents=True, exist_ok=True)
    write_text(manifest, json.dumps(info, indent=1) + "\n")


def merge(out: Path, columns: Sequence[str], rows: Mapping[int, Sequence[str]]) -> int:
    """Write DIR/sweep.csv, all or nothing, from `rows` (cell texts by point id, checked by
    the caller), one row per point sorted by id; returns the rows."""
    write_table(out, columns, (rows[k] for k in sorted(rows)))
    return len(rows)


def write_table(out: Path, columns: Sequence[str], rows: Iterable[Sequence[str]]) -> Path:
    """Write DIR/sweep.csv, all or nothing, from rows of cell texts as they come (in order,
    checked by the caller): the table is never held in memory whole."""
    def write(fh) -> None:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(columns)
        w.writerows(rows)

    return atomic_write(out / TABLE, write)


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
