"""What the mechanism and its drives can do, in one place: the feasibility engine of a scene
(stewart_fmu.reach.Engine: stroke, joint cones, leg and obstacle clearance, cond(J)) with the
drives' bounds of its [drive] and [controller.motor] tables (controller.drive.AxisModel: the
no-load speed, the peak acceleration of its constant load and the peak force Kf I_max), and
what each consumer keeps free of them (`Margins`, declared once here).

Every consumer takes its limits from here: the device's setpoint check (hil.setpoint: the
geometric limits, `geometric_engine`), the live envelope (stewart_sim.live.envelope: `Margins`
kept free of the engine's limits), excite, size and cue feasibility (`drive_bounds`), and
`stewart-sim workspace` (`engine`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_fmu import table
from stewart_fmu.model import Model
from stewart_fmu.reach import LIMITS, DriveBounds, Engine
from stewart_fmu.reach_params import COND_LIMIT

from .config import ControllerConfig
from .drive import AxisModel, axis_model

# The limits of the pose alone that the engine computes from the scene's [joints] and
# [clearance] tables: what the device refuses and the live envelope never sends.
GEOMETRIC = ("base_cone", "platform_cone", "leg_clearance", "obstacle")


@dataclass(frozen=True)
class Margins:
    """What the live envelope keeps free of each limit: the stroke's as a fraction of the
    stroke, the joint cones' as a fraction of the cone angle, the clearances' as a fraction of
    the leg radius, the others as fractions of the limit."""

    stroke: float = 0.02
    speed: float = 0.2
    acceleration: float = 0.2
    force: float = 0.2
    cond: float = 0.2
    cone: float = 0.1
    clearance: float = 0.5

    def check(self) -> None:
        """ValueError naming the first margin that is not in [0, 1)."""
        for name in self.__dataclass_fields__:
            x = getattr(self, name)
            if not 0.0 <= x < 1.0:
                raise ValueError(f"envelope margin '{name}' must be in [0, 1), got {x!r}")


# What the offline consumers keep free of the limits: excite's excitation (stroke: a fraction
# of the stroke at each end; the drives' limits and cond(J): at most a fraction of each)
EXCITE_STROKE = 0.05
EXCITE_FRACTION = 0.8
# The emulated device's headroom over the drives' limits (hil.input_bounds): planned moves may
# ask more than a drive delivers (it then saturates); the device refuses absurd values, not
# ambitious ones
DEVICE_RATE = 10.0      # setpoint rate: this many times the no-load speed
DEVICE_FORCE = 50.0     # feed-forward force: this many times the peak force


@dataclass(frozen=True)
class Capability:
    """What one scene's mechanism and drives can do: its stroke (None: not limited), its drive
    (None without [drive] or [controller]), the drives' bounds, the motor's voltage limit and
    the cond(J) limit; `engine()` the feasibility engine over them."""

    model: Model
    axis: AxisModel | None
    drive: DriveBounds | None
    voltage: float | None      # V, the motor's voltage_limit
    cond: float = COND_LIMIT

    @property
    def leg_min(self) -> float | None:
        return self.model.leg_min

    @property
    def leg_max(self) -> float | None:
        return self.model.leg_max

    @property
    def force(self) -> float | None:
        """N, the drives' peak rack force Kf I_max (None: no drive)."""
        return None if self.drive is None else self.drive.force

    def engine(self) -> Engine:
        return Engine(self.model, self.drive, self.cond)


def capability(model: Model, config: ControllerConfig | None) -> Capability:
    """The scene's capability (its [drive] and [controller.motor] when it has both)."""
    axis = axis_of(model, config)
    return Capability(model, axis, bounds_of(axis),
                      None if axis is None else axis.motor.voltage_limit)


def axis_of(model: Model, config: ControllerConfig | None) -> AxisModel | None:
    """The drive of the scene's legs (controller.drive.axis_model with the scene's motor and
    load), None without a [drive] or a [controller] table."""
    if config is None or model.drive is None:
        return None
    return axis_model(model, config.motor, config.load_mass)


def bounds_of(axis: AxisModel | None) -> DriveBounds | None:
    """The drives' bounds of an axis model: its no-load speed, peak acceleration, peak force."""
    if axis is None:
        return None
    return DriveBounds(axis.no_load_speed, axis.peak_acceleration, axis.peak_force)


def drive_bounds(model: Model, config: ControllerConfig | None) -> DriveBounds | None:
    """The drives' bounds of a scene; None without a [drive] or a [controller] table (the legs'
    speed, acceleration and force are then not limited)."""
    return bounds_of(axis_of(model, config))


def engine(model: Model, config: ControllerConfig | None) -> Engine:
    """The scene's engine: its geometric limits, its drives' bounds when it has them, the
    default cond(J) limit."""
    return capability(model, config).engine()


def geometric_engine(model: Model) -> Engine:
    """The engine of the pose's own limits, without cond(J) (the device bounds it by its
    parameter SP_COND_MAX) and without the drives."""
    return Engine(model, None, cond_limit=None)


def kept(model: Model, margins: Margins) -> np.ndarray:
    """Per limit of LIMITS, the margin a consumer with `margins` keeps free of the geometric
    limits (rad for the cones, m for the clearances; 0 for the others)."""
    r, off = model.reach, table.reach_offset
    out = np.zeros(len(LIMITS))
    index = {lim.name: lim.index for lim in LIMITS}
    out[index["base_cone"]] = margins.cone * r[off("BASE_CONE")]
    out[index["platform_cone"]] = margins.cone * r[off("PLATFORM_CONE")]
    clear = margins.clearance * r[off("LEG_RADIUS")]
    out[index["leg_clearance"]] = out[index["obstacle"]] = clear
    return out


def first_violated(margins: np.ndarray, keep: np.ndarray | float = 0.0,
                   names: tuple[str, ...] = GEOMETRIC) -> int | None:
    """The index (into LIMITS) of the first limit of `names`, in LIMITS order, whose margin is
    below `keep` (per limit, or one number); None when none is."""
    keep = np.broadcast_to(np.asarray(keep, dtype=float), (len(LIMITS),))
    for lim in LIMITS:
        if lim.name in names and not margins[lim.index] >= keep[lim.index]:
            return lim.index
    return None
