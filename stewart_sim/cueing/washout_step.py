"""The classical washout (washout.py's module doc: the algorithm) stepped one vehicle sample at
a time, for a live loop; `classical_washout` is this stepper's loop over a recorded motion, so
the offline and the live cue are one computation.

Every part is causal at a fixed period h:
- the linear filters (filters.FilterBank) need u_{k+1} only to reach x_{k+1};
- the rotational high-pass's derivative w_hp' = u' - a . (z', ..., z^(m)) takes the input's
  slope u' from the samples up to t_k: the second-order backward difference
  (3 u_k - 4 u_{k-1} + u_{k-2}) / (2 h) (the left slope (u_k - u_{k-1}) / h at the second
  sample, zero at the first: the vehicle at rest before it). A central difference, the mean
  of the slopes either side, needs u_{k+1}, which a live loop does not have. The left slope
  alone, the exact derivative from the left of the filter's response to the piecewise-linear
  input, is only first order: the angular acceleration then differs from the derivative of
  the angular rate by O(h) (3e-3 rad/s^2 at 100 Hz on a smooth motion,
  tests/app/test_cueing_washout.py's second-order check), the backward difference by O(h^2);
- the tilt-rate limiter (rate_limit_step) and the Euler-angle kinematics (heun_step) are
  per-sample by nature.

Position limiter (the scene's [cueing] position_limit, per axis): the translational channel's
position p goes through a smooth saturation with a linear zone, Schwarz's nonlinear scaling
(C. W. Schwarz, "Two mitigation strategies for motion system limits in driving and flight
simulators", IEEE Trans. Systems, Man, and Cybernetics A 37(4), 2007: a soft limiter whose
corner at the limit is smoothed) applied to the position: untouched up to the knee
POSITION_KNEE * limit, beyond it knee + (limit - knee) tanh((|p| - knee) / (limit - knee)),
which never reaches the limit. Its slope is 1 and its curvature 0 on both sides of the knee
(tanh'(0) = 1, tanh''(0) = 0), so the velocity f'(p) v and the acceleration f'(p) a +
f''(p) v^2 (the chain rule) stay continuous; the filters themselves are not touched, so the
position comes back out of the limit as the washout returns it. (A cubic Hermite corner, as in
Schwarz, has a jump in f'' and so in the acceleration.) The price is the braking as the
position bends: |f''| <= 4 / (3 sqrt(3)) / room = 0.770 / room (room = limit - knee), so the
delivered acceleration is at most |a| + 0.770 v^2 / room: a limit far inside the washout's own
excursion, entered fast, brakes hard (a 0.05 m limit on the shipped braking's 0.35 m, entered
at 0.62 m/s: 12 m/s^2).

The first step is the motion's first sample: the vehicle is at rest before it and every filter
starts at zero state (the offline convention).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import KinematicsError
from stewart_fmu.rotations import GIMBAL_LIMIT

from stewart_sim.scene.cueing_config import CueingConfig
from .filters import FilterBank, high_pass_denominator

Vector3 = tuple[float, float, float]
# fraction of position_limit up to which the position limiter leaves the position untouched:
# half the room is cued as it is, the other half bends the excursion towards the limit
POSITION_KNEE = 0.5


@dataclass(frozen=True)
class CueSample:
    """One sample of the cue (the rows of washout.Cue at one time)."""

    q: np.ndarray      # (6,) absolute platform pose (home + cue), m and rad
    qd: np.ndarray     # (6,) its derivative (Euler-angle rates for the angles)
    qdd: np.ndarray    # (6,)
    tilt: np.ndarray   # (2,) the tilt-coordination part of (roll, pitch), rad


class WashoutStepper:
    """The classical washout of `config`, one vehicle sample per `step` at the period h (s).
    `start` (s) is the first sample's time, for error messages only."""

    def __init__(self, config: CueingConfig, home, gravity, h: float, *,
                 start: float = 0.0) -> None:
        self._h = float(h)
        self._start = float(start)
        self._home = np.asarray(home, dtype=float).reshape(6).copy()
        gravity = np.asarray(gravity, dtype=float).reshape(3)
        self._gravity = tuple(gravity.tolist())
        self._g = float(np.linalg.norm(gravity))
        self._t_gain = tuple(config.translational_gain)
        self._t_limit = tuple(config.translational_limit)
        self._r_gain = tuple(config.rotational_gain)
        self._r_limit = tuple(config.rotational_limit)
        self._tilt_on = config.tilt_limit != 0.0
        w, z = config.tilt_frequency, config.tilt_damping
        self._tilt_w2 = w * w
        self._tilt_s_max = math.sin(config.tilt_limit)
        self._rate_limit = config.tilt_rate_limit
        tilt_den = np.array([1.0, 2.0 * z * w, w * w])
        rot_dens = [high_pass_denominator(config.rotational_frequency[i],
                                          config.rotational_damping[i],
                                          config.rotational_order) for i in range(3)]
        # stage 1: tilt low-pass (roll, pitch) then the rotational high-pass, one bank: both
        # are driven by the scaled input alone
        self._first = FilterBank(([tilt_den, tilt_den] if self._tilt_on else []) + rot_dens,
                                 self._h)
        self._n_tilt = 2 if self._tilt_on else 0
        self._rot_order = config.rotational_order
        # a . (z', ..., z^(m)) of w_hp' per axis: den[:0:-1] = (a_0, ..., a_{m-1})
        self._rot_lead = [tuple(d[:0:-1].tolist()) for d in rot_dens]
        order = config.translational_order
        self._t_order = order
        self._p_limit = config.position_limit
        # stage 2: the translational high-pass, driven by a = R(angles) f_s + g
        self._second = FilterBank([high_pass_denominator(
            config.translational_frequency[i], config.translational_damping[i], order,
            config.translational_first_order[i]) for i in range(3)], self._h)
        self.reset()

    def reset(self) -> None:
        """Back to rest: the next step is a motion's first sample."""
        self._k = 0
        self._x1 = np.zeros(self._first.size)     # the banks' states
        self._x2 = np.zeros(self._second.size)
        self._u1: list[float] = []
        self._u2: list[float] = []
        self._w_prev: Vector3 = (0.0, 0.0, 0.0)
        self._w_prev2: Vector3 = (0.0, 0.0, 0.0)
        self._lag: list[float | None] = [None, None]
        self._cmd_prev = [0.0, 0.0]
        self._beta: Vector3 = (0.0, 0.0, 0.0)
        self._rate: Vector3 = (0.0, 0.0, 0.0)

    def step(self, specific_force, angular_velocity) -> CueSample:
        """The cue at the next vehicle sample: specific force (m/s^2) and angular velocity
        (rad/s), both (3,) in the vehicle frame."""
        q, qd, qdd, tilt = self.step_row(specific_force, angular_velocity)
        row = np.array(q + qd + qdd + tilt)          # one array, four views (cheaper)
        row[:6] += self._home
        return CueSample(q=row[:6], qd=row[6:12], qdd=row[12:18], tilt=row[18:])

    def step_row(self, specific_force, angular_velocity) -> tuple[list[float], list[float],
                                                                   list[float], list[float]]:
        """`step` as lists: the cue (q WITHOUT home), qd, qdd (6 each), tilt (2)."""
        # Python floats: numpy scalars would slow every operation below
        fx, fy, fz = (specific_force.tolist() if isinstance(specific_force, np.ndarray)
                      else map(float, specific_force))
        wx, wy, wz = (angular_velocity.tolist() if isinstance(angular_velocity, np.ndarray)
                      else map(float, angular_velocity))
        g, (kx, ky, kz), (lx, ly, lz) = self._g, self._t_gain, self._t_limit
        # the specific force's deviation from rest, scaled and limited, rest added back
        f_s = (min(max(kx * fx, -lx), lx), min(max(ky * fy, -ly), ly),
               g + min(max(kz * (fz - g), -lz), lz))
        (kx, ky, kz), (lx, ly, lz) = self._r_gain, self._r_limit
        w_s = (min(max(kx * wx, -lx), lx), min(max(ky * wy, -ly), ly),
               min(max(kz * wz, -lz), lz))
        first = self._k == 0
        # --- stage 1: tilt low-pass and rotational high-pass
        u1 = ([f_s[1], -f_s[0]] if self._tilt_on else []) + list(w_s)
        # the state is written back only at the end: a step that raises leaves it as it was
        out1 = self._first.start(u1) if first else self._first.advance(self._x1, self._u1, u1)
        n1 = self._first.size
        x1_state = out1[:n1]
        out1 = out1.tolist()
        x1, top1 = out1[:n1], out1[n1:]
        tilt, tilt_d, tilt_dd, lag = self._tilt(x1, top1)
        if first:           # the input's slope from the samples so far (module doc)
            slope = [0.0, 0.0, 0.0]
        elif self._k == 1:
            slope = [(w_s[i] - self._w_prev[i]) / self._h for i in range(3)]
        else:
            slope = [(3.0 * w_s[i] - 4.0 * self._w_prev[i] + self._w_prev2[i]) / (2.0 * self._h)
                     for i in range(3)]
        w_hp, w_hp_d = [0.0] * 3, [0.0] * 3
        nt, m = self._n_tilt, self._rot_order
        for i in range(3):
            top = top1[nt + i]
            o = self._first.offsets[nt + i]
            # z^(m+1) = u' - a . (z', ..., z^(m))
            lead = self._rot_lead[i]
            w_hp[i] = top
            w_hp_d[i] = slope[i] - (lead[0] * top if m == 1 else
                                    lead[0] * x1[o + 1] + lead[1] * top)
        # --- Euler-angle kinematics of the high-passed rate, the tilt added
        time = self._start + self._k * self._h
        if first:
            beta = (0.0, 0.0, 0.0)
            rate = euler_rates(tilt[0], tilt[1], w_hp[0], w_hp[1], w_hp[2], time)
        else:
            beta, rate = heun_step(self._beta, self._rate, tilt, w_hp, self._h, time)
        ang = [beta[0] + tilt[0], beta[1] + tilt[1], beta[2]]
        ang_d = [rate[0] + tilt_d[0], rate[1] + tilt_d[1], rate[2]]
        ang_dd = euler_acceleration(ang, ang_d, w_hp, w_hp_d)
        ang_dd[0] += tilt_dd[0]
        ang_dd[1] += tilt_dd[1]
        # --- stage 2: a = R(angles) f_s + g, high-passed; position, velocity, acceleration
        a = _specific_force_to_acceleration(ang, f_s, self._gravity)
        out2 = self._second.start(a) if first else self._second.advance(self._x2, self._u2, a)
        n2 = self._second.size
        x2_state = out2[:n2]
        out2 = out2.tolist()
        x2, acc = out2[:n2], out2[n2:]
        order = self._t_order
        pos = [x2[o + order - 2] for o in self._second.offsets]
        vel = [x2[o + order - 1] for o in self._second.offsets]
        if self._p_limit is not None:
            for i, limit in enumerate(self._p_limit):
                pos[i], vel[i], acc[i] = soft_limit(pos[i], vel[i], acc[i], limit)
        self._x1, self._u1, self._x2, self._u2 = x1_state, u1, x2_state, a
        self._w_prev2, self._w_prev = self._w_prev, w_s
        self._lag, self._cmd_prev = lag[0], lag[1]
        self._beta, self._rate = beta, rate
        self._k += 1
        return pos + ang, vel + ang_d, acc + ang_dd, tilt

    def _tilt(self, x1: list[float], top1: list[float]) -> tuple[list[float], list[float],
                                                                  list[float], tuple[list, list]]:
        """(roll, pitch) tilt, rate and acceleration: asin of the low-passed f / g (clipped to
        the tilt limit), rate-limited; and the limiter's next (lag, command) state."""
        if not self._tilt_on:
            return [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], (self._lag, self._cmd_prev)
        g, w2, s_max, limit = self._g, self._tilt_w2, self._tilt_s_max, self._rate_limit
        out, out_d, out_dd = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
        lag: list[float | None] = [None, None]
        cmds = [0.0, 0.0]
        for j in range(2):
            r = w2 * x1[2 * j] / g                    # low-passed f / g
            rd = w2 * x1[2 * j + 1] / g
            rdd = w2 * top1[j] / g
            rc = min(max(r, -s_max), s_max)
            root = math.sqrt(1.0 - rc * rc)
            cmd = math.asin(rc)
            # d/dt asin(r) = r' / sqrt(1 - r^2);
            # d2/dt2 = r'' / sqrt(1 - r^2) + r r'^2 / (1 - r^2)^1.5
            if abs(r) < s_max:
                cmd_d, cmd_dd = rd / root, rdd / root + rc * rd * rd / root ** 3
            else:
                cmd_d = cmd_dd = 0.0
            prev = cmd if self._k == 0 else self._cmd_prev[j]
            out[j], out_d[j], out_dd[j], lag[j] = rate_limit_step(
                self._lag[j], prev, cmd, cmd_d, cmd_dd, limit, limit * self._h)
            cmds[j] = cmd
        return out, out_d, out_dd, (lag, cmds)


