"""The checks a LEG_SETPOINT passes before the device follows it, and its optional fields.

In order (the first failure is the reason, legs numbered 1..6): every length, and every rate,
force and force rate its flags declare valid, finite; those within the bounds of hil.input_bounds;
every length within [SP_LEN_MIN, SP_LEN_MAX]; a pose with these lengths (forward kinematics by
Newton from the last accepted pose); cond(J) at that pose at most SP_COND_MAX; the pose inside
the joint cones and the leg and obstacle clearances (the engine of Bounds.reach,
controller.capability: the one feasibility engine).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from controller.capability import first_violated
from hil import mavlink_stewart as ms
from hil.input_bounds import Bounds
from stewart_fmu.errors import StewartError
from stewart_fmu.kinematics import condition_number, forward_kinematics
from stewart_fmu.model import Model
from stewart_fmu.reach import LIMITS


def check_setpoint(msg: Any, flags: int, bounds: Bounds, model: Model, guess: np.ndarray,
                   cond_max: float) -> tuple[str | None, np.ndarray | None]:
    """(why the setpoint is refused or None, its pose); `guess` starts forward kinematics."""
    lengths = np.array(msg.length, dtype=float)
    if not np.all(np.isfinite(lengths)):
        return "non-finite length", None
    if flags & ms.STEWART_SETPOINT_FLAG_RATE_VALID and not np.all(np.isfinite(msg.rate)):
        return "non-finite rate", None
    if flags & ms.STEWART_SETPOINT_FLAG_FORCE_VALID and not np.all(np.isfinite(msg.force)):
        return "non-finite force", None
    if (flags & ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID
            and not np.all(np.isfinite(msg.force_rate))):
        return "non-finite force rate", None
    why = bounds.setpoint(msg, flags, ms.STEWART_SETPOINT_FLAG_RATE_VALID,
                          ms.STEWART_SETPOINT_FLAG_FORCE_VALID,
                          ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID)
    if why is not None:
        return why, None
    lo, hi = bounds.leg_min, bounds.leg_max
    bad = [i for i in range(6) if not lo <= lengths[i] <= hi]
    if bad:
        i = bad[0]
        side, bound = ("min", lo) if lengths[i] < lo else ("max", hi)
        return f"leg {i + 1} at {lengths[i]:.4g} m, stroke {side} {bound:.4g}", None
    try:
        pose = forward_kinematics(model, lengths, guess=guess)
    except StewartError:
        return "no pose has these lengths", None
    cond = condition_number(model, pose)
    if not cond <= cond_max:
        return f"near-singular, cond {cond:.3g} > {cond_max:g}", None
    why = geometry(bounds.reach, pose)
    return (why, None) if why is not None else (None, pose)


def geometry(engine: Any, pose: np.ndarray) -> str | None:
    """Why `pose` violates a joint cone or a clearance of `engine` (the limit, the leg or pair,
    the margin), or None (also without an engine)."""
    if engine is None:
        return None
    v = engine.verdict(pose)
    k = first_violated(v.margins)
    if k is None:
        return None
    lim = LIMITS[k]
    return f"{lim.name} at {v.where_of(k)}, margin {v.margins[k]:.3g} {lim.unit}"


def flagged(flags: int, flag: int, values: Any) -> np.ndarray | None:
    """A setpoint's field as an array when its validity flag is set, else None."""
    return np.array(values, dtype=float) if flags & flag else None
