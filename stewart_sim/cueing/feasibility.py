"""Can the mechanism fly a platform trajectory? Stroke and cond(J) from inverse kinematics, leg
forces from the scene's inverse dynamics (every declared effect, the drive's reflected inertia
included: the rack force of the paper's Eq. 12), and the motor current and voltage the drives
need for those forces (controller/drive.py):

    i = sigma / Kf                   Kf = Kt zeta / r  (AxisModel.force_constant)
    V = R i + L di/dt + Ke' ldot     Ke' = Ke zeta / r (AxisModel.voltage)

(AxisModel.drive_for, as the controller's feedforward: di/dt by central differences.)
Limits (the scene's Capability, controller.capability, the one home of what the mechanism and
its drives can do; a Feasibility holds the one it was judged against): the stroke [leg_min,
leg_max] of [geometry]; cond(J) (scaled as in stewart_fmu.kinematics) below `cond_limit` (the
engine's COND_LIMIT); |i| and |V| below [controller.motor]'s current_limit and voltage_limit;
|sigma| below the drives' peak force Kf x current_limit, the most force the drive can give.
What `cue-live`'s envelope keeps free of them on top is live.preflight's. A scene without
[controller] (or without [drive]) has no motor: current, voltage and the force limit are then
not computed (`drive_note` says why).

Forces are computed at every sample, also those past the stroke (the stroke is checked here,
not refused by the dynamics), so a report shows what the whole trajectory would take.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from controller.capability import Capability, capability
from controller.config import ControllerConfig
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import TrajectoryError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.reach import LIMITS
from stewart_fmu.reach_params import COND_LIMIT   # the engine's cond(J) limit, SP_COND_MAX's default

QUANTITIES = ("stroke_min", "stroke_max", "cond", "force", "current", "voltage")
# the engine's units for the limits it shares (stewart_fmu.reach.LIMITS), the motor's for its own
UNITS = {**{lim.name: lim.unit for lim in LIMITS if lim.name in QUANTITIES}, "current": "A",
         "voltage": "V"}


@dataclass(frozen=True)
class Violation:
    """One crossing of a limit: its first sample, the leg (1..6; None for cond, a property of
    the pose), the value there and the limit, and how long the crossing lasted."""

    t: float
    sample: int
    leg: int | None
    quantity: str       # one of QUANTITIES
    value: float        # at the first sample past the limit
    limit: float
    unit: str
    duration: float     # s: samples past the limit in this crossing x dt


@dataclass(frozen=True)
class Margin:
    """The worst sample of one quantity: `ratio` = value / limit (limit / value for
    stroke_min), so that ratio > 1 means past the limit, whichever its direction."""

    quantity: str
    ratio: float
    value: float
    limit: float
    unit: str
    t: float
    sample: int
    leg: int | None


@dataclass(frozen=True)
class Feasibility:
    """What a trajectory asks of the mechanism and its drives, against their limits."""

    t: np.ndarray                  # (N,) s
    lengths: np.ndarray            # (N, 6) m
    cond: np.ndarray               # (N,) scaled cond(J)
    sigma: np.ndarray              # (N, 6) N, rack force incl. the drive term
    current: np.ndarray | None     # (N, 6) A (None: no motor in the scene)
    voltage: np.ndarray | None     # (N, 6) V
    capability: Capability         # the limits judged against (its cond: the cond(J) limit)
    violations: tuple[Violation, ...]   # in time order
    margins: tuple[Margin, ...]         # one per quantity that has a limit
    drive_note: str | None = None       # why current and voltage are missing, if they are

    @property
    def feasible(self) -> bool:
        return not self.violations

    @property
    def leg_min(self) -> float | None:
        """m (None: the scene gives no stroke limit)."""
        return self.capability.leg_min

    @property
    def leg_max(self) -> float | None:
        return self.capability.leg_max

    @property
    def cond_limit(self) -> float:
        return self.capability.cond

    @property
    def force_limit(self) -> float | None:
        """N, Kf x current_limit (None: no motor)."""
        return self.capability.force

    @property
    def current_limit(self) -> float | None:
        """A (None: no motor)."""
        axis = self.capability.axis
        return None if axis is None else axis.motor.current_limit

    @property
    def voltage_limit(self) -> float | None:
        """V (None: no motor)."""
        return self.capability.voltage


def feasibility(model: Model, t, q, qd, qdd, controller: ControllerConfig | None, *,
                cond_limit: float = COND_LIMIT) -> Feasibility:
    """Stroke, cond(J), leg force, motor current and voltage of the trajectory (t (N,), q, qd,
    qdd (N, 6), Euler-angle rates) against the scene's limits (the motor's from `controller`,
    the scene's [controller] table; None: not checked); every crossing is reported at its
    first sample with its leg."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2 or np.shape(q) != (t.size, 6):
        raise TrajectoryError(f"feasibility: need t (N,), N >= 2, and q, qd, qdd (N, 6); got "
                              f"{t.shape} and {np.shape(q)}")
    kin = inverse_kinematics(model, q, qd, qdd)
    sigma = inverse_dynamics(replace(model, leg_min=None, leg_max=None), q, qd, qdd)
    cap = replace(capability(model, controller), cond=cond_limit)
    current = voltage = None
    note = None
    if controller is None:
        note = ("the scene has no [controller] table (the motor's ratings): current, voltage "
                "and the force limit not computed")
    elif model.drive is None:
        note = ("the scene has no [drive] table (gearbox and pinion): current, voltage and the "
                "force limit not computed")
    else:
        voltage, current = cap.axis.drive_for(t, sigma, kin.rates)
    current_limit = None if cap.axis is None else cap.axis.motor.current_limit
    checks = {"stroke_min": (kin.lengths, cap.leg_min, -1),
              "stroke_max": (kin.lengths, cap.leg_max, +1),
              "cond": (kin.cond[:, None], cap.cond, +1),
              "force": (sigma, cap.force, 0), "current": (current, current_limit, 0),
              "voltage": (voltage, cap.voltage, 0)}
    violations, margins = [], []
    for quantity, (values, limit, side) in checks.items():
        if values is None or limit is None:
            continue
        violations += _crossings(t, quantity, values, limit, side)
        margins.append(_margin(t, quantity, values, limit, side))
    violations.sort(key=lambda v: (v.sample, QUANTITIES.index(v.quantity), v.leg or 0))
    return Feasibility(t, kin.lengths, kin.cond, sigma, current, voltage, cap,
                       tuple(violations), tuple(margins), note)


