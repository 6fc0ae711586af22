"""What the mechanism and its drives can do, in one place: the feasibility engine of a scene
(stewart_fmu.reach.Engine: stroke, joint cones, leg and obstacle clearance, cond(J)) with the
drives' bounds of its [drive] and [controller.motor] tables (controller.drive.AxisModel: the
no-load speed, the peak acceleration of its constant load and the peak force Kf I_max), and
what each consumer keeps free of them (`Margins` and the constants below, declared once here).

`Capability` is that one home; a consumer's view of it is a Capability too: `inset` keeps the
servo's overshoot room free at each end of the stroke (`overshoot_room`: what the emulated
device accepts as a setpoint length), `less` takes `Margins` off every limit (what the live
envelope sends), and the `setpoint_*` properties are the device's headroom over the drives.

Every consumer takes its limits from here: the device's setpoint check (hil.setpoint: an inset
Capability, its `geometric` engine and `setpoint_*` bounds), the live envelope
(stewart_sim.live.envelope: an inset Capability `less` its `Margins`), excite, size and cue
feasibility (`capability`, `drive_bounds`), and `stewart-sim workspace` (`engine`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from stewart_fmu import table
from stewart_fmu.model import Model
from stewart_fmu.reach import LIMITS, DriveBounds, Engine
from stewart_fmu.reach_params import COND_LIMIT

from .config import ControllerConfig, scene_axis
from .drive import AxisModel

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
# The emulated device's headroom over the drives' limits (Capability.setpoint_rate,
# setpoint_force, setpoint_force_rate): planned moves may ask more than a drive delivers (it
# then saturates): the project's own references for the paper's 0.1 s moves ask the
# micro-manipulator's legs for 6.5x the no-load speed and 21x the peak force (Kane
# feed-forward), and the host must be able to send them. The device refuses absurd values,
# not ambitious ones
DEVICE_RATE = 10.0        # setpoint rate: this many times the no-load speed
DEVICE_FORCE = 50.0       # feed-forward force: this many times the peak force
DEVICE_FORCE_RATE = 10.0  # feed-forward force rate: this many times the drive's fastest


@dataclass(frozen=True)
class Capability:
    """What one scene's mechanism and drives can do, or what a consumer may use of it (`inset`,
    `less`): its stroke (None: not limited), its drive (None without [drive] or [controller]),
    the drives' bounds, the motor's voltage limit, the cond(J) limit, and what is kept free of
    the geometric limits; `engine()` the feasibility engine of the mechanism's own limits."""

    model: Model
    axis: AxisModel | None
    drive: DriveBounds | None
    voltage: float | None      # V, the motor's voltage_limit
    cond: float = COND_LIMIT
    # m, the leg lengths a consumer may use (inset, less); None: the model's stroke
    stroke: tuple[float, float] | None = None
    # per limit of LIMITS, the margin kept free of the geometric limits (less; None: none)
    keep: np.ndarray | None = field(default=None, compare=False)

    @property
    def leg_min(self) -> float | None:
        return self.model.leg_min if self.stroke is None else self.stroke[0]

    @property
    def leg_max(self) -> float | None:
        return self.model.leg_max if self.stroke is None else self.stroke[1]

    @property
    def ends(self) -> tuple[float, float]:
        """m, (leg_min, leg_max) with an end the scene does not limit at 0 and inf."""
        lo, hi = self.leg_min, self.leg_max
        return (0.0 if lo is None else lo), (math.inf if hi is None else hi)

    @property
    def speed(self) -> float | None:
        """m/s, the drives' |leg speed| bound (None: no drive)."""
        return None if self.drive is None else self.drive.speed

    @property
    def acceleration(self) -> float | None:
        """m/s^2, the drives' |leg acceleration| bound (None: no drive)."""
        return None if self.drive is None else self.drive.acceleration

    @property
    def force(self) -> float | None:
        """N, the drives' peak rack force Kf I_max (None: no drive)."""
        return None if self.drive is None else self.drive.force

    @property
    def setpoint_rate(self) -> float:
        """m/s, the most |rate| a device setpoint may carry: DEVICE_RATE x the no-load speed."""
        return DEVICE_RATE * self.speed

    @property
    def setpoint_force(self) -> float:
        """N, the most |feed-forward force| a device setpoint may carry: DEVICE_FORCE x the
        peak force."""
        return DEVICE_FORCE * self.force

    @property
    def setpoint_force_rate(self) -> float:
        """N/s, the most |feed-forward force rate| a device setpoint may carry: DEVICE_FORCE_RATE
        x Kf V_max / L, the drive's fastest change of force (its di/dt limit)."""
        a = self.axis
        return DEVICE_FORCE_RATE * a.force_constant * a.motor.voltage_limit / a.motor.inductance

    @cached_property
    def geometric(self) -> Engine | None:
        """The engine of the pose's own limits (`geometric_engine`) when the scene has one of
        GEOMETRIC ([joints], [clearance]), else None."""
        reach = geometric_engine(self.model)
        return reach if {lim.name for lim in reach.present()} & set(GEOMETRIC) else None

    def engine(self) -> Engine:
        return Engine(self.model, self.drive, self.cond)

    def room(self, holding_force: float) -> float:
        """m, the servo's overshoot room (`overshoot_room`) with `holding_force` held."""
        return overshoot_room(self.axis, holding_force)

    def inset(self, room: float) -> Capability:
        """This capability with `room` m kept free at each end of the stroke."""
        lo, hi = self.ends
        return replace(self, stroke=(lo + room, hi - room))

    def less(self, margins: Margins) -> Capability:
        """This capability less `margins` (Margins.check first): the stroke narrowed by a
        fraction of the mechanism's stroke at each end (none without a leg_max), the drives'
        bounds and cond(J) each (1 - margin) of theirs, the geometric margins kept (`kept`);
        the axis and the voltage as they are."""
        margins.check()
        lo, hi = self.ends
        m_lo = 0.0 if self.model.leg_min is None else self.model.leg_min
        m_hi = math.inf if self.model.leg_max is None else self.model.leg_max
        keep = margins.stroke * (m_hi - m_lo) if math.isfinite(m_hi) else 0.0
        d = self.drive
        drive = None if d is None else DriveBounds(
            (1 - margins.speed) * d.speed, (1 - margins.acceleration) * d.acceleration,
            (1 - margins.force) * d.force)
        return replace(self, drive=drive, cond=(1 - margins.cond) * self.cond,
                       stroke=(lo + keep, hi - keep), keep=kept(self.model, margins))


