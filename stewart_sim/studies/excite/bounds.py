"""The limits an excitation trajectory keeps, and how far a trajectory is from each.

Every limit is the scene's capability (controller.capability: the one home of what the
mechanism and its drives can do); excite keeps a margin from each (declared there too):

- stroke: [leg_min, leg_max] of [geometry], STROKE_MARGIN of the stroke kept free at each end;
- leg speed: the drive's no-load speed V_max / Ke' (controller.drive.AxisModel.no_load_speed);
- leg acceleration: the drive's peak force over its constant load (AxisModel.peak_acceleration);
- rack force: Kf x current_limit (AxisModel.peak_force), against the prior scene's inverse
  dynamics, drives included (stewart_sim.cueing.feasibility);
- motor voltage: [controller.motor] voltage_limit against R i + L di/dt + Ke' ldot (feasibility);
- cond(J): the scaled condition number of the Jacobian (stewart_fmu.kinematics) against
  the engine's COND_LIMIT.

Speed, acceleration, force, voltage and cond(J) are kept to LIMIT_FRACTION of their limit. A
scene without [controller] or [drive] has no motor: its speed, acceleration, force and voltage
are then not limited (`Kept.note` says why), the stroke still bounds the motion.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.capability import EXCITE_FRACTION, EXCITE_STROKE, Capability, capability
from controller.config import ControllerConfig
from stewart_fmu.errors import StewartError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_sim.cueing.feasibility import feasibility

STROKE_MARGIN = EXCITE_STROKE     # fraction of the stroke kept free at each end
LIMIT_FRACTION = EXCITE_FRACTION  # speed, acceleration, force, voltage and cond(J): at most this
QUANTITIES = ("stroke_min", "stroke_max", "speed", "acceleration", "force", "voltage", "cond")
MAX_SLACKS = 6 * (len(QUANTITIES) - 1) + 1   # entries of `slack` per sample: per leg, cond(J) one


@dataclass(frozen=True)
class Kept:
    """What excite keeps free of a scene's capability (controller.capability: the stroke, the
    drives' bounds, the motor's voltage, cond(J); None: not limited, see `note`): `margin` m
    at each end of the stroke, at most `fraction` of the others."""

    cap: Capability
    margin: float           # m kept free at each end of the stroke
    fraction: float = LIMIT_FRACTION
    note: str | None = None

    @property
    def leg_min(self) -> float:
        return self.cap.leg_min

    @property
    def leg_max(self) -> float:
        return self.cap.leg_max

    @property
    def speed(self) -> float | None:
        """m/s, the drives' no-load speed."""
        return None if self.cap.drive is None else self.cap.drive.speed

    @property
    def acceleration(self) -> float | None:
        """m/s^2, the drives' peak acceleration of their constant load."""
        return None if self.cap.drive is None else self.cap.drive.acceleration

    @property
    def force(self) -> float | None:
        return self.cap.force

    @property
    def voltage(self) -> float | None:
        return self.cap.voltage

    @property
    def cond(self) -> float:
        return self.cap.cond

    def bound(self, quantity: str) -> float | None:
        """What the trajectory may reach: leg_min + margin, leg_max - margin, fraction x the
        others (None: not limited)."""
        if quantity == "stroke_min":
            return self.leg_min + self.margin
        if quantity == "stroke_max":
            return self.leg_max - self.margin
        limit = getattr(self, quantity)
        return None if limit is None else self.fraction * limit


@dataclass(frozen=True)
class Peaks:
    """What a trajectory asks: per leg (6,) the shortest and longest length (m), the peak |leg
    speed| (m/s), |acceleration| (m/s^2), |rack force| (N) and |motor voltage| (V; None without
    a motor), and the worst cond(J) over the samples."""

    stroke_min: np.ndarray
    stroke_max: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    force: np.ndarray
    voltage: np.ndarray | None
    cond: float


