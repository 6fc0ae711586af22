"""The vestibular models: what a person perceives of a specific force and an angular velocity,
and the motion a platform delivers at the person's head.

Otolith (specific force, per axis; Young & Meiry 1968, in the form Reid & Nahon 1985 and
Telban & Cardullo 2005 use):

    f_hat / f = K (tau_a s + 1) / ((tau_L s + 1)(tau_S s + 1))
    K = 0.4, tau_a = 13.2 s, tau_L = 5.33 s, tau_S = 0.66 s

Between the break frequencies (0.19 to 1.5 rad/s, where a simulator's cues live) the gain is
0.75 to 0.89 (peak at 0.5 rad/s; asymptote K tau_a / tau_L = 0.99), so the perceived specific
force reads close to m/s^2 there and is compared with the thresholds (measured with such
transient stimuli) as it is; a sustained specific force settles at K = 0.4 of its value (the
otoliths adapt): 1 g at rest reads 3.92 m/s^2.

Semicircular canals (angular velocity, per axis; the torsion-pendulum model with adaptation of
Young & Oman 1969, in the form of Telban & Cardullo 2005):

    w_hat / w = tau_L tau_a s^2 / ((tau_L s + 1)(tau_S s + 1)(tau_a s + 1))
    tau_L = 6.1 s (roll), 5.3 s (pitch), 10.2 s (yaw); tau_S = 0.1 s; tau_a = 30 s

(the numbers as Reid & Nahon 1985 tabulate them). Gain 1 between 1/tau_L and 1/tau_S, none
for a sustained rate: a constant rotation is no longer felt after a few tau_L.

Perception thresholds (Reid & Nahon 1985, Table 2.1, also Telban & Cardullo 2005):
specific force 0.17, 0.17, 0.28 m/s^2 (x, y, z); angular velocity 3.0, 3.6, 2.6 deg/s
(roll, pitch, yaw).

References: L. R. Young, J. L. Meiry, "A revised dynamic otolith model", Aerospace Medicine
39(6), 1968. L. R. Young, C. M. Oman, "Model for vestibular adaptation to horizontal rotation",
Aerospace Medicine 40(10), 1969. L. D. Reid, M. A. Nahon, "Flight simulation motion-base drive
algorithms: Part 1", UTIAS Report 296, 1985. R. J. Telban, F. M. Cardullo, "Motion cueing
algorithm development: human-centered linear and nonlinear approaches", NASA CR-2005-213747.

The models run exactly in discrete time: each transfer function is discretised with a
zero-order hold (exact for piecewise-constant input) in parallel first-order sections,
starting in the steady state of the first sample (the person has sat in the initial motion
long enough to adapt to it).
"""
from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np
from scipy import signal

from stewart_fmu.rotations import euler_motion

from .motion import MotionError, VehicleMotion, first_irregular_step

OTOLITH_GAIN = 0.4                 # K (static gain)
OTOLITH_TAU = (13.2, 5.33, 0.66)   # s: tau_a, tau_L, tau_S (every axis)
CANAL_TAU_L = (6.1, 5.3, 10.2)     # s: roll, pitch, yaw
CANAL_TAU_S = 0.1                  # s
CANAL_TAU_A = 30.0                 # s
OTOLITH_THRESHOLD = np.array([0.17, 0.17, 0.28])           # m/s^2, x, y, z
CANAL_THRESHOLD = np.radians([3.0, 3.6, 2.6])              # rad/s, roll, pitch, yaw
AXES = ("x", "y", "z")                                    # specific force
ROTATION_AXES = ("roll", "pitch", "yaw")                  # angular velocity


