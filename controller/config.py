"""The scene's [controller] table: motor, design targets, controller rate and feedforward.

    [controller]
    rate = 1000.0            # Hz, controller and communication rate
    bandwidth = 20.0         # Hz, crossover of each axis loop
    phase_margin = 60.0      # deg
    feedforward = "none"     # "none" | "constant_load" | "kane" (computed torque)
    load_mass = 0.5          # kg, optional: the constant load (default: from the Kane model)
    delay = 0                # controller periods of actuation delay: 0 | 1 (see ControllerConfig)
    [controller.motor]
    resistance = 2.5         # ohm
    inductance = 5e-4        # H
    torque_constant = 0.02   # N m / A
    back_emf = 0.02          # V s / rad
    current_limit = 2.0      # A
    voltage_limit = 24.0     # V
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from stewart_fmu.errors import SceneError
from stewart_fmu.model import Model

from .drive import MOTOR_KEYS, AxisModel, Motor, axis_model

FEEDFORWARD = ("none", "constant_load", "kane")
NUMBER_KEYS = ("rate", "bandwidth", "phase_margin", "load_mass")  # the table's numbers
DELAYS = (0, 1)  # the actuation delays the closed loop implements, in controller periods
_KEYS = {*NUMBER_KEYS, "feedforward", "delay", "motor"}


@dataclass(frozen=True)
class Bound:
    """A key's physical bounds: low < x (low <= x when closed) and x < high (x <= high)."""

    low: float
    high: float
    unit: str
    low_closed: bool = False
    high_closed: bool = True

    def reason(self, x: float) -> str | None:
        """Why x is out of bounds ("must be > 0 Hz, got -1.0"), None when it is within."""
        if not (x >= self.low if self.low_closed else x > self.low):
            return f"must be {'>=' if self.low_closed else '>'} {self.low:g} {self.unit}, got {x!r}"
        if not (x <= self.high if self.high_closed else x < self.high):
            return f"must be {'<=' if self.high_closed else '<'} {self.high:g} {self.unit}, got {x!r}"
        return None


# The physical bounds of every number of [controller] and [controller.motor], by dotted key under
# controller: engineering ones, wide enough for any servo drive of the plant's table
# (native/include/stewart_table.h: from a micro-manipulator's 24 V motor to a motion
# simulator's kW ones, two or three orders of magnitude to spare) and narrow enough that the
# design's numbers stay finite: the crossover 2 pi bandwidth, the loop's transfer function at it
# (products of up to five of these values and the drive's), the sampled loop at 1 / rate. A
# rate from 1 Hz to 100 kHz, a crossover from 0.01 Hz to 10 kHz, a phase margin strictly between
# 0 and 90 deg (a PID reaches no other), motor resistance 1 uohm to 1 kohm, inductance 1 nH to
# 10 H, torque and back-EMF constants 1e-6 to 1e3, limits up to 100 kA and 100 kV.
BOUNDS: dict[str, Bound] = {
    "rate": Bound(1.0, 1e5, "Hz", low_closed=True),
    "bandwidth": Bound(1e-2, 1e4, "Hz", low_closed=True),
    "phase_margin": Bound(0.0, 90.0, "deg", high_closed=False),
    "load_mass": Bound(0.0, 1e6, "kg"),
    "motor.resistance": Bound(1e-6, 1e3, "ohm", low_closed=True),
    "motor.inductance": Bound(1e-9, 10.0, "H", low_closed=True),
    "motor.torque_constant": Bound(1e-6, 1e3, "N m/A", low_closed=True),
    "motor.back_emf": Bound(1e-6, 1e3, "V s/rad", low_closed=True),
    "motor.current_limit": Bound(0.0, 1e5, "A"),
    "motor.voltage_limit": Bound(0.0, 1e5, "V"),
}


