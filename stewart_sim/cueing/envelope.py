"""The live safety envelope: between the washout's pose samples and the device's leg setpoints,
one causal step per sample, a bounded amount of work each.

Limits (`EnvelopeLimits`, built by `envelope_limits` from the scene and its drives):

=============  ==========================================================================
stroke         [leg_min + room + m, leg_max - room - m]: the emulated device's setpoint
               bounds (hil.limits.bounds, room = hil.limits.overshoot_room against the force
               held at home) less a margin m, a fraction of the stroke
speed          |ldot| <= (1 - margin) x the drive's no-load speed (controller.drive.AxisModel)
acceleration   |lddot| <= (1 - margin) x the drive's peak acceleration (AxisModel)
force          |sigma| <= (1 - margin) x Kf I_max, sigma the scene's inverse dynamics (every
               declared effect, the drive's reflected inertia included: the rack force);
               Kf I_max from cueing.optimal.mechanism_limits
cond           scaled cond(J) (stewart_fmu.kinematics) <= (1 - margin) x cueing.feasibility's
               COND_LIMIT (the device's default SP_COND_MAX)
=============  ==========================================================================

A sample passes unchanged (bit for bit: the cue's q, qd, qdd, their leg lengths and rates from
the C core, its force from the inverse dynamics) when it is inside every limit AND is one
admissible step from the last sample sent: its leg rates differ from the last ones by at most
a dt, its leg lengths sit within a dt^2 / 2 of the trapezoid (l + (ldot + ldot') dt / 2) of the
last sample (a jump of the cue is a step no drive makes), and every leg can still stop inside
the stroke: l + ldot |ldot| / (2 a) + ldot dt / 2 within the stroke (the braking distance of
piecewise-constant accelerations at the sample rate: l + ldot^2 / (2a) is what the continuous
stop takes, ldot dt / 2 bounds what stopping on the sample grid adds).

Otherwise the envelope flies its own state (q, qd) one step with a constant pose acceleration:
the tracking acceleration towards the cue, a_des = qdd_cue + w^2 (q_cue - q) + 2 w (qd_cue -
qd) (critically damped; w = a / v in 1/s, so that at the speed limit braking starts at four
times the distance the acceleration limit needs), brought into each leg's box for this step:
the leg accelerations are affine in the pose acceleration (lddot = A qdd + c at the step's
start state, A by the C core's leg kinematics), so

1. the stroke: a leg whose acceleration would leave the stroke's box (the next state unable to
   stop inside the stroke: the braking condition above, solved for the next leg rate) is
   clipped to it, the other legs keep theirs (a leg at its end goes no further, the platform
   slides along that end towards the cue);
2. speed and acceleration: one factor s in [0, 1] scales the legs' accelerations back towards
   the coasting ones (no pose acceleration; where coasting leaves a leg's box, that leg
   clipped into it) until every leg is within +-a and its next rate within +-v. One factor
   for all legs keeps the direction of the pose's motion: a cue too fast lags, it does not
   twist;
3. the force: the rack forces are affine in the pose acceleration too (evaluated at the step's
   start state), so the force limit only lowers s further. The stroke outranks the force: a
   leg that must brake to stay in its stroke brakes even where that takes more than the force
   limit (counted as a force intervention).

A cue pose above the cond limit (or one that is not finite, or that the core refuses) is
refused until the cue is good again: the target acceleration becomes -qd / dt (stop within
one sample, as `brake()`) plus w^2 (q_good - q), which, once stopped, brings the platform back
to the last good pose sent (a time constant of 1 / (w^2 dt)); the stop itself runs within the
limits, so a platform moving into the singular direction passes the cond limit by its braking
distance (the cond margin below the device's SP_COND_MAX is there for that).

`brake()` is the emergency stop: the same step with the target acceleration -qd / dt (stop
within one sample), scaled into the boxes, so the platform stops as fast as the limits allow
along the path it was on, then holds where it stopped.

Work per sample: three C-core calls when a sample passes (leg state, cond(J), inverse
dynamics), at most fifteen when it is limited (the leg Jacobian by six more calls of the
core's leg kinematics only when a leg is clipped into its box); no iteration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from controller.config import ControllerConfig
from hil.limits import overshoot_room
from stewart_fmu.errors import SceneError
from stewart_fmu.model import Model
from stewart_fmu.native import core

from .feasibility import COND_LIMIT
from .optimal import mechanism_limits

LIMITS = ("stroke", "speed", "acceleration", "force", "cond", "invalid")
BOX_LIMITS = LIMITS[:3]     # the per-leg limits of a step's leg accelerations, in priority order
# A pose stepped at a constant pose acceleration does not move its legs at exactly constant leg
# accelerations (the kinematics are not linear): the leg rates and accelerations it ends at
# differ from the box's by up to ~3e-3 of the limits (large rotations at the limits), their
# lengths by ~1e-9 m. The box keeps this fraction of the speed and acceleration limits free for
# that, and this fraction of the length a step at the acceleration limit moves (a dt^2) at each
# end of the stroke.
TIGHTEN = 1e-2


@dataclass(frozen=True)
class Margins:
    """What the envelope keeps free of each limit: the stroke's as a fraction of the stroke,
    the others as fractions of the limit."""

    stroke: float = 0.02
    speed: float = 0.2
    acceleration: float = 0.2
    force: float = 0.2
    cond: float = 0.2


@dataclass(frozen=True)
class EnvelopeLimits:
    """The envelope's limits (see the module doc), SI."""

    leg_min: float
    leg_max: float
    speed: float          # m/s
    acceleration: float   # m/s^2
    force: float          # N
    cond: float           # scaled cond(J)