def otolith_num_den(axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (descending powers of s) of the otolith model (all axes alike)."""
    _check_axis(axis)
    tau_a, tau_l, tau_s = OTOLITH_TAU
    return OTOLITH_GAIN * np.array([tau_a, 1.0]), np.polymul([tau_l, 1.0], [tau_s, 1.0])


def canal_num_den(axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (descending powers of s) of the canal model of axis 0, 1, 2
    (roll, pitch, yaw)."""
    _check_axis(axis)
    tau_l = CANAL_TAU_L[axis]
    den = np.polymul(np.polymul([tau_l, 1.0], [CANAL_TAU_S, 1.0]), [CANAL_TAU_A, 1.0])
    return np.array([tau_l * CANAL_TAU_A, 0.0, 0.0]), den


def otolith_tf(axis: int = 0) -> ct.TransferFunction:
    """The otolith model as a python-control transfer function (specific force in and out)."""
    return ct.tf(*otolith_num_den(axis), inputs=f"f{AXES[axis]}", outputs=f"f{AXES[axis]}_hat")


def canal_tf(axis: int) -> ct.TransferFunction:
    """The canal model of axis 0, 1, 2 (roll, pitch, yaw) as a python-control transfer function."""
    return ct.tf(*canal_num_den(axis), inputs=f"w{AXES[axis]}", outputs=f"w{AXES[axis]}_hat")


def otolith(t, specific_force) -> np.ndarray:
    """Perceived specific force (N, 3), m/s^2, of specific force (N, 3) sampled at uniform t
    (gain 0.75-0.89 for transients, 0.4 for a sustained force: see the module doc)."""
    return _perceive(t, specific_force, [otolith_num_den(k) for k in range(3)], "specific_force")


def semicircular_canals(t, angular_velocity) -> np.ndarray:
    """Perceived angular velocity (N, 3), rad/s, of angular velocity (N, 3) sampled at uniform t."""
    return _perceive(t, angular_velocity, [canal_num_den(k) for k in range(3)], "angular_velocity")


def delivered_motion(t, q, qd, qdd, gravity, head=None) -> tuple[np.ndarray, np.ndarray]:
    """Specific force (N, 3) and angular velocity (N, 3) felt at the head, a point fixed in the
    platform frame C at `head` (m, from C's origin; None or zeros: the origin itself), in C,
    for poses q and their Euler-rate derivatives qd, qdd (N, 6) in N:

        f = R^T (a + alpha x r + omega x (omega x r) - g)      r = R head
          = R^T (a - g) + (R^T alpha) x head + w x (w x head)
        w = R^T omega = R^T E(theta) thetadot

    a: the acceleration of C's origin, omega and alpha: the platform's angular velocity and
    acceleration, all in N; g the gravity vector. The second form is the first with R^T taken
    inside the cross products (R^T (u x v) = R^T u x R^T v for a rotation R). The angular
    velocity is the same at every point of a rigid body. A platform at rest feels R^T (-g)
    anywhere on it: its tilt turns part of gravity into a horizontal specific force (tilt
    coordination). C's axes are taken as the vehicle's (x forward, y left, z up)."""
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    n = q.shape[0]
    if np.shape(t) != (n,) or any(a.shape != (n, 6) for a in (q, qd, qdd)):
        raise MotionError(f"platform motion: t must have shape (N,) and q, qd, qdd (N, 6); got "
                          f"{np.shape(t)}, {q.shape}, {qd.shape}, {qdd.shape}")
    return _delivered(q, qd, qdd, np.asarray(gravity, dtype=float), head_offset(head))


def delivered_at(q, qd, qdd, gravity, head=None) -> tuple[np.ndarray, np.ndarray]:
    """delivered_motion of one sample (pose q, Euler rates qd, qdd, each (6,)): the specific
    force (3,) and angular velocity (3,) at the head, in C. For a live loop: no time axis, no
    shape checks beyond numpy's own (benchmarks/bench_delivered_at.py measures its cost)."""
    f, w = _delivered(np.reshape(np.asarray(q, dtype=float), (1, 6)),
                      np.reshape(np.asarray(qd, dtype=float), (1, 6)),
                      np.reshape(np.asarray(qdd, dtype=float), (1, 6)),
                      np.asarray(gravity, dtype=float), head_offset(head))
    return f[0], w[0]


def head_offset(head) -> np.ndarray | None:
    """The head as a (3,) float array, or None when it is the platform's origin (no offset to
    add: the origin's result stays bit for bit what it is without one)."""
    if head is None:
        return None
    h = np.asarray(head, dtype=float)
    if h.shape != (3,):
        raise MotionError(f"head: must be 3 numbers (x, y, z in m), got shape {h.shape}")
    return h if np.any(h != 0.0) else None


def _delivered(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, g: np.ndarray,
               head: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """delivered_motion's formula on checked (N, 6) rows; head None: at the origin."""
    n = q.shape[0]
    R, omega, alpha = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    euler_motion(q, qd, qdd, R, omega, alpha)
    f = np.einsum("nji,nj->ni", R, qdd[:, :3] - g)
    w = np.einsum("nji,nj->ni", R, omega)
    if head is not None:
        alpha_c = np.einsum("nji,nj->ni", R, alpha)
        f = f + _cross(alpha_c, head) + _cross(w, _cross(w, head))
    return f, w


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b of (N, 3) rows and a (3,) or (N, 3) b: np.cross's arithmetic without its
    axis handling, which costs more than the products on the few rows of a live sample."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=1)


@dataclass(frozen=True)
class Perception:
    """What a person perceives of the vehicle's motion and of the platform's, sample by sample.

    f: specific force (m/s^2), w: angular velocity (rad/s), per axis x, y, z (roll, pitch, yaw),
    vehicle frame = platform frame. error = perceived delivered - perceived vehicle. The
    delivered motion is taken at the head (`head`, m in C; zeros: the platform's origin); the
    vehicle's is as recorded (where its sensor or model put the driver).

    False cue (per axis, per sample): the delivered motion is perceived above the perception
    threshold and with the opposite sign to what the vehicle's motion is perceived as:
    |d| > threshold and d * v < 0, where d, v are the perceived delivered and vehicle signals
    taken from rest (specific force minus the perceived 1 g of sitting still, so a heave cue
    on z counts as well; angular velocity as it is). The vehicle's perceived signal may itself
    be below threshold: a clearly felt cue against a faint true one misleads all the same.
    false_cue_time_* is the total time of such samples per axis (samples x dt).
    """

    t: np.ndarray                       # (N,) s
    vehicle_f: np.ndarray               # (N, 3) m/s^2
    vehicle_w: np.ndarray               # (N, 3) rad/s
    delivered_f: np.ndarray             # (N, 3) m/s^2, at the head, frame C
    delivered_w: np.ndarray             # (N, 3) rad/s, frame C
    perceived_vehicle_f: np.ndarray     # (N, 3) m/s^2
    perceived_vehicle_w: np.ndarray     # (N, 3) rad/s
    perceived_delivered_f: np.ndarray   # (N, 3) m/s^2
    perceived_delivered_w: np.ndarray   # (N, 3) rad/s
    error_f: np.ndarray                 # (N, 3) m/s^2
    error_w: np.ndarray                 # (N, 3) rad/s
    rms_f: np.ndarray                   # (3,) m/s^2, RMS of error_f per axis
    rms_w: np.ndarray                   # (3,) rad/s
    false_cue_f: np.ndarray             # (N, 3) bool
    false_cue_w: np.ndarray             # (N, 3) bool
    false_cue_time_f: np.ndarray        # (3,) s
    false_cue_time_w: np.ndarray        # (3,) s
    threshold_f: np.ndarray             # (3,) m/s^2, OTOLITH_THRESHOLD
    threshold_w: np.ndarray             # (3,) rad/s, CANAL_THRESHOLD
    workspace_min: np.ndarray           # (6,) min of each pose coordinate q (m, rad)
    workspace_max: np.ndarray           # (6,)
    workspace_range: np.ndarray         # (6,) max - min
    head: np.ndarray                    # (3,) m, in C: where the delivered motion is felt


def perception(vehicle: VehicleMotion, t, q, qd, qdd, gravity, head=None) -> Perception:
    """Perceived vehicle motion against the perceived platform motion (poses q and their
    Euler-rate derivatives qd, qdd, (N, 6), at the vehicle's sample times t) felt at `head`
    (m, in C; None: the platform's origin), their error, its RMS, the false cues (see
    Perception) and the workspace the poses use."""
    t = np.asarray(t, dtype=float)
    if t.shape != vehicle.t.shape or not np.allclose(t, vehicle.t, rtol=0.0,
                                                     atol=1e-9 * max(vehicle.dt, 1.0)):
        raise MotionError(f"platform motion: its times must be the vehicle's ({vehicle.t.size} "
                          f"samples from {vehicle.t[0]!r} s, step {vehicle.dt!r} s)")
    q = np.asarray(q, dtype=float)
    f_del, w_del = delivered_motion(t, q, qd, qdd, gravity, head)
    pv_f = otolith(t, vehicle.specific_force)
    pv_w = semicircular_canals(t, vehicle.angular_velocity)
    pd_f, pd_w = otolith(t, f_del), semicircular_canals(t, w_del)
    rest = np.array([0.0, 0.0, np.linalg.norm(gravity)]) * _static_gain(otolith_num_den())
    false_f = _false_cues(pd_f - rest, pv_f - rest, OTOLITH_THRESHOLD)
    false_w = _false_cues(pd_w, pv_w, CANAL_THRESHOLD)
    lo, hi = q.min(axis=0), q.max(axis=0)
    return Perception(
        t, vehicle.specific_force, vehicle.angular_velocity, f_del, w_del, pv_f, pv_w, pd_f, pd_w,
        pd_f - pv_f, pd_w - pv_w, _rms(pd_f - pv_f), _rms(pd_w - pv_w), false_f, false_w,
        false_f.sum(axis=0) * vehicle.dt, false_w.sum(axis=0) * vehicle.dt,
        OTOLITH_THRESHOLD.copy(), CANAL_THRESHOLD.copy(), lo, hi, hi - lo,
        np.zeros(3) if head is None else np.array(head, dtype=float))


def _false_cues(delivered: np.ndarray, vehicle: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """Samples where the delivered perception exceeds the threshold with the wrong sign."""
    return (np.abs(delivered) > threshold) & (delivered * vehicle < 0)


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x**2, axis=0))


def _static_gain(num_den) -> float:
    num, den = num_den
    return float(num[-1] / den[-1])


def _perceive(t, x, models, name: str) -> np.ndarray:
    """Run the three per-axis models (num, den) on x (N, 3), ZOH-exact, from steady state."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or t.size < 2 or x.shape != (t.size, 3):
        raise MotionError(f"{name}: need t (N,), N >= 2, and values (N, 3); "
                          f"got {t.shape}, {x.shape}")
    k = first_irregular_step(t)
    if k is not None:
        raise MotionError(f"{name}: the times must be uniformly sampled and increasing "
                          f"(sample {k}, t = {float(t[k])!r} s)")
    dt = (t[-1] - t[0]) / (t.size - 1)
    out = np.empty_like(x)
    for k, (num, den) in enumerate(models):
        gain, coeffs, poles = zoh_parallel(num, den, dt)
        out[:, k] = gain * x[:, k]
        for c, a in zip(coeffs, poles):
            b, a_ = [1.0, -1.0], [1.0, -a]
            y, _ = signal.lfilter(b, a_, x[:, k], zi=signal.lfilter_zi(b, a_) * x[0, k])
            out[:, k] += c * y
    return out


def zoh_parallel(num, den, dt: float) -> tuple[float, np.ndarray, np.ndarray]:
    """The zero-order-hold equivalent of a strictly proper num/den with distinct real poles p_i,
    in parallel form: H(z) = H(0) + sum_i c_i (1 - z^-1) / (1 - a_i z^-1), with a_i = exp(p_i dt)
    and c_i the residues of H(s)/s at p_i (so the step response is H(0) + sum c_i exp(p_i t)
    at every sample, exactly). Returns (H(0), c, a). First-order sections keep the poles near
    z = 1 (tau_a = 30 s at 100 Hz: a = 0.99967) exact, where a cubic's coefficients would not."""
    num, den = np.atleast_1d(np.asarray(num, float)), np.atleast_1d(np.asarray(den, float))
    poles = np.roots(den)
    if np.any(np.abs(poles.imag) > 0) or np.unique(poles.real).size != poles.size \
            or np.any(poles.real >= 0) or np.trim_zeros(num, "f").size >= den.size:
        raise ValueError("zoh_parallel needs a strictly proper model with distinct stable "
                         "real poles")
    p = poles.real
    coeffs = np.polyval(num, p) / (p * np.polyval(np.polyder(den), p))
    return _static_gain((num, den)), coeffs, np.exp(p * dt)


def _check_axis(axis: int) -> None:
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