def overshoot_room(axis: AxisModel, holding_force: float) -> float:
    """m, the stroke kept free at each end of a device's setpoint lengths: the servo's own
    overshoot. A leg that arrives at a setpoint at the drive's no-load speed v0 = V_max / Ke'
    runs on until the peak force Kf I_max, less the static leg force F_hold the drive holds
    (gravity may push the same way), stops its moving mass m (the axis model's load plus m_d):
    room = m v0^2 / (2 (Kf I_max - F_hold)); inf when the drive cannot out-push the load it
    holds. The bound, not the servo, keeps the room: the servo's tick is the co-simulation
    master's (controller.axis.servo_step), so a host following the bounds gets the loop it
    designed."""
    brake = axis.peak_force - abs(holding_force)
    if not brake > 0:
        return float("inf")
    return axis.moving_mass * axis.no_load_speed ** 2 / (2.0 * brake)


def capability(model: Model, config: ControllerConfig | None) -> Capability:
    """The scene's capability (its [drive] and [controller.motor] when it has both)."""
    return with_axis(model, axis_of(model, config))


def with_axis(model: Model, axis: AxisModel | None) -> Capability:
    """The capability of `model` driven by `axis` (None: no drive)."""
    return Capability(model, axis, bounds_of(axis),
                      None if axis is None else axis.motor.voltage_limit)


def axis_of(model: Model, config: ControllerConfig | None) -> AxisModel | None:
    """The drive of the scene's legs (controller.drive.axis_model with the scene's motor and
    load), None without a [drive] or a [controller] table."""
    if config is None or model.drive is None:
        return None
    return scene_axis(model, config)


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
