"""The classical washout: vehicle specific force and angular velocity -> platform pose.

Reid, L. D. and Nahon, M. A., "Flight simulation motion-base drive algorithms", Parts 1-3,
UTIAS Reports, University of Toronto (1985-86); Nahon, M. A. and Reid, L. D., "Simulator
motion-drive algorithms: a designer's perspective", J. Guidance, Control, and Dynamics 13(2),
1990.
Three channels, as there:

- translational: the specific force's deviation from rest is scaled and limited per axis,
  rotated into the inertial frame with the platform's orientation, gravity added back
  (a = R f_s + g, zero at rest), high-passed (second order s^2 / (s^2 + 2 zeta w s + w^2), or
  third order with the extra first-order factor s / (s + w_b) that washes the position back to
  zero under a sustained input) and integrated twice to the platform position;
- tilt coordination: the scaled specific force (x, y) is low-passed (second order) and
  turned into the pitch and roll at which gravity alone gives it in the platform's frame,
  rate-limited (tilt_rate_limit, below the tilt-rate perception threshold) and limited in
  angle;
- rotational: the angular velocity is scaled and limited per axis, high-passed (first or
  second order), turned into Euler-angle rates with the platform's (total) Euler angles and
  integrated; the tilt is added.

Signs, with the contract's R = Rz(thz) Ry(thy) Rx(thx): a platform at rest with orientation R
has the specific force R^T (-g) = g (-sin thy, cos thy sin thx, cos thy cos thx) in its own
frame. A sustained forward acceleration (f_x > 0: the seat pushes the occupant forward) is
therefore given by thy = -asin(f_x / g) (nose UP: thy > 0 tips the x axis down), a leftward
one (f_y > 0) by thx = +asin(f_y / g) (right side down). The classical algorithm takes the two
separately (the delivered lateral specific force is f_y cos(thy), a second-order difference).

Discrete time: every linear filter is propagated exactly for the input interpolated linearly
between samples (filters.py); position, velocity and acceleration, angular velocity and its
derivative are the filters' own states. The Euler-angle kinematics thetadot = T(theta) w is
nonlinear and integrated with Heun's method (the trapezoidal rule with an Euler predictor,
second order); the stored rates are re-evaluated at the corrected angles, so q is the
trapezoidal integral of qd. The tilt follows its command exactly while the command's rate is
within the limit; otherwise it moves at the limit rate (rate +-limit, acceleration 0).

The vehicle is taken to be at rest before t[0] (all filters start at zero state); the vehicle
frame is aligned with the platform at its neutral pose (home). The cue's angles are added to
home's, as the contract adds pose coordinates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stewart_fmu.rotations import GIMBAL_LIMIT, euler_motion
from stewart_fmu.errors import KinematicsError

from .config import CueingConfig
from .filters import foh_states, input_slope, top_derivative
from .motion import VehicleMotion


@dataclass(frozen=True)
class Cue:
    """The platform trajectory a washout asks for, in the contract's pose coordinates."""

    t: np.ndarray      # (N,) s
    q: np.ndarray      # (N, 6) absolute platform pose (home + cue), m and rad
    qd: np.ndarray     # (N, 6) its derivative (Euler-angle rates for the angles)
    qdd: np.ndarray    # (N, 6)
    tilt: np.ndarray   # (N, 2) the tilt-coordination part of (roll, pitch), rad


def classical_washout(config: CueingConfig, motion: VehicleMotion, home: np.ndarray,
                      gravity: np.ndarray) -> Cue:
    """The classical washout (Reid & Nahon 1985) of a vehicle motion: the platform pose, rates
    and accelerations at the motion's samples (see the module doc for the algorithm)."""
    t = np.asarray(motion.t, dtype=float)
    h = float((t[-1] - t[0]) / (t.size - 1))
    gravity = np.asarray(gravity, dtype=float)
    g = float(np.linalg.norm(gravity))
    rest = np.array([0.0, 0.0, g])
    f_s = rest + np.clip(np.asarray(config.translational_gain) * (motion.specific_force - rest),
                         -np.asarray(config.translational_limit),
                         np.asarray(config.translational_limit))
    w_s = np.clip(np.asarray(config.rotational_gain) * motion.angular_velocity,
                  -np.asarray(config.rotational_limit), np.asarray(config.rotational_limit))

    tilt, tilt_d, tilt_dd = tilt_coordination(config, f_s[:, :2], g, h)
    w_hp, w_hp_d = _rotational_high_pass(config, w_s, h)
    ang, ang_d = _euler_kinematics(w_hp, tilt, tilt_d, h, t)
    ang_dd = _euler_acceleration(ang, ang_d, w_hp, w_hp_d, tilt_dd)
    pos, vel, acc = _translational(config, f_s, ang, gravity, h)

    q = np.asarray(home, dtype=float) + np.column_stack([pos, ang])
    return Cue(t=t, q=q, qd=np.column_stack([vel, ang_d]), qdd=np.column_stack([acc, ang_dd]),
               tilt=tilt)


