"""The checks a LEG_SETPOINT passes before the device follows it, and its optional fields.

In order (the first failure is the reason, legs numbered 1..6): every length, and every rate,
force and force rate its flags declare valid, finite; those within the device's capability
(controller.capability.Capability: setpoint_rate, setpoint_force, setpoint_force_rate); every
length within [SP_LEN_MIN, SP_LEN_MAX] (the capability's stroke, the servo's overshoot room
kept free); a pose with these lengths (forward kinematics by Newton from the last accepted
pose); cond(J) at that pose at most SP_COND_MAX; the pose inside the joint cones and the leg and
obstacle clearances (the capability's `geometric` engine: the one feasibility engine).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from controller.capability import Capability, first_violated
from hil import mavlink_stewart as ms
from stewart_fmu.errors import StewartError
from stewart_fmu.kinematics import condition_number, forward_kinematics
from stewart_fmu.model import Model
from stewart_fmu.reach import LIMITS


def check_setpoint(msg: Any, flags: int, cap: Capability, model: Model, guess: np.ndarray,
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
    why = beyond(msg, flags, cap)
    if why is not None:
        return why, None
    lo, hi = cap.leg_min, cap.leg_max
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
    why = geometry(cap.geometric, pose)
    return (why, None) if why is not None else (None, pose)


def beyond(msg: Any, flags: int, cap: Capability) -> str | None:
    """Why a (finite) setpoint's rate, force or force rate, where its flags declare them valid,
    is beyond the capability's setpoint bounds (legs numbered 1..6), or None."""
    checks = []
    if flags & ms.STEWART_SETPOINT_FLAG_RATE_VALID:
        checks.append(("rate", msg.rate, cap.setpoint_rate, "m/s"))
    if flags & ms.STEWART_SETPOINT_FLAG_FORCE_VALID:
        checks.append(("force", msg.force, cap.setpoint_force, "N"))
    if flags & ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID:
        checks.append(("force rate", msg.force_rate, cap.setpoint_force_rate, "N/s"))
    for what, values, bound, unit in checks:
        a = np.abs(np.asarray(values, dtype=float))
        i = int(np.argmax(a))
        if not a[i] <= bound:
            return f"leg {i + 1} {what} {values[i]:.3g} {unit}, bound {bound:.3g}"
    return None


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