def _excess(values: np.ndarray, limit: float, side: int) -> np.ndarray:
    """How far past the limit (> 0: violated): below a minimum (side -1), above a maximum
    (+1), or beyond +-limit in magnitude (0)."""
    if side < 0:
        return limit - values
    return (np.abs(values) if side == 0 else values) - limit


def _crossings(t: np.ndarray, quantity: str, values: np.ndarray, limit: float,
               side: int) -> list[Violation]:
    """One Violation per run of samples past the limit, per column (leg)."""
    past = _excess(values, limit, side) > 0
    dt = (t[-1] - t[0]) / (t.size - 1) if t.size > 1 else 0.0
    out = []
    for col in range(values.shape[1]):
        edges = np.diff(np.r_[0, past[:, col].astype(np.int8), 0])
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for k, end in zip(starts, ends):
            out.append(Violation(float(t[k]), int(k), _leg(values, col), quantity,
                                 float(values[k, col]), float(limit), UNITS[quantity],
                                 float((end - k) * dt)))
    return out


def _margin(t: np.ndarray, quantity: str, values: np.ndarray, limit: float, side: int) -> Margin:
    """The sample and leg closest to (or furthest past) the limit."""
    ratio = limit / values if side < 0 else (np.abs(values) if side == 0 else values) / limit
    k, col = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    return Margin(quantity, float(ratio[k, col]), float(values[k, col]), float(limit),
                  UNITS[quantity], float(t[k]), int(k), _leg(values, col))


def _leg(values: np.ndarray, col) -> int | None:
    """Leg number 1..6 of a column, None for a per-pose quantity (one column)."""
    return None if values.shape[1] == 1 else int(col) + 1
