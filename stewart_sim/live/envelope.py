"""The live safety envelope: between the washout's pose samples and the device's leg setpoints,
one causal step per sample, a bounded amount of work each.

Limits (`envelope_limits`: the scene's capability, controller.capability, inset by the servo's
overshoot room as the device's setpoint lengths are, less the margins its `Margins` keep free:
Capability.inset(room).less(margins)):

=============  ==========================================================================
stroke         [leg_min + room + m, leg_max - room - m]: the emulated device's setpoint
               lengths (controller.capability.overshoot_room against the force held at
               home) less a margin m, a fraction of the stroke
speed          |ldot| <= (1 - margin) x the drive's no-load speed (DriveBounds.speed)
acceleration   |lddot| <= (1 - margin) x the drive's peak acceleration (DriveBounds)
force          |sigma| <= (1 - margin) x Kf I_max, sigma the scene's inverse dynamics (every
               declared effect, the drive's reflected inertia included: the rack force);
               Kf I_max the drive's peak force (DriveBounds.force)
cond           scaled cond(J) (stewart_fmu.kinematics) <= (1 - margin) x the engine's
               COND_LIMIT (the device's default SP_COND_MAX)
joint cones,   the engine's base_cone, platform_cone, leg_clearance and obstacle margins
clearances     (scene's [joints], [clearance]) at least a fraction of the cone angle, of the
               leg radius (Margins.cone, Margins.clearance)
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
the tracking acceleration towards the cue, a_des = qdd_cue + k_d (qd_ref - qd + phi(q_ref - q)),
(q_ref, qd_ref) the cue carried back one sample at its acceleration to the state's time (a state
on it lands on the cue), phi(e) = sign(e) min(k_p |e|, sqrt(2 a_p |e|)) per coordinate: near
the cue a linear loop,
critically damped (k_d = 1 / TRACK_TIME, k_p = k_d / 4: the error decays as exp(-2 k_p t)),
far from it an approach rate the platform can brake from at a_p (half the acceleration limit;
divided by the model's characteristic length for the angles), so that a step is flown at the
limits and stops at the cue without overshoot. It is brought into each leg's box for this step:
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

A cue pose above the cond limit or inside the margin of a joint cone or a clearance (or one
that is not finite, or that the core refuses) is refused until the cue is good again: the target acceleration becomes -qd / dt (stop within
one sample, as `brake()`) plus k_d k_p (q_good - q), which, once stopped, brings the platform
back to the last good pose sent (a time constant of 1 / (k_d k_p dt)); the stop itself runs
within the limits, so a platform moving into the singular direction passes the cond limit by
its braking distance (the cond margin below the device's SP_COND_MAX is there for that).

No sample sent leaves a joint cone or a clearance (the margin not kept there, the limit
itself): a step whose pose would is replaced by the emergency stop's step, and where that
would too, by the last pose sent held at rest (the one step that may exceed the acceleration
limit: the geometry outranks the drives).

`brake()` is the emergency stop: the same step with the target acceleration -qd / dt (stop
within one sample), scaled into the boxes, so the platform stops as fast as the limits allow
along the path it was on, then holds where it stopped.

Work per sample: three C-core calls when a sample passes (leg state, cond(J), inverse
dynamics), at most fifteen when it is limited (the leg Jacobian by six more calls of the
core's leg kinematics only when a leg is clipped into its box); no iteration. A scene with
joint cones or a clearance adds one engine call per sample (stewart_reach_margins), three when
limited (the step's pose and where it would stop), and one step more where the stop replaces it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from controller.capability import GEOMETRIC, Capability, Margins, capability, first_violated
from controller.config import ControllerConfig
from stewart_fmu.errors import SceneError
from stewart_fmu.model import Model
from stewart_fmu.native import core
from stewart_fmu.reach import LIMITS as REACH_LIMITS

LIMITS = ("stroke", "speed", "acceleration", "force", "cond", "invalid") + GEOMETRIC
# the limits of the pose alone: a cue pose beyond one is refused (stop, the last good pose held)
POSE_LIMITS = ("cond", "invalid") + GEOMETRIC
BOX_LIMITS = LIMITS[:3]     # the per-leg limits of a step's leg accelerations, in priority order
# A pose stepped at a constant pose acceleration does not move its legs at exactly constant leg
# accelerations (the kinematics are not linear): the leg rates and accelerations it ends at
# differ from the box's by up to ~3e-3 of the limits (large rotations at the limits), their
# lengths by ~1e-9 m. The box keeps this fraction of the speed and acceleration limits free for
# that, and this fraction of the length a step at the acceleration limit moves (a dt^2) at each
# end of the stroke.
TIGHTEN = 1e-2
TRACK_TIME = 0.01   # s, the time constant of the tracking law's rate loop (at least 5 samples)


def envelope_limits(model: Model, controller: ControllerConfig | None,
                    margins: Margins = Margins()) -> Capability:
    """What the envelope may use of `model`'s legs and drives (the scene's [drive] and
    [controller] tables): its capability inset by the servo's overshoot room at home, less
    `margins`. SceneError when the scene has no drive or no motor, or the stroke leaves no
    room; ValueError naming the margin when one is not in [0, 1)."""
    margins.check()
    cap = capability(model, controller)
    if cap.drive is None:
        raise SceneError("controller", "the live envelope needs the drives' limits: the scene's "
                         "[drive] and [controller.motor] tables", model.source)
    free = replace(model, leg_min=None, leg_max=None)
    home = np.asarray(model.home, dtype=float)
    held, status = core.inverse_dynamics(free.native, home, np.zeros(6), np.zeros(6))
    if status:
        raise SceneError("geometry.home", "the inverse dynamics refuse the home pose",
                         model.source)
    room = cap.room(float(np.max(np.abs(held))))
    inset = cap.inset(room)
    out = inset.less(margins)
    if not out.leg_min < out.leg_max:
        leg_min, leg_max = cap.ends
        keep = out.leg_min - inset.leg_min
        raise SceneError("geometry", f"the stroke [{leg_min:g}, {leg_max:g}] m leaves no room "
                         f"once the servo's overshoot room ({room:.3g} m) and the envelope's "
                         f"margin ({keep:.3g} m) are kept at each end", model.source)
    return out


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

    def as_dict(self) -> dict:
        """Plain numbers (for a JSON summary): per_leg as lists of six ints."""
        return {"samples": self.samples, "limited": self.limited,
                "per_limit": dict(self.per_limit),
                "per_leg": {k: [int(x) for x in v] for k, v in self.per_leg.items()}}


class Envelope:
    """The causal per-sample envelope (see the module doc) of `model`, at `dt` s a sample,
    starting at rest at `start` (default: home), which must lie inside the stroke.

    The per-leg arithmetic runs on Python floats, six legs at a time: for six numbers that is
    several times faster than numpy's per-call overhead, and the work per sample is what the
    live loop's 1 ms must hold."""

    def __init__(self, model: Model, limits: Capability, dt: float, start=None) -> None:
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        # the stroke is the envelope's own check: the core must not refuse a cue outside it
        self._p = replace(model, leg_min=None, leg_max=None).native
        self.limits, self.dt = limits, float(dt)
        self._kd = 1.0 / max(TRACK_TIME, 5.0 * self.dt)
        self._kp = self._kd / 4.0
        a_half = limits.acceleration / 2.0
        self._a_pose = np.r_[np.full(3, a_half), np.full(3, a_half / model.characteristic_length)]
        q0 = np.array(model.home if start is None else start, dtype=float)
        z = np.zeros(6)
        legs, status = self._legs(q0, z, z)
        if status or not self._cond(q0) <= limits.cond or not (
                np.all(legs[:, 0] >= limits.leg_min) and np.all(legs[:, 0] <= limits.leg_max)) \
                or self._geometry(q0, None) is not None:
            raise ValueError("the envelope's start pose must lie inside its stroke, cond, "
                             "joint cone and clearance limits")
        forces, _ = core.inverse_dynamics(self._p, q0, z, z)
        self.last = EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q0, z.copy(),
                                 z.copy(), True)
        self._lp, self._vp = self.last.lengths.tolist(), self.last.rates.tolist()
        self._hold: np.ndarray | None = None     # the pose held while the cue is refused
        self._samples = self._limited = 0
        self._per_limit = dict.fromkeys(LIMITS, 0)
        self._per_leg = {name: np.zeros(6, dtype=int) for name in LIMITS}

    # ------------------------------------------------------------------ public steps

    def step(self, q, qd, qdd) -> EnvelopeStep:
        """The sample to send for the cue sample (q, qd, qdd) (pose, Euler-angle rates and
        their derivatives)."""
        q, qd, qdd = (np.array(a, dtype=float).reshape(6) for a in (q, qd, qdd))
        reasons: dict[str, list[bool]] = {}
        legs = forces = None
        ok = all(map(math.isfinite, q.tolist() + qd.tolist() + qdd.tolist()))
        if ok:
            legs, status = self._legs(q, qd, qdd)
            ok = not status
        if not ok:
            reasons["invalid"] = [False] * 6
        elif not self._cond(q) <= self.limits.cond:
            reasons["cond"] = [False] * 6
        elif (name := self._geometry(q, self.limits.keep)) is not None:
            reasons[name] = [False] * 6
        else:
            forces, _ = core.inverse_dynamics(self._p, q, qd, qdd)
            reasons = self._check(legs.tolist(), forces.tolist())
        if not reasons:
            self._hold = None
            out = EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q, qd, qdd, True)
            return self._record(out)
        last = self.last
        if any(name in reasons for name in POSE_LIMITS):
            # stop at once (as brake()), then creep back to the last good pose
            if self._hold is None:
                self._hold = last.q
            a_des = self._kd * self._kp * (self._hold - last.q) - last.qd / self.dt
        else:
            self._hold = None
            # the cue carried back one sample (at its own acceleration) to the state's time:
            # a state on it flies onto the cue exactly with the cue's acceleration
            dt = self.dt
            e = q - qd * dt + qdd * (dt * dt / 2.0) - last.q
            approach = np.sign(e) * np.minimum(self._kp * np.abs(e),
                                               np.sqrt(2.0 * self._a_pose * np.abs(e)))
            a_des = qdd + self._kd * (qd - qdd * dt - last.qd + approach)
        return self._record(self._guarded_step(a_des, reasons))

    def brake(self) -> EnvelopeStep:
        """The emergency stop's sample: stop as fast as the limits allow (target: no pose
        rate after this sample), then hold the pose where the platform stopped."""
        return self._record(self._guarded_step(-self.last.qd / self.dt, {}))

    @property
    def interventions(self) -> Interventions:
        return Interventions(self._samples, self._limited, dict(self._per_limit),
                             {k: v.copy() for k, v in self._per_leg.items()})

    # ------------------------------------------------------------------ the checks

    def _legs(self, q, qd, qdd) -> tuple[np.ndarray, int]:
        """(rows (6, 3) of leg length, rate, acceleration; status) from the C core."""
        _, legs, status = core.twist_forces(self._p, q, qd, qdd)
        return legs, status

    def _geometry(self, q, keep) -> str | None:
        """The first joint cone or clearance (GEOMETRIC) whose margin at q is below `keep`
        (per limit; None: 0), or None (also without such limits)."""
        if self.limits.geometric is None:
            return None
        k = first_violated(self.limits.geometric.verdict(q).margins, 0.0 if keep is None else keep)
        return None if k is None else REACH_LIMITS[k].name

    def _cond(self, q) -> float:
        cond, status = core.condition_number(self._p, q)
        return cond if not status else math.inf

    def _check(self, legs: list, forces: list) -> dict[str, list[bool]]:
        """The limits a cue sample (its leg rows [l, ldot, lddot] and forces) breaks, per
        leg, as a step from the last sample sent."""
        lim, dt = self.limits, self.dt
        a, vmax, fmax, lo, hi = lim.acceleration, lim.speed, lim.force, lim.leg_min, lim.leg_max
        half, adt, jump = dt / 2.0, a * dt, a * dt * dt / 2.0
        # the braking condition as the box has it (TIGHTEN): a state passed can always stop
        a_stop = (1.0 - TIGHTEN) * a
        brake, inset = 1.0 / (2.0 * a_stop), TIGHTEN * a_stop * dt * dt
        bottom, top = lo + inset, hi - inset
        out: dict[str, list[bool]] = {}
        for i, (l, v, u) in enumerate(legs):
            lp, vp = self._lp[i], self._vp[i]
            stop = l + v * abs(v) * brake + v * half
            broken = (("stroke", not (lo <= l <= hi and bottom <= stop <= top)),
                      ("speed", not abs(v) <= vmax),
                      ("acceleration", not (abs(u) <= a and abs(v - vp) <= adt
                                            and abs(l - lp - (vp + v) * half) <= jump)),
                      ("force", not abs(forces[i]) <= fmax))
            for name, bad in broken:
                if bad:
                    out.setdefault(name, [False] * 6)[i] = True
        return out

    def _box(self, legs: list):
        """Per leg, from its state [l, ldot, ...]: the accelerations (lo, hi) allowed over the
        next sample (the stroke's braking condition first, then the speed, then the
        acceleration; where two leave nothing in common, the nearest point of the earlier
        one), which of BOX_LIMITS bounds each end, and the stroke's bounds alone."""
        lim, dt = self.limits, self.dt
        a, vmax = (1.0 - TIGHTEN) * lim.acceleration, (1.0 - TIGHTEN) * lim.speed
        inset = TIGHTEN * a * dt * dt
        top, bottom = lim.leg_max - inset, lim.leg_min + inset
        adt = a * dt
        lo, hi, by_lo, by_hi, s_lo, s_hi = [], [], [], [], [], []
        for l, v, _ in legs:
            # the next leg rate's bounds: the stroke's (vl, vh) first
            up, dn = top - l - v * dt / 2.0, l - bottom + v * dt / 2.0
            vh = -adt + math.sqrt(adt * adt + 2 * a * up) if up >= 0 else 2 * (top - l) / dt - v
            vl = adt - math.sqrt(adt * adt + 2 * a * dn) if dn >= 0 else 2 * (bottom - l) / dt - v
            if vl > vh:
                vl = vh
            s_lo.append((vl - v) / dt)
            s_hi.append((vh - v) / dt)
            # which bound is tightest at each end (BOX_LIMITS order, the first of equals)
            kh, th = 0, vh
            if vmax < th:
                kh, th = 1, vmax
            if v + adt < th:
                kh = 2
            kl, tl = 0, vl
            if -vmax > tl:
                kl, tl = 1, -vmax
            if v - adt > tl:
                kl = 2
            by_hi.append(kh)
            by_lo.append(kl)
            # within the speed, then the acceleration; the nearest point where none is left
            for lo2, hi2 in ((-vmax, vmax), (v - adt, v + adt)):
                nl = lo2 if lo2 > vl else vl
                nh = hi2 if hi2 < vh else vh
                vl, vh = (nl if nl < vh else vh), (nh if nh > vl else vl)
            lo.append((vl - v) / dt)
            hi.append((vh - v) / dt)
        return lo, hi, by_lo, by_hi, s_lo, s_hi

    # ------------------------------------------------------------------ the limited step

    def _guarded_step(self, a_des: np.ndarray, reasons: dict[str, list[bool]]) -> EnvelopeStep:
        """The limited step, unless its pose leaves a joint cone or a clearance (no margin
        kept): then the emergency stop's step, and if that leaves one too, the last pose sent
        held at rest. No sample sent lies outside those limits."""
        if self.limits.geometric is None:
            return self._limited_step(a_des, reasons)
        out = self._limited_step(a_des, dict(reasons))
        name = self._geometry(out.q, None) or self._geometry(self._stop(out), None)
        if name is None:
            return out
        _mark(reasons, name, [True] * 6)
        out = self._limited_step(-self.last.qd / self.dt, reasons)
        if self._geometry(out.q, None) is None:
            return out
        last, z = self.last, np.zeros(6)
        legs, _ = self._legs(last.q, z, z)
        forces, _ = core.inverse_dynamics(self._p, last.q, z, z)
        return EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, last.q.copy(), z, z,
                            False, tuple(n for n in LIMITS if n in reasons), np.ones(6, bool))

    def _limited_step(self, a_des: np.ndarray, reasons: dict[str, list[bool]]) -> EnvelopeStep:
        """One step of the envelope's own state with the pose acceleration a_des brought into
        the legs' boxes and the force limit (see the module doc)."""
        last, dt, p = self.last, self.dt, self._p
        q0, qd0 = last.q, last.qd
        z = np.zeros(6)
        coast = self._legs(q0, qd0, z)[0].tolist()
        c = [row[2] for row in coast]
        lo, hi, by_lo, by_hi, s_lo, s_hi = self._box(coast)
        if not all(map(math.isfinite, a_des.tolist())):
            a_des = z
        d = self._legs(q0, qd0, a_des)[0][:, 2].tolist()
        b = [min(max(x, l_), h) for x, l_, h in zip(c, lo, hi)]
        d_in = [min(max(x, l_), h) for x, l_, h in zip(d, s_lo, s_hi)]
        a_b = z
        if b != c or d_in != d:
            A = self._leg_jacobian(q0, qd0, np.array(c))
            a_b = _solve(A, np.subtract(b, c))
            if d_in != d:
                # a leg at its stroke's end goes no further; the others keep their accelerations
                _mark(reasons, "stroke", [x != y for x, y in zip(d_in, d)])
                a_des = a_des + _solve(A, np.subtract(d_in, d))
                d = d_in
        s = _largest_step(b, d, lo, hi)
        if s < 1.0:
            for k, name in enumerate(BOX_LIMITS):
                _mark(reasons, name, [(x > h and bh == k) or (x < l_ and bl == k) for
                                      x, l_, h, bl, bh in zip(d, lo, hi, by_lo, by_hi)])
        f_b = core.inverse_dynamics(p, q0, qd0, a_b)[0].tolist()
        f_d = core.inverse_dynamics(p, q0, qd0, a_des)[0].tolist()
        fmax = self.limits.force
        s_f = _largest_step(f_b, f_d, [-fmax] * 6, [fmax] * 6)
        held = [abs(x) > fmax for x in f_b]
        if s_f < s or any(held):
            # the legs whose force lowered s, and those over the limit even at s = 0
            _mark(reasons, "force", [h or (s_f < s and abs(y) > fmax)
                                     for h, y in zip(held, f_d)])
            s = min(s, s_f)
        acc = a_b + s * (a_des - a_b)
        q = q0 + qd0 * dt + acc * (dt * dt / 2.0)
        qd = qd0 + acc * dt
        legs, _ = self._legs(q, qd, acc)
        forces, _ = core.inverse_dynamics(p, q, qd, acc)
        mask = [False] * 6
        for m in reasons.values():
            mask = [x or y for x, y in zip(mask, m)]
        return EnvelopeStep(legs[:, 0].copy(), legs[:, 1].copy(), forces, q, qd, acc, False,
                            tuple(n for n in LIMITS if n in reasons), np.array(mask))

    def _stop(self, out: EnvelopeStep) -> np.ndarray:
        """Where a sample's state comes to rest braking each pose coordinate at the tracking
        law's a_p (half the acceleration limit; the stop itself runs at the legs' limits)."""
        return out.q + out.qd * np.abs(out.qd) / (2.0 * self._a_pose)

    def _leg_jacobian(self, q, qd, c: np.ndarray) -> np.ndarray:
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
                if name not in POSE_LIMITS:
                    self._per_leg[name] += out.legs
        self.last = out
        self._lp, self._vp = out.lengths.tolist(), out.rates.tolist()
        return out


def _mark(reasons: dict[str, list[bool]], name: str, legs: list[bool]) -> None:
    """Add the legs (bool per leg) a limit intervened on, when any."""
    if any(legs):
        old = reasons.get(name, [False] * 6)
        reasons[name] = [x or y for x, y in zip(old, legs)]


def _solve(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """x with A x = r; at a singular A (a singular pose) the least-squares x."""
    try:
        return np.linalg.solve(A, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, r, rcond=None)[0]


def _largest_step(b: list, d: list, lo: list, hi: list) -> float:
    """The largest s in [0, 1] with b + s (d - b) within [lo, hi] on every row, b inside."""
    s = 1.0
    for x, y, l_, h in zip(b, d, lo, hi):
        if y > h and y != x:
            s = min(s, (h - x) / (y - x))
        elif y < l_ and y != x:
            s = min(s, (l_ - x) / (y - x))
    return max(0.0, s) if math.isfinite(s) else 0.0