def high_pass_denominator(frequency: float, damping: float, order: int,
                          first_order: float = 0.0) -> np.ndarray:
    """d(s) of the washout's high-pass s^order / d(s): order 1: s + w; order 2:
    s^2 + 2 zeta w s + w^2; order 3: (s^2 + 2 zeta w s + w^2)(s + w_b)."""
    if order == 1:
        return np.array([1.0, frequency])
    second = np.array([1.0, 2.0 * damping * frequency, frequency ** 2])
    return second if order == 2 else np.convolve(second, [1.0, first_order])


def tilt_coordination(config: CueingConfig, f_xy: np.ndarray, g: float,
                      h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(roll, pitch) tilt, its rate and acceleration (each (N, 2)) from the scaled specific
    force (x, y): second-order low-pass w^2 / (s^2 + 2 zeta w s + w^2), then
    roll = asin(f_y / g), pitch = -asin(f_x / g) (clipped to tilt_limit), rate-limited."""
    n = f_xy.shape[0]
    if config.tilt_limit == 0.0:
        zero = np.zeros((n, 2))
        return zero, zero.copy(), zero.copy()
    w, z = config.tilt_frequency, config.tilt_damping
    den = np.array([1.0, 2.0 * z * w, w * w])
    u = f_xy[:, ::-1] * np.array([1.0, -1.0])  # (f_y, -f_x): the sign of (roll, pitch)
    states = foh_states([den, den], u, h)
    cmd, cmd_d, cmd_dd = (np.empty((n, 2)) for _ in range(3))
    s_max = math.sin(config.tilt_limit)
    for j, st in enumerate(states):
        r = w * w * st[:, 0] / g                      # low-passed f / g
        rd = w * w * st[:, 1] / g
        rdd = w * w * top_derivative(den, st, u[:, j]) / g
        inside = np.abs(r) < s_max
        rc = np.clip(r, -s_max, s_max)
        root = np.sqrt(1.0 - rc * rc)
        cmd[:, j] = np.arcsin(rc)
        # d/dt asin(r) = r' / sqrt(1 - r^2); d2/dt2 = r'' / sqrt(1 - r^2) + r r'^2 / (1 - r^2)^1.5
        cmd_d[:, j] = np.where(inside, rd / root, 0.0)
        cmd_dd[:, j] = np.where(inside, rdd / root + rc * rd * rd / root ** 3, 0.0)
    return rate_limit(cmd, cmd_d, cmd_dd, config.tilt_rate_limit, h)


def rate_limit(cmd: np.ndarray, cmd_d: np.ndarray, cmd_dd: np.ndarray, limit: float,
               h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The command (starting at its first sample) followed at a rate of at most `limit`:
    equal to it while it can be (its rate clipped to +-limit, its acceleration 0 where
    clipped), else moving towards it by limit * h per sample (rate +-limit, acceleration 0)
    until it catches up. No sample moves by more than limit * h."""
    n, step = cmd.shape[0], limit * h
    out = cmd.copy()
    out_d = np.clip(cmd_d, -limit, limit)
    out_dd = np.where(np.abs(cmd_d) > limit, 0.0, cmd_dd)
    for j in range(cmd.shape[1]):
        c = cmd[:, j].tolist()
        k = 0
        # Only where the command steps further than the limit does the tilt fall behind; the
        # lag is followed sample by sample until the tilt meets the command again.
        for start in np.flatnonzero(np.abs(np.diff(cmd[:, j])) > step).tolist():
            if start < k:
                continue
            x, k = c[start], start + 1
            while k < n:
                x += min(max(c[k] - x, -step), step)
                if x == c[k]:
                    break
                out[k, j], out_d[k, j], out_dd[k, j] = x, math.copysign(limit, c[k] - x), 0.0
                k += 1
    return out, out_d, out_dd


def _rotational_high_pass(config: CueingConfig, w_s: np.ndarray,
                          h: float) -> tuple[np.ndarray, np.ndarray]:
    """High-passed angular velocity (vehicle frame) and its derivative, both (N, 3)."""
    dens = [high_pass_denominator(config.rotational_frequency[i], config.rotational_damping[i],
                                  config.rotational_order) for i in range(3)]
    states = foh_states(dens, w_s, h)
    slope = input_slope(w_s, h)
    w_hp, w_hp_d = np.empty_like(w_s), np.empty_like(w_s)
    for i, (den, st) in enumerate(zip(dens, states)):
        top = top_derivative(den, st, w_s[:, i])      # z^(m): the high-passed rate
        w_hp[:, i] = top
        # z^(m+1) = u' - a . (z', ..., z^(m))
        w_hp_d[:, i] = slope[:, i] - np.column_stack([st[:, 1:], top]) @ den[:0:-1]
    return w_hp, w_hp_d


def _euler_kinematics(w_hp: np.ndarray, tilt: np.ndarray, tilt_d: np.ndarray, h: float,
                      t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cue angles (tilt added) and their rates: the high-passed part beta integrates
    betadot = T(beta + tilt) w_hp by Heun's method; the rates stored are T at the corrected
    angles (the next step's predictor slope). T written out (_body_to_euler_rates) for speed."""
    n = w_hp.shape[0]
    p, q, r = (w_hp[:, i].tolist() for i in range(3))
    tx, ty = tilt[:, 0].tolist(), tilt[:, 1].tolist()
    bx, by, bz = [0.0] * n, [0.0] * n, [0.0] * n
    dx, dy, dz = [0.0] * n, [0.0] * n, [0.0] * n
    dx[0], dy[0], dz[0] = _body_to_euler_rates(tx[0], ty[0], p[0], q[0], r[0], t[0])
    half = 0.5 * h
    sin, cos, tan = math.sin, math.cos, math.tan
    for k in range(n - 1):
        j = k + 1
        pj, qj, rj = p[j], q[j], r[j]
        ex, ey, ez = dx[k], dy[k], dz[k]
        # predictor: Euler step, then T at the predicted angles
        phi, th = bx[k] + h * ex + tx[j], by[k] + h * ey + ty[j]
        ct = cos(th)
        if -GIMBAL_LIMIT < ct < GIMBAL_LIMIT:
            _body_to_euler_rates(phi, th, pj, qj, rj, t[j])       # raises, naming the time
        sp, cp = sin(phi), cos(phi)
        m = qj * sp + rj * cp
        bx[j] = x1 = bx[k] + half * (ex + pj + tan(th) * m)
        by[j] = y1 = by[k] + half * (ey + qj * cp - rj * sp)
        bz[j] = bz[k] + half * (ez + m / ct)
        # corrector's rates: T at the corrected angles
        phi, th = x1 + tx[j], y1 + ty[j]
        ct = cos(th)
        if -GIMBAL_LIMIT < ct < GIMBAL_LIMIT:
            _body_to_euler_rates(phi, th, pj, qj, rj, t[j])
        sp, cp = sin(phi), cos(phi)
        m = qj * sp + rj * cp
        dx[j], dy[j], dz[j] = pj + tan(th) * m, qj * cp - rj * sp, m / ct
    ang = np.column_stack([np.add(bx, tx), np.add(by, ty), bz])
    return ang, np.column_stack([np.add(dx, tilt_d[:, 0]), np.add(dy, tilt_d[:, 1]), dz])


def _body_to_euler_rates(phi: float, theta: float, p: float, q: float, r: float,
                         time: float) -> tuple[float, float, float]:
    """Euler-angle rates of R = Rz Ry Rx for the body-frame angular velocity (p, q, r):
    thetadot = (R^T E)^{-1} w (the contract's E, expressed in the platform frame)."""
    ct = math.cos(theta)
    if -GIMBAL_LIMIT < ct < GIMBAL_LIMIT:
        raise KinematicsError(f"washout: pitch at +-90 deg (gimbal lock of the Euler angles) "
                              f"at t = {time!r} s")
    sp, cp = math.sin(phi), math.cos(phi)
    m = q * sp + r * cp
    return p + math.tan(theta) * m, q * cp - r * sp, m / ct


def _euler_acceleration(ang: np.ndarray, ang_d: np.ndarray, w: np.ndarray, w_d: np.ndarray,
                        tilt_dd: np.ndarray) -> np.ndarray:
    """d/dt of T(theta) w + the tilt's acceleration: the time derivative of the body-to-Euler
    rate map along the angles' own rates, plus T applied to the high-passed w'."""
    phi, th = ang[:, 0], ang[:, 1]
    phid, thd = ang_d[:, 0], ang_d[:, 1]
    sp, cp, ct, tt = np.sin(phi), np.cos(phi), np.cos(th), np.tan(th)
    p, q, r = w.T
    pd, qd, rd = w_d.T
    m, n = q * sp + r * cp, q * cp - r * sp
    md = qd * sp + rd * cp + n * phid                 # d/dt (q sin phi + r cos phi)
    acc = np.column_stack([
        pd + thd / ct ** 2 * m + tt * md,
        qd * cp - rd * sp - m * phid,
        md / ct + m * np.sin(th) * thd / ct ** 2,
    ])
    acc[:, :2] += tilt_dd
    return acc


def _translational(config: CueingConfig, f_s: np.ndarray, ang: np.ndarray, gravity: np.ndarray,
                   h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Platform position, velocity, acceleration (N, 3): a = R(angles) f_s + g high-passed and
    integrated twice; the filter P(s) = s^(order-2) / d(s) gives position z^(order-2),
    velocity z^(order-1) and acceleration z^(order) from one state."""
    n = f_s.shape[0]
    pose = np.zeros((n, 6))
    pose[:, 3:] = ang
    R, om, al = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    zero = np.zeros((n, 6))
    euler_motion(pose, zero, zero, R, om, al)
    a = np.einsum("nij,nj->ni", R, f_s) + gravity
    order = config.translational_order
    dens = [high_pass_denominator(config.translational_frequency[i],
                                  config.translational_damping[i], order,
                                  config.translational_first_order[i]) for i in range(3)]
    states = foh_states(dens, a, h)
    pos, vel, acc = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for i, (den, st) in enumerate(zip(dens, states)):
        pos[:, i] = st[:, order - 2]
        vel[:, i] = st[:, order - 1]
        acc[:, i] = top_derivative(den, st, a[:, i])
    return pos, vel, acc
