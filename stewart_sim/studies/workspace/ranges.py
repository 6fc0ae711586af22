"""`workspace --ranges` and `--reach`: the travel before the first limit, as tables."""
from __future__ import annotations

import numpy as np

from stewart_fmu.reach import AxisRange, Travel

_UNITS = {"x": "mm", "y": "mm", "z": "mm", "thx": "deg", "thy": "deg", "thz": "deg"}


def _shown(axis: str, value: float) -> float:
    return value * 1e3 if _UNITS[axis] == "mm" else float(np.degrees(value))


def ranges_text(rows: tuple[AxisRange, ...], frame: str) -> str:
    """The datasheet table: per axis the travel from home both ways (mm, deg) and the limit
    that ends each (leg or pair)."""
    lines = [f"travel from home along each axis of the {frame} frame, the others held "
             "(interdependent ranges)",
             f"{'axis':<5} {'minus':>13} {'plus':>13}  {'ends minus':<28} ends plus"]
    for r in rows:
        u = _UNITS[r.axis]
        minus = f"{r.minus_limit} {r.minus_where}".strip() or "none within reach"
        plus = f"{r.plus_limit} {r.plus_where}".strip() or "none within reach"
        lines.append(f"{r.axis:<5} {_shown(r.axis, r.minus):>9.3f} {u:<3} "
                     f"{_shown(r.axis, r.plus):>9.3f} {u:<3}  {minus:<28} {plus}")
    return "\n".join(lines)


def ranges_table(rows: tuple[AxisRange, ...]) -> np.ndarray:
    """The ranges as a CSV table: axis index 0..5 (x .. thz), minus, plus (m or rad), and the
    limits' names and where they bind."""
    out = np.empty(len(rows), dtype=[("axis", object), ("minus", "f8"), ("plus", "f8"),
                                     ("minus_limit", object), ("minus_where", object),
                                     ("plus_limit", object), ("plus_where", object)])
    for k, r in enumerate(rows):
        out[k] = (r.axis, r.minus, r.plus, r.minus_limit, r.minus_where, r.plus_limit,
                  r.plus_where)
    return out


def reach_text(t: Travel, q0: np.ndarray, direction: np.ndarray, frame: str) -> str:
    pose = ",".join(repr(float(v)) for v in q0)
    d = ",".join(repr(float(v)) for v in direction)
    if not t.inside:
        return f"the start pose ({pose}, {frame} frame) is outside the limit {t.limit} at {t.where}"
    stop = f"stopped by {t.limit} at {t.where}" if t.limit else \
        f"no limit within {t.reach!r} (the largest step looked at)"
    return f"largest step {t.step!r} from ({pose}) along ({d}) in the {frame} frame: {stop}"

