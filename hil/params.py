"""The emulated device's parameter table: names, what each reads and sets, its bounds.

Every parameter has a range (hil.input_bounds.ParamRanges): a PARAM_SET out of range, or of a type
other than REAL32 and the integer types up to 32 bits in MAVLink's bytewise encoding
(hil.protocol), is refused with the unchanged PARAM_VALUE and a STATUSTEXT. The setpoint bounds,
the device's capability (controller.capability.Capability), are read-only parameters
(SP_LEN_MIN/MAX, SP_RATE_MAX, SP_FORCE_MAX, SP_FRATE_MAX).

  CTRL_KP, CTRL_KI, CTRL_KD     PID gains, [0, GAIN_FACTOR x designed]
  DRV_V_LIMIT, DRV_I_LIMIT      motor voltage and current limits, up to the ratings
  WDG_TIMEOUT                   the watchdog (s)
  SP_COND_MAX                   cond(J) above which a setpoint counts as singular
  SR_*                          telemetry stream rates (Hz, 0 = off)
  SP_*                          the setpoint bounds (read-only)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

from controller.capability import Capability
from hil import input_bounds, protocol
from hil import mavlink_stewart as ms
from hil.servo import Servo
from hil.downlink import TELEMETRY
from stewart_fmu.reach_params import COND_LIMIT

COND_MAX = COND_LIMIT      # default SP_COND_MAX: the engine's cond(J) limit (scaled)
#: The parameters hil.servo.Servo.restore_design brings back to the design after a numerical
#: fault: the PID gains and the drive limits.
DESIGN_PARAMS = ("CTRL_KP", "CTRL_KI", "CTRL_KD", "DRV_V_LIMIT", "DRV_I_LIMIT")
#: Parameter names of the stream rates.
STREAM_PARAMS = {"SR_SYS_STATUS": "SYS_STATUS", "SR_LEG_STATE": "LEG_STATE",
                 "SR_DRIVE_STATUS": "DRIVE_STATUS", "SR_ATTITUDE": "ATTITUDE_QUATERNION",
                 "SR_POSITION": "LOCAL_POSITION_NED"}


@dataclass
class Param:
    """One parameter: read it, set it, and why a value is refused (None: acceptable)."""

    get: Callable[[], float]
    set: Callable[[float], None]
    check: Callable[[float], str | None]


@dataclass
class Settings:
    """The device's settings that are not the drives': the watchdog (s), SP_COND_MAX and the
    telemetry rates (Hz, by stream name of hil.downlink.TELEMETRY)."""

    watchdog: float
    cond_max: float = COND_MAX
    rates: dict[str, float] = field(default_factory=lambda: dict(TELEMETRY))


def parameters(servo: Servo, settings: Settings, b: input_bounds.ParamRanges, cap: Capability,
               rate: float) -> dict[str, Param]:
    """The table, in the order PARAM_REQUEST_LIST answers (the index of PARAM_VALUE): the
    settable ones within `b`, the setpoint bounds of `cap` read-only."""

    def gain(name: str) -> Param:
        return Param(lambda: getattr(servo.ctrl.gains, name), lambda x: servo.set_gain(name, x),
                     input_bounds.in_range(0.0, b.gain_max[name]))

    def motor(name: str, rng: tuple[float, float], unit: str) -> Param:
        return Param(lambda: getattr(servo.ctrl.axis.motor, name),
                     lambda x: servo.set_motor(name, x), input_bounds.in_range(*rng, unit))

    def bound(value: float) -> Param:
        return Param(lambda: value, lambda x: None, input_bounds.read_only)

    def stream(name: str) -> Param:
        return Param(lambda: settings.rates[name], lambda x: settings.rates.__setitem__(name, x),
                     lambda x: input_bounds.check_rate(x)
                     or input_bounds.in_range(0.0, min(rate, b.stream_max), "Hz")(x))

    params = {"CTRL_KP": gain("kp"), "CTRL_KI": gain("ki"), "CTRL_KD": gain("kd"),
              "DRV_V_LIMIT": motor("voltage_limit", b.voltage_range, "V"),
              "DRV_I_LIMIT": motor("current_limit", b.current_range, "A"),
              "WDG_TIMEOUT": Param(lambda: settings.watchdog,
                                   lambda x: setattr(settings, "watchdog", x),
                                   input_bounds.in_range(*b.watchdog_range, "s")),
              "SP_COND_MAX": Param(lambda: settings.cond_max,
                                   lambda x: setattr(settings, "cond_max", x),
                                   input_bounds.in_range(1.0, b.cond_max_limit, lo_open=True))}
    params.update({p: stream(s) for p, s in STREAM_PARAMS.items()})
    params.update({"SP_LEN_MIN": bound(cap.leg_min), "SP_LEN_MAX": bound(cap.leg_max),
                   "SP_RATE_MAX": bound(cap.setpoint_rate),
                   "SP_FORCE_MAX": bound(cap.setpoint_force),
                   "SP_FRATE_MAX": bound(cap.setpoint_force_rate)})
    return params


def param_name(param_id: Any) -> str:
    """The name in a param_id field (bytes or str, NUL-padded)."""
    if isinstance(param_id, bytes):
        param_id = param_id.decode("ascii", "replace")
    return str(param_id).rstrip("\x00")


def value_message(params: dict[str, Param], name: str) -> Any:
    """PARAM_VALUE of `name` (REAL32, with its index and the count)."""
    names = list(params)
    return ms.MAVLink_param_value_message(name.encode(), float(params[name].get()),
                                          ms.MAV_PARAM_TYPE_REAL32, len(names), names.index(name))


def read(params: dict[str, Param], msg: Any) -> tuple[list[Any], str | None]:
    """PARAM_REQUEST_READ (by index when param_index >= 0, else by name): (PARAM_VALUE, None),
    or ([], why not)."""
    names = list(params)
    if msg.param_index >= 0:
        if msg.param_index < len(names):
            return [value_message(params, names[msg.param_index])], None
        return [], f"no parameter index {msg.param_index}"
    name = param_name(msg.param_id)
    if name in params:
        return [value_message(params, name)], None
    return [], f"no parameter {name}"


def set_from(params: dict[str, Param], msg: Any) -> tuple[list[Any], str | None]:
    """PARAM_SET: set the value when it is acceptable; (the PARAM_VALUE to answer, None), or
    (the unchanged PARAM_VALUE, or none for an unknown name; why refused)."""
    name = param_name(msg.param_id)
    p = params.get(name)
    if p is None:
        return [], f"no parameter {name}"
    x, why = protocol.param_set_value(msg)
    if why is not None:
        return [value_message(params, name)], f"{name} refused: {why}"
    why = "must be finite" if not math.isfinite(x) else p.check(x)
    if why is not None:
        return [value_message(params, name)], f"{name} {x:g} refused: {why}"
    p.set(x)
    return [value_message(params, name)], None


def restored_text(before: dict[str, float], params: dict[str, Param]) -> str:
    """What a restore of DESIGN_PARAMS did, from their values `before` it: "restored CTRL_KP
    1e+09 -> 1.261e+04, ... (CTRL_KI 1.585e+05 ... kept)" (every one named with its value)."""
    changed, kept = [], []
    for name in DESIGN_PARAMS:
        old, new = before[name], params[name].get()
        if old == new:
            kept.append(f"{name} {new:.4g}")
        else:
            changed.append(f"{name} {old:.4g} -> {new:.4g}")
    if not changed:
        return "design gains and limits kept: " + ", ".join(kept)
    return "restored " + ", ".join(changed) + (f" ({', '.join(kept)} kept)" if kept else "")
