"""Physical bounds of everything that enters the emulated device.

The setpoints' bounds are the device's capability (controller.capability.Capability, the one
home of what the mechanism and its drives can do: its stroke inset by the servo's overshoot
room, its `setpoint_*` headroom over the drives); the parameters' ranges (`ParamRanges`, built
by `param_ranges`) and the stream rates' check are here. The motor's ratings are those of the
scene's [controller.motor] table; Kf = Kt zeta / r (N/A) and Ke' = Ke zeta / r (V s/m) are the
drive's force and back-EMF constants at the rack.

=================  ==========================================  ===========================
what               bound                                       micro-manipulator scene
=================  ==========================================  ===========================
setpoint length    [leg_min + room, leg_max - room] (below)    [0.0747, 0.1853] m
setpoint rate      |ldot| <= 10 V_max / Ke' (no-load speed)    3 m/s   (V_max/Ke' = 0.3 m/s)
feed-fwd force     |F| <= 50 Kf I_max (the drive's peak)       8 kN    (Kf I_max = 160 N)
force rate         |dF/dt| <= 10 Kf V_max / L (di/dt limit)    3.84e7 N/s
CTRL_KP/KI/KD      [0, 10 x the designed gain]                 see PARAM_VALUE of the design
DRV_V_LIMIT        [0.01, 1] x the motor's voltage_limit       [0.24, 24] V
DRV_I_LIMIT        [0.01, 1] x the motor's current_limit       [0.02, 2] A
WDG_TIMEOUT        [0.01, 10] s                                (also the constructor's)
SP_COND_MAX        (1, 1e4]
pose position      |x|, |y|, |z| <= pose_position_max (below)  0.351 m (platform frame)
pose angles        |thx|, |thy|, |thz| <= pi                   pi rad
SR_* (streams)     [0, min(controller rate, 1000)] Hz          [0, 1000] Hz
=================  ==========================================  ===========================

The room kept free at each end of the stroke is the servo's own overshoot
(controller.capability.overshoot_room) with the static leg force the drive holds at home:
room = m v0^2 / (2 (Kf I_max - F_hold)), 4.7 mm of the micro-manipulator's 120 mm stroke (its
worst full-stroke step overshoots 2.7 mm). It is a read-only fact a host reads (SP_LEN_MIN,
SP_LEN_MAX), not a hidden change of dynamics near the stops.

The setpoint bounds are also reported as read-only parameters (SP_RATE_MAX, SP_FORCE_MAX,
SP_FRATE_MAX, SP_LEN_MIN, SP_LEN_MAX) so a host can read them with PARAM_REQUEST_LIST.
Out-of-range values are refused: a STATUSTEXT names the value and the bound.

A POSE_SETPOINT's position is bounded by where the frame's origin can be at all: C's origin is
within |a_i| + l_i + |p_i| of the base's origin for every leg, so within max |a_i| + leg_max +
max |p_i|; the moving frame's origin (pivot or tool, on the platform) adds its offset from C's
origin, and the fixed frame (user, on the base) its offset from N's; no bound (inf) without a
stroke. Past it no leg length can reach the pose; the bound refuses garbage before any
arithmetic, the stroke check refuses the rest.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from controller.design import PidGains
from controller.drive import Motor

GAIN_FACTOR = 10.0      # gains up to this many times the design's
LIMIT_FLOOR = 0.01      # drive limits down to this fraction of the motor's rating
WATCHDOG_RANGE = (0.01, 10.0)   # s
COND_MAX_LIMIT = 1e4
STREAM_MAX = 1000.0     # Hz


@dataclass(frozen=True)
class ParamRanges:
    """What a PARAM_SET may set (see the module doc): the gains (kp, ki, kd) up to gain_max,
    the drive limits, the watchdog, SP_COND_MAX's upper end and the stream rates' cap."""

    gain_max: dict[str, float]
    voltage_range: tuple[float, float]
    current_range: tuple[float, float]
    watchdog_range: tuple[float, float] = WATCHDOG_RANGE
    cond_max_limit: float = COND_MAX_LIMIT
    stream_max: float = STREAM_MAX


def param_ranges(motor: Motor, gains: PidGains) -> ParamRanges:
    """The ranges of a device whose motor's ratings are `motor` and whose designed gains are
    `gains` (controller.design.PidGains)."""
    return ParamRanges(
        gain_max={k: GAIN_FACTOR * getattr(gains, k) for k in ("kp", "ki", "kd")},
        voltage_range=(LIMIT_FLOOR * motor.voltage_limit, motor.voltage_limit),
        current_range=(LIMIT_FLOOR * motor.current_limit, motor.current_limit))


def check_rate(hz: Any) -> str | None:
    """Why `hz` is no rate (a finite number >= 0), or None."""
    if isinstance(hz, bool) or not isinstance(hz, (int, float)) or not math.isfinite(hz) or hz < 0:
        return f"rate must be a finite number >= 0 Hz, got {hz!r}"
    return None


def in_range(lo: float, hi: float, unit: str = "", lo_open: bool = False):
    """A parameter check: None when lo <= x <= hi (lo < x with lo_open), else why not."""
    def check(x: float) -> str | None:
        ok = (lo < x if lo_open else lo <= x) and x <= hi
        if ok:
            return None
        left = "(" if lo_open else "["
        return f"must be in {left}{lo:.4g}, {hi:.4g}]{(' ' + unit) if unit else ''}"
    return check


def read_only(x: float) -> str | None:
    return "read-only (a bound of the device)"


POSE_ANGLE_MAX = math.pi   # rad: a POSE_SETPOINT's angles (every rotation has angles within it)


def pose_position_max(model: Any, change: Any) -> float:
    """m, the largest |coordinate| of a pose's position in a frame whose (mov, fix) of
    stewart_fmu.frames.frame_change is `change` (None: the platform's own pose; see the module
    doc): inf when the scene has no stroke."""
    if model.leg_max is None or not math.isfinite(model.leg_max):
        return math.inf
    # math.hypot on lists: a setpoint pays this, and numpy's per-call cost is tens of us
    reach = (max(math.hypot(*a) for a in model.base_joints.tolist()) + model.leg_max
             + max(math.hypot(*p) for p in model.platform_joints.tolist()))
    if change is None:
        return reach
    offsets = list(change)
    return reach + math.hypot(*offsets[:3]) + math.hypot(*offsets[6:9])


def pose_rate_max(leg_rate: float, cond_max: float, char_length: float, change: Any,
                  thy: float) -> tuple[float, float]:
    """(m/s, rad/s), the largest |position rate| and |Euler-angle rate| of a POSE_SETPOINT in
    a frame whose (mov, fix) of stewart_fmu.frames.frame_change is `change` (None: the
    platform's own) and whose pitch is `thy`, when its legs' rates are within `leg_rate`
    (the capability's setpoint_rate) at a pose of cond(J) <= `cond_max` (SP_COND_MAX).

    ldot = J_s nu_s with J_s the scaled Jacobian (kinematics.condition_number) and
    nu_s = (v, Lc omega); every row of J_s starts with a unit vector, so s_max(J_s) >= 1 and
    |nu_s| <= cond |ldot| <= cond_max sqrt(6) leg_rate = S: |v| <= S, |omega| <= S / Lc. The
    frame's origin, |d| off C's, moves at most S (1 + |d| / Lc) (the user frame's rotation keeps
    norms) and turns with the platform; Euler rates of R = Rz Ry Rx are Rz^T omega through
    [[c, 0, 0], [0, 1, 0], [-s, 0, 1]] (c, s of thy), so each is at most
    |omega| (1 + |s|) / |c| (inf at gimbal lock). Past these no leg rate within the bound can
    give the pose's rates; inside them the LEG_SETPOINT's own rate check decides."""
    s = cond_max * math.sqrt(6.0) * leg_rate
    d = 0.0 if change is None else math.hypot(*list(change)[:3])
    omega = s / char_length
    c = abs(math.cos(thy))
    turn = omega * (1.0 + abs(math.sin(thy))) / c if c > 0.0 else math.inf
    return s * (1.0 + d / char_length), turn