def soft_limit(p: float, v: float, a: float, limit: float) -> Vector3:
    """The position limiter (module doc) on one axis: the position p, its velocity v and
    acceleration a mapped through f(p) = p up to the knee, then a tanh towards +-limit;
    velocity f'(p) v, acceleration f'(p) a + f''(p) v^2."""
    knee = POSITION_KNEE * limit
    s = abs(p)
    if s <= knee:
        return p, v, a
    room = limit - knee
    x = (s - knee) / room
    th = math.tanh(x)
    sech2 = 1.0 / math.cosh(x) ** 2 if x < 350.0 else 0.0     # cosh overflows past ~710
    sign = math.copysign(1.0, p)
    return sign * (knee + room * th), sech2 * v, sech2 * a - sign * 2.0 * th * sech2 / room * v * v


def rate_limit_step(lag: float | None, previous: float, command: float, command_d: float,
                    command_dd: float, limit: float,
                    step: float) -> tuple[float, float, float, float | None]:
    """One sample of the tilt-rate limiter: the output, its rate and acceleration, and the
    lag state (None: the output is on the command; a float: the output, behind it).

    The output equals the command while the command moves by at most `step` (= limit * h)
    per sample, its rate clipped to +-limit (acceleration 0 where clipped). A sample further
    than `step` from the previous command starts a lag: from the previous command the output
    moves towards the command by at most `step` per sample (rate +-limit, acceleration 0)
    until it lands on it. No sample moves by more than `step`."""
    if lag is None and abs(command - previous) > step:
        lag = previous
    if lag is not None:
        lag += min(max(command - lag, -step), step)
        if lag != command:
            return lag, math.copysign(limit, command - lag), 0.0, lag
    return (command, min(max(command_d, -limit), limit),
            0.0 if abs(command_d) > limit else command_dd, None)


