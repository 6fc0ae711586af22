"""A POSE_SETPOINT's own checks, and the LEG_SETPOINT it becomes.

In order (the first failure is the reason): no flag but STEWART_POSE_SETPOINT_FLAG_HOLD; a
frame of STEWART_FRAME; with HOLD nothing more (the pose is ignored, as LEG_SETPOINT's lengths
are). Else every pose field finite, each position coordinate within the frame's
hil.input_bounds.pose_position_max and each angle within POSE_ANGLE_MAX; then the platform's
pose (stewart_fmu.frames.to_platform) and its leg lengths (the core's leg_state). The result is a
LEG_SETPOINT of the same time and sequence with those lengths, no rate and no force, which the
device checks (hil.setpoint.check_setpoint: stroke, a pose, cond(J), cones and clearances) and
follows as any other: one check path, whichever message a setpoint came in.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil.input_bounds import POSE_ANGLE_MAX, pose_position_max
from stewart_fmu.dynamics import leg_state
from stewart_fmu.frames import frame_change, to_platform
from stewart_fmu.model import Model

#: STEWART_FRAME value -> the frame's name in stewart_fmu.frames (reach_params.FRAME_NAMES).
FRAMES = {ms.STEWART_FRAME_PLATFORM: "platform", ms.STEWART_FRAME_PIVOT: "pivot",
          ms.STEWART_FRAME_TOOL: "tool", ms.STEWART_FRAME_USER: "user"}
FIELDS = ("x", "y", "z", "thx", "thy", "thz")
_HOLD = ms.STEWART_POSE_SETPOINT_FLAG_HOLD
_ZERO6 = [0.0] * 6


def pose_of(msg: Any) -> np.ndarray:
    """A POSE_SETPOINT's pose (x, y, z, thx, thy, thz) as given, in its frame."""
    return np.array([getattr(msg, f) for f in FIELDS], dtype=float)


def check_pose(msg: Any, model: Model) -> str | None:
    """Why a POSE_SETPOINT is refused before any arithmetic on its pose, or None."""
    if msg.flags & ~_HOLD:
        return f"flags 0x{msg.flags:02x}: unknown bits 0x{msg.flags & ~_HOLD:02x}"
    frame = FRAMES.get(msg.frame)
    if frame is None:
        known = ", ".join(f"{k} {n}" for k, n in FRAMES.items())
        return f"frame {msg.frame} unknown (known: {known})"
    if msg.flags & _HOLD:
        return None
    pose = pose_of(msg)
    for name, v in zip(FIELDS, pose):
        if not math.isfinite(v):
            return f"non-finite pose {name}"
    reach = pose_position_max(model, frame_change(model, frame))
    for name, v, bound, unit in zip(FIELDS, pose, (reach,) * 3 + (POSE_ANGLE_MAX,) * 3,
                                    ("m",) * 3 + ("rad",) * 3):
        if not abs(v) <= bound:
            return f"pose {name} {v:.4g} {unit} in frame {frame}, bound {bound:.4g} {unit}"
    return None


def leg_setpoint(msg: Any, model: Model) -> tuple[str | None, Any, np.ndarray | None]:
    """(why a POSE_SETPOINT is refused or None, the LEG_SETPOINT it becomes, the platform's
    pose: None with HOLD)."""
    why = check_pose(msg, model)
    if why is not None:
        return why, None, None
    if msg.flags & _HOLD:
        return None, ms.MAVLink_leg_setpoint_message(
            msg.time_usec, msg.sequence, _ZERO6, _ZERO6, ms.STEWART_SETPOINT_FLAG_HOLD), None
    q = to_platform(model, pose_of(msg), FRAMES[msg.frame])
    lengths, _, _ = leg_state(model, q, np.zeros(6))      # the core's, one pose per call
    return None, ms.MAVLink_leg_setpoint_message(
        msg.time_usec, msg.sequence, [float(v) for v in lengths], _ZERO6, 0), q
