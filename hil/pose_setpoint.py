"""A POSE_SETPOINT's own checks, and the LEG_SETPOINT it becomes.

In order (the first failure is the reason): no flag but STEWART_POSE_SETPOINT_FLAG_HOLD and
_RATE_VALID; a frame of STEWART_FRAME; with HOLD nothing more (the pose and its rate are
ignored, as LEG_SETPOINT's lengths are). Else every pose field finite, each position coordinate
within the frame's hil.input_bounds.pose_position_max and each angle within POSE_ANGLE_MAX; with
RATE_VALID every rate finite and within hil.input_bounds.pose_rate_max (what legs within the
capability's setpoint_rate can give at cond(J) <= SP_COND_MAX). Then the platform's pose
(stewart_fmu.frames.to_platform) and its leg lengths (the core's leg_state); with RATE_VALID
the platform's motion (stewart_fmu.frames.motion_to_platform) and the legs' lengths and rates
(leg_state: the core's Jacobian). The result is a LEG_SETPOINT of the same time and sequence
with those lengths, those rates (its RATE_VALID) or none, and no force, which the device checks
(hil.setpoint.check_setpoint: rates within setpoint_rate, stroke, a pose, cond(J), cones and
clearances) and follows as any other: one check path, whichever message a setpoint came in.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil.input_bounds import POSE_ANGLE_MAX, pose_position_max, pose_rate_max
from stewart_fmu.dynamics import leg_state
from stewart_fmu.errors import StewartError
from stewart_fmu.frames import frame_change, motion_to_platform, to_platform
from stewart_fmu.model import Model

#: STEWART_FRAME value -> the frame's name in stewart_fmu.frames (reach_params.FRAME_NAMES).
FRAMES = {ms.STEWART_FRAME_PLATFORM: "platform", ms.STEWART_FRAME_PIVOT: "pivot",
          ms.STEWART_FRAME_TOOL: "tool", ms.STEWART_FRAME_USER: "user"}
FIELDS = ("x", "y", "z", "thx", "thy", "thz")
RATES = ("dx", "dy", "dz", "dthx", "dthy", "dthz")
_HOLD = ms.STEWART_POSE_SETPOINT_FLAG_HOLD
_RATE = ms.STEWART_POSE_SETPOINT_FLAG_RATE_VALID
_KNOWN = _HOLD | _RATE
_ZERO6 = [0.0] * 6


def pose_of(msg: Any) -> np.ndarray:
    """A POSE_SETPOINT's pose (x, y, z, thx, thy, thz) as given, in its frame."""
    return np.array([getattr(msg, f) for f in FIELDS], dtype=float)


def rate_of(msg: Any) -> np.ndarray:
    """A POSE_SETPOINT's rates (dx, dy, dz, dthx, dthy, dthz) as given, in its frame."""
    return np.array(msg.rate, dtype=float)


def check_pose(msg: Any, model: Model, leg_rate: float, cond_max: float) -> str | None:
    """Why a POSE_SETPOINT is refused before any arithmetic on its pose and rates, or None;
    `leg_rate` and `cond_max` bound the rates (pose_rate_max)."""
    if msg.flags & ~_KNOWN:
        return f"flags 0x{msg.flags:02x}: unknown bits 0x{msg.flags & ~_KNOWN:02x}"
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
    change = frame_change(model, frame)
    reach = pose_position_max(model, change)
    for name, v, bound, unit in zip(FIELDS, pose, (reach,) * 3 + (POSE_ANGLE_MAX,) * 3,
                                    ("m",) * 3 + ("rad",) * 3):
        if not abs(v) <= bound:
            return f"pose {name} {v:.4g} {unit} in frame {frame}, bound {bound:.4g} {unit}"
    if not msg.flags & _RATE:
        return None
    rate = rate_of(msg)
    for name, v in zip(RATES, rate):
        if not math.isfinite(v):
            return f"non-finite rate {name}"
    move, turn = pose_rate_max(leg_rate, cond_max, model.characteristic_length, change,
                               pose[4])
    for name, v, bound, unit in zip(RATES, rate, (move,) * 3 + (turn,) * 3,
                                    ("m/s",) * 3 + ("rad/s",) * 3):
        if not abs(v) <= bound:
            return f"rate {name} {v:.4g} {unit} in frame {frame}, bound {bound:.4g} {unit}"
    return None


def leg_setpoint(msg: Any, model: Model, leg_rate: float,
                 cond_max: float) -> tuple[str | None, Any, np.ndarray | None]:
    """(why a POSE_SETPOINT is refused or None, the LEG_SETPOINT it becomes, the platform's
    pose: None with HOLD); `leg_rate` (m/s, the capability's setpoint_rate) and `cond_max`
    (SP_COND_MAX) bound its rates (check_pose)."""
    why = check_pose(msg, model, leg_rate, cond_max)
    if why is not None:
        return why, None, None
    if msg.flags & _HOLD:
        return None, ms.MAVLink_leg_setpoint_message(
            msg.time_usec, msg.sequence, _ZERO6, _ZERO6, ms.STEWART_SETPOINT_FLAG_HOLD), None
    frame = FRAMES[msg.frame]
    if not msg.flags & _RATE:
        q = to_platform(model, pose_of(msg), frame)
        lengths, _, _ = leg_state(model, q, np.zeros(6))      # the core's, one pose per call
        return None, ms.MAVLink_leg_setpoint_message(
            msg.time_usec, msg.sequence, [float(v) for v in lengths], _ZERO6, 0), q
    try:
        q, qd, _ = motion_to_platform(model, pose_of(msg), rate_of(msg), None, frame)
    except StewartError as exc:          # the platform's pose at gimbal lock: no Euler rates
        return f"rate in frame {frame}: {exc}", None, None
    lengths, rates, _ = leg_state(model, q, qd)               # ldot = J nu, the core's J
    return None, ms.MAVLink_leg_setpoint_message(
        msg.time_usec, msg.sequence, [float(v) for v in lengths], [float(v) for v in rates],
        ms.STEWART_SETPOINT_FLAG_RATE_VALID), q