def euler_rates(phi: float, theta: float, p: float, q: float, r: float,
                time: float) -> Vector3:
    """Euler-angle rates of R = Rz Ry Rx for the body-frame angular velocity (p, q, r):
    thetadot = (R^T E)^{-1} w (the contract's E, expressed in the platform frame)."""
    ct = math.cos(theta)
    if -GIMBAL_LIMIT < ct < GIMBAL_LIMIT:
        raise KinematicsError(f"washout: pitch at +-90 deg (gimbal lock of the Euler angles) "
                              f"at t = {time!r} s")
    sp, cp = math.sin(phi), math.cos(phi)
    m = q * sp + r * cp
    return p + math.tan(theta) * m, q * cp - r * sp, m / ct


def heun_step(beta: Vector3, rate: Vector3, tilt: list[float], w: list[float], h: float,
              time: float) -> tuple[Vector3, Vector3]:
    """One step of betadot = T(beta + tilt) w by Heun's method (the trapezoidal rule with an
    Euler predictor): beta and its rate at the previous sample, the tilt (roll, pitch) and
    the high-passed body rate w at the new one -> beta there and its rate, T at the
    corrected angles (the next step's predictor slope)."""
    p, q, r = w
    ex, ey, ez = rate
    # predictor: Euler step, then T at the predicted angles
    px, py, pz = euler_rates(beta[0] + h * ex + tilt[0], beta[1] + h * ey + tilt[1], p, q, r,
                             time)
    half = 0.5 * h
    new = (beta[0] + half * (ex + px), beta[1] + half * (ey + py), beta[2] + half * (ez + pz))
    return new, euler_rates(new[0] + tilt[0], new[1] + tilt[1], p, q, r, time)


