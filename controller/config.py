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

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from stewart_fmu.errors import SceneError
from stewart_fmu.model import Model

from .drive import Motor, motor_from_table

FEEDFORWARD = ("none", "constant_load", "kane")
NUMBER_KEYS = ("rate", "bandwidth", "phase_margin", "load_mass")  # the table's numbers
DELAYS = (0, 1)  # the actuation delays the closed loop implements, in controller periods
_KEYS = {*NUMBER_KEYS, "feedforward", "delay", "motor"}


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
            values[key] = _positive(table, key, model.source)
    if not values.get("phase_margin", 60.0) < 90:
        raise SceneError("controller.phase_margin", "must be below 90 deg", model.source)
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


def _positive(table: Mapping[str, Any], key: str, source: str | None) -> float:
    x = table[key]
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x) or x <= 0:
        raise SceneError(f"controller.{key}", f"must be a finite number > 0, got {x!r}", source)
    return float(x)
