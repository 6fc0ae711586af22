"""`workspace --check`: each pose of a CSV against every limit, as the contract's V.csv: the
pose as given, `feasible` (1 or 0), `limit` (the binding limit, empty when feasible), one
margin column per limit the scene and the file have (positive inside), then `where` (the leg,
pair of legs, or obstacle and leg of the binding limit; empty when feasible)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from stewart_fmu.frames import to_platform
from stewart_fmu.io import csv_header, read_table
from stewart_fmu.reach import LIMITS, Engine, where_text

POSE = ("x", "y", "z", "thx", "thy", "thz")
RATES = tuple(f"d{c}" for c in POSE)
ACCELERATIONS = tuple(f"dd{c}" for c in POSE)


def read_poses(path: Path) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Poses (N, 6), and their rates and accelerations when the file has every one of those
    columns (the trajectory's names dx .. ddthz); TrajectoryError naming a missing column or a
    bad row."""
    header = set(csv_header(path, "poses"))
    rates = all(c in header for c in RATES)
    accel = rates and all(c in header for c in ACCELERATIONS)
    columns = POSE + (RATES if rates else ()) + (ACCELERATIONS if accel else ())
    data = read_table(path, columns, "poses")
    return (data[:, :6].copy(), data[:, 6:12].copy() if rates else None,
            data[:, 12:18].copy() if accel else None)


def check_table(engine: Engine, poses: np.ndarray, qd=None, qdd=None,
                frame: str = "platform") -> np.ndarray:
    """The V.csv table of poses given in `frame` (rates and accelerations: of C's pose)."""
    q = to_platform(engine.model, poses, frame)
    res = engine.check(q, qd, qdd)
    present = engine.present(qd is not None, qdd is not None)
    fields = [(c, "f8") for c in POSE] + [("feasible", "i8"), ("limit", object)]
    fields += [(lim.name, "f8") for lim in present] + [("where", object)]
    out = np.empty(len(q), dtype=fields)
    for k, c in enumerate(POSE):
        out[c] = poses[:, k]
    out["feasible"] = res["feasible"].astype(np.int64)
    names = np.array([""] + [lim.name for lim in LIMITS], dtype=object)
    out["limit"] = names[res["binding"].astype(np.int64) + 1]
    for lim in present:
        out[lim.name] = res[lim.name]
    out["where"] = ""
    for k in np.flatnonzero(res["binding"] >= 0):
        b = int(res["binding"][k])
        out["where"][k] = where_text(b, int(res[f"{LIMITS[b].name}_at"][k]))
    return out


def summary(table: np.ndarray, present_names: list[str]) -> str:
    """'N poses: F feasible; binding: stroke_max 12, base_cone 3'."""
    n = len(table)
    counts = {name: int(np.sum(table["limit"] == name)) for name in present_names}
    bound = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
    return f"{n} poses: {int(np.sum(table['feasible']))} feasible" + \
        (f"; binding: {bound}" if bound else "")