def envelope_limits(model: Model, controller: ControllerConfig | None,
                    margins: Margins = Margins()) -> EnvelopeLimits:
    """The limits of `model`'s legs and drives (the scene's [drive] and [controller] tables),
    each less its margin. SceneError when the scene has no drive or no motor."""
    lim = mechanism_limits(model, controller, None)
    if lim.axis is None or lim.force is None:
        raise SceneError("controller", "the live envelope needs the drives' limits: the scene's "
                         "[drive] and [controller.motor] tables")
    axis = lim.axis
    free = replace(model, leg_min=None, leg_max=None)
    home = np.asarray(model.home, dtype=float)
    held, status = core.inverse_dynamics(free.native, home, np.zeros(6), np.zeros(6))
    if status:
        raise SceneError("geometry.home", "the inverse dynamics refuse the home pose")
    room = overshoot_room(axis, float(np.max(np.abs(held))))
    leg_min = model.leg_min if model.leg_min is not None else 0.0
    leg_max = model.leg_max if model.leg_max is not None else math.inf
    keep = margins.stroke * (leg_max - leg_min) if math.isfinite(leg_max) else 0.0
    lo, hi = leg_min + room + keep, leg_max - room - keep
    if not lo < hi:
        raise SceneError("geometry", f"the stroke [{leg_min:g}, {leg_max:g}] m leaves no room "
                         f"once the servo's overshoot room ({room:.3g} m) and the envelope's "
                         f"margin ({keep:.3g} m) are kept at each end")
    return EnvelopeLimits(lo, hi, (1 - margins.speed) * axis.no_load_speed,
                          (1 - margins.acceleration) * axis.peak_acceleration,
                          (1 - margins.force) * lim.force, (1 - margins.cond) * COND_LIMIT)


@dataclass(frozen=True)
class EnvelopeStep:
    """One sample sent: the setpoints (leg lengths, rates, feed-forward rack forces) and the
    pose they come from; `limits` the limits that intervened in this sample (LIMITS names),
    `legs` the legs (bool (6,)) any per-leg limit intervened on. passed: the cue went through
    unchanged."""

    lengths: np.ndarray    # (6,) m
    rates: np.ndarray      # (6,) m/s
    forces: np.ndarray     # (6,) N
    q: np.ndarray          # (6,) pose commanded
    qd: np.ndarray         # (6,) Euler-angle rates
    qdd: np.ndarray        # (6,)
    passed: bool
    limits: tuple[str, ...] = ()
    legs: np.ndarray = field(default_factory=lambda: np.zeros(6, dtype=bool))