def limits(model: Model, controller: ControllerConfig | None) -> Kept:
    """The scene's limits; StewartError when it gives no stroke or leaves home no room."""
    if model.leg_min is None or model.leg_max is None:
        raise StewartError("excite: the scene gives no stroke ([geometry] leg_min and leg_max): "
                           "the excitation needs it to bound the motion")
    margin = STROKE_MARGIN * (model.leg_max - model.leg_min)
    home = inverse_kinematics(model, np.asarray(model.home)[None, :], with_cond=False).lengths[0]
    free = min(float(np.min(home)) - model.leg_min, model.leg_max - float(np.max(home)))
    if not free > margin:
        raise StewartError(f"excite: no room to move: a leg at home is {free * 1e3:.3g} mm from "
                           f"an end of its stroke, within the margin of {margin * 1e3:.3g} mm "
                           f"({STROKE_MARGIN:.0%} of the stroke)")
    cap = capability(model, controller)
    if cap.drive is None:
        what = "[controller] table (the motor)" if controller is None else "[drive] table"
        return Kept(cap, margin, note=f"the scene has no {what}: leg speed, acceleration, rack "
                                      "force and voltage not limited")
    return Kept(cap, margin)


@dataclass(frozen=True)
class Samples:
    """What a trajectory asks at each of its N samples, per leg (N, 6): length (m), |leg speed|
    (m/s), |acceleration| (m/s^2), |rack force| (N) and |motor voltage| (V; None without a
    motor); cond(J) (N,)."""

    lengths: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    force: np.ndarray
    voltage: np.ndarray | None
    cond: np.ndarray


def samples(model: Model, controller: ControllerConfig | None, t: np.ndarray, q: np.ndarray,
            qd: np.ndarray, qdd: np.ndarray) -> Samples:
    """The trajectory's values at every sample (feasibility's lengths, forces, voltages and
    cond(J); leg speeds and accelerations by inverse kinematics)."""
    f = feasibility(model, t, q, qd, qdd, controller)
    kin = inverse_kinematics(model, q, qd, qdd, with_cond=False)
    return Samples(f.lengths, np.abs(kin.rates), np.abs(kin.accelerations), np.abs(f.sigma),
                   None if f.voltage is None else np.abs(f.voltage), f.cond)


def peaks(model: Model, controller: ControllerConfig | None, t: np.ndarray, q: np.ndarray,
          qd: np.ndarray, qdd: np.ndarray) -> Peaks:
    """The peaks of a trajectory: the extremes over its `samples`."""
    s = samples(model, controller, t, q, qd, qdd)
    return Peaks(np.min(s.lengths, axis=0), np.max(s.lengths, axis=0),
                 np.max(s.speed, axis=0), np.max(s.acceleration, axis=0),
                 np.max(s.force, axis=0), None if s.voltage is None else np.max(s.voltage, axis=0),
                 float(np.max(s.cond)))


def slack(lim: Kept, p: Peaks | Samples) -> np.ndarray:
    """How far inside its bound each quantity is, as a fraction (>= 0: inside): the stroke's per
    leg in units of the stroke, the others 1 - value / bound per leg (cond(J): one column).
    Of Peaks: one number per quantity and leg, in the order of `slack_names`; of Samples: that
    per sample (N, K), whose minimum over the samples is the slack of their peaks."""
    span = lim.leg_max - lim.leg_min
    if isinstance(p, Samples):
        low = high = p.lengths
        cond = p.cond[:, None]
    else:
        low, high, cond = p.stroke_min, p.stroke_max, np.atleast_1d(p.cond)
    out = [(low - lim.bound("stroke_min")) / span, (lim.bound("stroke_max") - high) / span]
    for quantity in ("speed", "acceleration", "force", "voltage"):
        bound, value = lim.bound(quantity), getattr(p, quantity)
        if bound is not None and value is not None:
            out.append(1.0 - value / bound)
    out.append(1.0 - cond / lim.bound("cond"))
    return np.concatenate(out, axis=-1)


def slack_names(lim: Kept) -> list[str]:
    """The quantity of each entry of `slack` ("speed leg 3", "cond")."""
    names = []
    for quantity in QUANTITIES:
        if quantity == "cond":
            names.append("cond(J)")
        elif quantity.startswith("stroke") or lim.bound(quantity) is not None:
            names += [f"{quantity} leg {i}" for i in range(1, 7)]
    return names


def tightest(lim: Kept, g: np.ndarray) -> str:
    """The entry of `slack` g (of Peaks, or of Samples flattened) with the least slack, as
    'speed leg 3 slack -0.02'."""
    g = np.ravel(g)
    names = slack_names(lim)
    k = int(np.argmin(g))
    return f"{names[k % len(names)]} slack {g[k]:.3g}"
