"""Trajectory and result files (CSV, the contract's columns), written atomically at full precision."""
from __future__ import annotations

import csv
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import TrajectoryError

POSE = ("x", "y", "z", "thx", "thy", "thz")
TRAJECTORY_COLUMNS = ("t", *POSE, *(f"d{c}" for c in POSE), *(f"dd{c}" for c in POSE))
FORCE_COLUMNS = ("t", *(f"sigma{i}" for i in range(1, 7)))


def named_array(columns: dict[str, np.ndarray]) -> np.ndarray:
    """A structured array with one float64 field per column (like fmpy's simulate_fmu result)."""
    n = len(next(iter(columns.values())))
    out = np.empty(n, dtype=[(name, "f8") for name in columns])
    for name, values in columns.items():
        out[name] = values
    return out


def write_csv(path: str | Path, table: np.ndarray) -> Path:
    """Write a structured array as CSV with repr-exact floats; the old file survives a failure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(table.dtype.names)
            for row in table.tolist():
                w.writerow([repr(float(v)) for v in row])
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; results are for everyone
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise
    return path


def read_trajectory(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read a trajectory CSV: returns t (N,), q, qd, qdd (N, 6); errors name the row and column."""
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise TrajectoryError(f"{path}: cannot read trajectory: {exc.strerror}") from None
    if not rows:
        raise TrajectoryError(f"{path}: empty file, expected header {','.join(TRAJECTORY_COLUMNS)}")
    header = tuple(c.strip() for c in rows[0])
    if header != TRAJECTORY_COLUMNS:
        missing = [c for c in TRAJECTORY_COLUMNS if c not in header]
        extra = [c for c in header if c not in TRAJECTORY_COLUMNS]
        raise TrajectoryError(
            f"{path}: header must be {','.join(TRAJECTORY_COLUMNS)}; "
            f"missing {missing or 'none'}, unexpected {extra or 'none'}"
            + ("" if missing or extra else ", columns out of order"))
    if len(rows) < 2:
        raise TrajectoryError(f"{path}: no samples after the header")
    data = np.empty((len(rows) - 1, len(TRAJECTORY_COLUMNS)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(TRAJECTORY_COLUMNS):
            raise TrajectoryError(f"{path}: line {r} has {len(row)} fields, expected {len(TRAJECTORY_COLUMNS)}")
        for c, cell in enumerate(row):
            try:
                data[r - 2, c] = float(cell)
            except ValueError:
                raise TrajectoryError(
                    f"{path}: line {r}, column '{TRAJECTORY_COLUMNS[c]}': not a number: {cell!r}") from None
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        raise TrajectoryError(
            f"{path}: line {r + 2}, column '{TRAJECTORY_COLUMNS[c]}': non-finite value {data[r, c]}")
    t = data[:, 0]
    if np.any(np.diff(t) <= 0):
        r = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 3
        raise TrajectoryError(f"{path}: line {r}, column 't': time must increase strictly")
    return t, data[:, 1:7].copy(), data[:, 7:13].copy(), data[:, 13:19].copy()


def trajectory_table(t, q, qd, qdd) -> np.ndarray:
    """The trajectory as a structured array with the contract's columns."""
    cols = np.column_stack([t, q, qd, qdd])
    return named_array({name: cols[:, k] for k, name in enumerate(TRAJECTORY_COLUMNS)})


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