@dataclass(frozen=True)
class Interventions:
    """The envelope's interventions so far: samples stepped, samples not passed unchanged,
    and per limit the samples it intervened in (`per_limit`) and per leg ((6,) ints,
    `per_leg`; zeros for the per-pose limits cond and invalid)."""

    samples: int
    limited: int
    per_limit: dict[str, int]
    per_leg: dict[str, np.ndarray]


class Envelope:
    """The causal per-sample envelope (see the module doc) of `model`, at `dt` s a sample,
    starting at rest at `start` (default: home), which must lie inside the stroke."""

    def __init__(self, model: Model, limits: EnvelopeLimits, dt: float, start=None) -> None:
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        # the stroke is the envelope's own check: the core must not refuse a cue outside it
        self._p = replace(model, leg_min=None, leg_max=None).native
        self.limits, self.dt = limits, float(dt)
        self.omega = limits.acceleration / limits.speed
        q0 = np.array(model.home if start is None else start, dtype=float)
        z = np.zeros(6)
        legs, status = self._legs(q0, z, z)
        if status or not self._cond(q0) <= limits.cond or not (
                np.all(legs[:, 0] >= limits.leg_min) and np.all(legs[:, 0] <= limits.leg_max)):
            raise ValueError("the envelope's start pose must lie inside its stroke and cond "
                             "limits")
        forces, _ = core.inverse_dynamics(self._p, q0, z, z)
        self.last = EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q0, z.copy(),
                                 z.copy(), True)
        self._hold: np.ndarray | None = None     # the pose held while the cue is refused
        self._samples = self._limited = 0
        self._per_limit = dict.fromkeys(LIMITS, 0)
        self._per_leg = {name: np.zeros(6, dtype=int) for name in LIMITS}

    # ------------------------------------------------------------------ public steps

    def step(self, q, qd, qdd) -> EnvelopeStep:
        """The sample to send for the cue sample (q, qd, qdd) (pose, Euler-angle rates and
        their derivatives)."""
        q, qd, qdd = (np.array(a, dtype=float).reshape(6) for a in (q, qd, qdd))
        reasons: dict[str, np.ndarray] = {}
        ok = bool(np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
                  and np.all(np.isfinite(qdd)))
        legs = forces = None
        if ok:
            legs, status = self._legs(q, qd, qdd)
            ok = not status
        if not ok:
            reasons["invalid"] = np.zeros(6, dtype=bool)
        elif not self._cond(q) <= self.limits.cond:
            reasons["cond"] = np.zeros(6, dtype=bool)
        else:
            forces, _ = core.inverse_dynamics(self._p, q, qd, qdd)
            reasons = self._check(legs, forces)
        if not reasons:
            self._hold = None
            out = EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q, qd, qdd, True)
            return self._record(out)
        last = self.last
        if "cond" in reasons or "invalid" in reasons:
            # stop at once (as brake()), then creep back to the last good pose
            if self._hold is None:
                self._hold = last.q
            a_des = self.omega**2 * (self._hold - last.q) - last.qd / self.dt
        else:
            self._hold = None
            a_des = qdd + self.omega**2 * (q - last.q) + 2.0 * self.omega * (qd - last.qd)
        return self._record(self._limited_step(a_des, reasons))

    def brake(self) -> EnvelopeStep:
        """The emergency stop's sample: stop as fast as the limits allow (target: no pose
        rate after this sample), then hold the pose where the platform stopped."""
        return self._record(self._limited_step(-self.last.qd / self.dt, {}))

    @property
    def interventions(self) -> Interventions:
        return Interventions(self._samples, self._limited, dict(self._per_limit),
                             {k: v.copy() for k, v in self._per_leg.items()})

    # ------------------------------------------------------------------ the checks

    def _legs(self, q, qd, qdd) -> tuple[np.ndarray, int]:
        """(rows (6, 3) of leg length, rate, acceleration; status) from the C core."""
        _, legs, status = core.twist_forces(self._p, q, qd, qdd)
        return legs, status

    def _cond(self, q) -> float:
        cond, status = core.condition_number(self._p, q)
        return cond if not status else math.inf

    def _check(self, legs: np.ndarray, forces: np.ndarray) -> dict[str, np.ndarray]:
        """The limits a cue sample (its leg rows and forces) breaks, per leg, as a step from
        the last sample sent."""
        lim, dt = self.limits, self.dt
        a, vmax = lim.acceleration, lim.speed
        l, v, u = legs[:, 0], legs[:, 1], legs[:, 2]
        lp, vp = self.last.lengths, self.last.rates
        stop = l + v * np.abs(v) / (2.0 * a) + v * dt / 2.0
        checks = {
            "stroke": (l < lim.leg_min) | (l > lim.leg_max) | (stop < lim.leg_min)
            | (stop > lim.leg_max),
            "speed": np.abs(v) > vmax,
            "acceleration": (np.abs(u) > a) | (np.abs(v - vp) > a * dt)
            | (np.abs(l - lp - (vp + v) * dt / 2.0) > a * dt * dt / 2.0),
            "force": np.abs(forces) > lim.force,
        }
        return {k: m for k, m in checks.items() if m.any()}

    def _box(self, l: np.ndarray, v: np.ndarray):
        """The leg accelerations (lo, hi) allowed over the next sample from leg state (l, v):
        the stroke's braking condition first, then the speed, then the acceleration; where
        two leave nothing in common, the nearest point of the earlier one. Also which of
        BOX_LIMITS bounds each leg's (lo, hi) (index arrays), and the stroke's bounds alone."""
        lim, dt = self.limits, self.dt
        a, vmax = (1.0 - TIGHTEN) * lim.acceleration, (1.0 - TIGHTEN) * lim.speed
        inset = TIGHTEN * a * dt * dt
        top, bottom = lim.leg_max - inset, lim.leg_min + inset
        up = top - l - v * dt / 2.0
        dn = l - bottom + v * dt / 2.0
        with np.errstate(invalid="ignore"):
            vh = np.where(up >= 0, -a * dt + np.sqrt(a * a * dt * dt + 2 * a * np.maximum(up, 0)),
                          2 * (top - l) / dt - v)
            vl = np.where(dn >= 0, a * dt - np.sqrt(a * a * dt * dt + 2 * a * np.maximum(dn, 0)),
                          2 * (bottom - l) / dt - v)
        vl = np.minimum(vl, vh)
        stroke = ((vl - v) / dt, (vh - v) / dt)
        by_hi = np.argmin(np.stack([vh, np.full(6, vmax), v + a * dt]), axis=0)
        by_lo = np.argmax(np.stack([vl, np.full(6, -vmax), v - a * dt]), axis=0)
        vl, vh = _intersect(vl, vh, -vmax, vmax)
        vl, vh = _intersect(vl, vh, v - a * dt, v + a * dt)
        return (vl - v) / dt, (vh - v) / dt, by_lo, by_hi, stroke

    # ------------------------------------------------------------------ the limited step

    def _limited_step(self, a_des: np.ndarray, reasons: dict[str, np.ndarray]) -> EnvelopeStep:
        """One step of the envelope's own state with the pose acceleration a_des scaled into
        the legs' boxes and the force limit (see the module doc)."""
        last, dt, p = self.last, self.dt, self._p
        q0, qd0 = last.q, last.qd
        z = np.zeros(6)
        coast, _ = self._legs(q0, qd0, z)
        c = coast[:, 2]
        lo, hi, by_lo, by_hi, (s_lo, s_hi) = self._box(coast[:, 0], coast[:, 1])
        a_des = np.where(np.isfinite(a_des), a_des, 0.0)
        d = self._legs(q0, qd0, a_des)[0][:, 2]
        b = np.minimum(np.maximum(c, lo), hi)
        d_in = np.minimum(np.maximum(d, s_lo), s_hi)
        A = None
        a_b = z
        if np.any(b != c) or np.any(d_in != d):
            A = self._leg_jacobian(q0, qd0, c)
            a_b = _solve(A, b - c)
        if np.any(d_in != d):
            # a leg at its stroke's end goes no further; the others keep their accelerations
            reasons["stroke"] = reasons.get("stroke", np.zeros(6, dtype=bool)) | (d_in != d)
            a_des = a_des + _solve(A, d_in - d)
            d = d_in
        s = _largest_step(b, d, lo, hi)
        if s < 1.0:
            for k, name in enumerate(BOX_LIMITS):
                mask = ((d > hi) & (by_hi == k)) | ((d < lo) & (by_lo == k))
                if mask.any():
                    reasons[name] = reasons.get(name, np.zeros(6, dtype=bool)) | mask
        f_b, _ = core.inverse_dynamics(p, q0, qd0, a_b)
        f_d, _ = core.inverse_dynamics(p, q0, qd0, a_des)
        f_lim = self.limits.force
        s_f = _largest_step(f_b, f_d, np.full(6, -f_lim), np.full(6, f_lim))
        over = (np.abs(f_b + s * (f_d - f_b)) > f_lim)
        if s_f < s or np.any(np.abs(f_b) > f_lim):
            reasons["force"] = reasons.get("force", np.zeros(6, dtype=bool)) | over \
                | (np.abs(f_b) > f_lim)
            s = min(s, s_f)
        acc = a_b + s * (a_des - a_b)
        q = q0 + qd0 * dt + acc * (dt * dt / 2.0)
        qd = qd0 + acc * dt
        legs, _ = self._legs(q, qd, acc)
        forces, _ = core.inverse_dynamics(p, q, qd, acc)
        mask = np.zeros(6, dtype=bool)
        for name, m in reasons.items():
            mask |= m
        return EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q, qd, acc, False,
                            tuple(n for n in LIMITS if n in reasons), mask)

    def _leg_jacobian(self, q, qd, c) -> np.ndarray:
        """d lddot / d qdd at (q, qd) (6, 6): the leg accelerations are affine in the pose
        acceleration, so one core call per column is exact."""
        A = np.empty((6, 6))
        for j in range(6):
            e = np.zeros(6)
            e[j] = 1.0
            A[:, j] = self._legs(q, qd, e)[0][:, 2] - c
        return A

    def _record(self, out: EnvelopeStep) -> EnvelopeStep:
        self._samples += 1
        if not out.passed:
            self._limited += 1
        for name in out.limits:
            self._per_limit[name] += 1
            self._per_leg[name] += out.legs if name not in ("cond", "invalid") else 0
        self.last = out
        return out


def _intersect(lo, hi, lo2, hi2) -> tuple[np.ndarray, np.ndarray]:
    """[lo, hi] within [lo2, hi2]; where they share nothing, the point of [lo, hi] nearest."""
    return (np.minimum(np.maximum(lo, lo2), hi), np.maximum(np.minimum(hi, hi2), lo))


def _solve(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """x with A x = r; at a singular A (a singular pose) the least-squares x."""
    try:
        return np.linalg.solve(A, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, r, rcond=None)[0]


def _largest_step(b: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """The largest s in [0, 1] with b + s (d - b) within [lo, hi] on every row, b inside."""
    s = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(d > hi, (hi - b) / (d - b), 1.0)
        down = np.where(d < lo, (lo - b) / (d - b), 1.0)
    s = min(s, float(np.min(up)), float(np.min(down)))
    return max(0.0, s) if math.isfinite(s) else 0.0
