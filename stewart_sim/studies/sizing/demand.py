"""What a motion asks of each leg's drive, through the scene's full dynamics:

    stroke used   max l_i - min l_i over the motion (m), and the extreme lengths
    speed         ldot_i (m/s)           acceleration  lddot_i (m/s^2)
    force         sigma_i, the rack force incl. the drive's reflected inertia m_d lddot_i (N):
                  stewart_sim.cueing.feasibility (the scene's inverse dynamics, every effect)
    torque        sigma_i / (zeta / r), the motor shaft torque (N m): rack_ratio
    motor speed   ldot_i zeta / r (rad/s)
    power         sigma_i ldot_i = torque x motor speed, the shaft's mechanical power (W)
    current       sigma_i / Kf and voltage R i + L di/dt + Ke' ldot_i (A, V): only with the
                  scene's own motor ([controller.motor]; controller.drive.AxisModel.drive_for,
                  called by feasibility)

Each quantity's peak is the largest magnitude over samples and legs, with its time and leg; its
RMS is per leg over the motion's time (trapezoidal, so any sampling weighs alike), the worst leg's.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_sim.cueing.feasibility import Feasibility, feasibility

from .motions import Motion

# quantity -> (unit in words, unit in a CSV column name)
UNITS = {"speed": ("m/s", "m_s"), "acceleration": ("m/s²", "m_s2"), "force": ("N", "N"),
         "torque": ("N m", "Nm"), "motor_speed": ("rad/s", "rad_s"), "power": ("W", "W"),
         "current": ("A", "A"), "voltage": ("V", "V")}
QUANTITIES = tuple(UNITS)


@dataclass(frozen=True)
class Peak:
    """The largest |value| of a quantity over a motion's samples and legs."""

    value: float     # signed, as it occurs
    t: float         # s
    leg: int         # 1..6

    @property
    def magnitude(self) -> float:
        return abs(self.value)


@dataclass(frozen=True)
class Statistic:
    """Peak and RMS of one quantity over one motion."""

    peak: Peak
    rms: float       # the worst leg's RMS over the motion's time
    rms_leg: int     # 1..6


@dataclass(frozen=True)
class LegDemand:
    """Every leg's demand along one motion (arrays (N, 6); None: not computed, see
    `feasibility.drive_note` for current and voltage, no [drive] for torque and motor speed;
    feasibility None: the checks not asked for)."""

    motion: str
    t: np.ndarray
    lengths: np.ndarray
    values: dict[str, np.ndarray | None]   # QUANTITIES -> (N, 6) or None
    feasibility: Feasibility | None        # stroke, cond(J) and the motor's margins

    @property
    def stroke_used(self) -> np.ndarray:
        """(6,) m: the range of each leg's length."""
        return self.lengths.max(axis=0) - self.lengths.min(axis=0)

    def statistics(self) -> dict[str, Statistic]:
        """Peak and RMS of every quantity computed."""
        return {k: statistic(self.t, v) for k, v in self.values.items() if v is not None}


def leg_demand(model: Model, motion: Motion, controller: ControllerConfig | None,
               checks: bool = True) -> LegDemand:
    """The demand of `motion` on the drives of `model` (its [drive]: the scene's, or a
    catalogue drive put in its place); current and voltage with `controller`'s motor.
    checks=False: the demand alone, without feasibility's checks (stroke, cond(J), the motor:
    an SVD per sample for cond(J), the bulk of the cost), what a catalogue drive's checks need;
    the same numbers."""
    kin = inverse_kinematics(model, motion.q, motion.qd, motion.qdd, with_cond=False)
    speed, accel = kin.rates, kin.accelerations
    f = feasibility(model, motion.t, motion.q, motion.qd, motion.qdd, controller) if checks \
        else None
    if f is not None:
        t, lengths, sigma = f.t, f.lengths, f.sigma
    else:   # the rack force at every sample, also past the stroke, as feasibility takes it
        t, lengths = np.asarray(motion.t, dtype=float), kin.lengths
        sigma = inverse_dynamics(replace(model, leg_min=None, leg_max=None), motion.q,
                                 motion.qd, motion.qdd)
    values: dict[str, np.ndarray | None] = {
        "speed": speed, "acceleration": accel, "force": sigma, "torque": None,
        "motor_speed": None, "power": sigma * speed,
        "current": None if f is None else f.current,
        "voltage": None if f is None else f.voltage}
    if model.drive is not None:
        ratio = model.drive.force_per_torque
        values["torque"] = sigma / ratio
        values["motor_speed"] = speed * ratio
    return LegDemand(motion.name, t, lengths, values, f)


def statistic(t: np.ndarray, values: np.ndarray) -> Statistic:
    """Peak |value| (time, leg) and the worst leg's RMS over time of an (N, 6) array."""
    k, col = np.unravel_index(int(np.argmax(np.abs(values))), values.shape)
    rms = leg_rms(t, values)
    worst = int(np.argmax(rms))
    return Statistic(Peak(float(values[k, col]), float(t[k]), int(col) + 1), float(rms[worst]),
                     worst + 1)


def leg_rms(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(6,) sqrt(integral of v^2 dt / duration) per leg, trapezoidal."""
    return np.sqrt(np.trapezoid(values**2, t, axis=0) / (t[-1] - t[0]))