def euler_acceleration(ang: list[float], ang_d: list[float], w: list[float],
                       w_d: list[float]) -> list[float]:
    """d/dt of T(theta) w: the body-to-Euler rate map's derivative along the angles' own rates
    times w, plus T applied to w'."""
    phi, th = ang[0], ang[1]
    phid, thd = ang_d[0], ang_d[1]
    sp, cp, ct = math.sin(phi), math.cos(phi), math.cos(th)
    p, q, r = w
    pd, qd, rd = w_d
    m, n = q * sp + r * cp, q * cp - r * sp
    md = qd * sp + rd * cp + n * phid                 # d/dt (q sin phi + r cos phi)
    return [pd + thd / ct ** 2 * m + math.tan(th) * md,
            qd * cp - rd * sp - m * phid,
            md / ct + m * math.sin(th) * thd / ct ** 2]


def _specific_force_to_acceleration(ang: list[float], f: Vector3,
                                    gravity: tuple[float, ...]) -> list[float]:
    """R f + g with the contract's R = Rz(psi) Ry(theta) Rx(phi) (stewart_fmu.rotations)."""
    cx, sx = math.cos(ang[0]), math.sin(ang[0])
    cy, sy = math.cos(ang[1]), math.sin(ang[1])
    cz, sz = math.cos(ang[2]), math.sin(ang[2])
    f0, f1, f2 = f
    return [cz * cy * f0 + (cz * sy * sx - sz * cx) * f1 + (cz * sy * cx + sz * sx) * f2
            + gravity[0],
            sz * cy * f0 + (sz * sy * sx + cz * cx) * f1 + (sz * sy * cx - cz * sx) * f2
            + gravity[1],
            -sy * f0 + cy * sx * f1 + cy * cx * f2 + gravity[2]]