@dataclass(frozen=True)
class ControllerConfig:
    """What the scene asks of the per-axis controllers.

    delay: the controller's computation (actuation) delay in periods. 0: the torque computed
    from the measurement at t_k drives the plant over [t_k, t_k+1]. 1: it is latched and drives
    the plant over [t_k+1, t_k+2], the drives holding their start torque over the first period
    (a digital servo that writes its output at the next sample; also what an SSP importer's
    step-then-exchange gives the controller FMU)."""

    motor: Motor
    rate: float = 1000.0
    bandwidth: float = 20.0
    phase_margin: float = 60.0
    feedforward: str = "none"
    load_mass: float | None = None
    delay: int = 0

    @property
    def dt(self) -> float:
        return 1.0 / self.rate


def controller_config(model: Model) -> ControllerConfig:
    """The [controller] table of the model's scene, checked (SceneError names the key)."""
    table = model.extra.get("controller")
    if table is None:
        raise SceneError("controller", "the scene has no [controller] table (motor and design "
                                       "targets): see controller/config.py", model.source)
    if not isinstance(table, Mapping):
        raise SceneError("controller", f"must be a table, got {table!r}", model.source)
    unknown = sorted(set(table) - _KEYS)
    if unknown:
        raise SceneError(f"controller.{unknown[0]}", f"unknown key (allowed: {sorted(_KEYS)})",
                         model.source)
    if "motor" not in table:
        raise SceneError("controller.motor", "required table is missing", model.source)
    values: dict[str, Any] = {"motor": motor_from_table(table["motor"], source=model.source)}
    for key in NUMBER_KEYS:
        if key in table:
            values[key] = bounded(table, key, "controller", model.source)
    ff = table.get("feedforward", "none")
    if ff not in FEEDFORWARD:
        raise SceneError("controller.feedforward", f"must be one of {FEEDFORWARD}, got {ff!r}",
                         model.source)
    values["feedforward"] = ff
    delay = table.get("delay", 0)
    if isinstance(delay, bool) or not isinstance(delay, int) or delay not in DELAYS:
        raise SceneError("controller.delay", f"must be 0 or 1 (controller periods of actuation "
                                             f"delay), got {delay!r}", model.source)
    values["delay"] = delay
    return ControllerConfig(**values)


def scene_axis(model: Model, config: ControllerConfig) -> AxisModel:
    """The drive of the scene's legs: controller.drive.axis_model with its [controller] table's
    motor and load (the one place a scene's axis model is built). SceneError without [drive]."""
    return axis_model(model, config.motor, config.load_mass)


def motor_from_table(table: Mapping[str, Any], source: str | None = None) -> Motor:
    """Read and check [controller.motor]: every key present, a finite number within BOUNDS."""
    where = "controller.motor"
    if not isinstance(table, Mapping):
        raise SceneError(where, "must be a table", source)
    unknown = sorted(set(table) - set(MOTOR_KEYS))
    if unknown:
        raise SceneError(f"{where}.{unknown[0]}", f"unknown key (allowed: {list(MOTOR_KEYS)})", source)
    values = {}
    for key in MOTOR_KEYS:
        if key not in table:
            raise SceneError(f"{where}.{key}", "required key is missing", source)
        values[key] = bounded(table, key, where, source)
    return Motor(**values)


def bounded(table: Mapping[str, Any], key: str, where: str, source: str | None) -> float:
    """table[key]: a finite number within its BOUNDS (SceneError naming `where.key`)."""
    dotted = f"{where}.{key}"
    given = table[key]
    x = float(given) if isinstance(given, float) or (isinstance(given, int) and not
                                                     isinstance(given, bool) and abs(given) <= 2**53) else math.nan
    if not math.isfinite(x):   # not a number, or an integer beyond what a float64 holds
        raise SceneError(dotted, f"must be a finite number > 0, got {given!r}", source)
    reason = BOUNDS[dotted.removeprefix("controller.")].reason(x)
    if reason is not None:
        raise SceneError(dotted, reason, source)
    return x
