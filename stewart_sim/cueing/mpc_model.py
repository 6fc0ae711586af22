"""The linear prediction model of the model-predictive cueing (stewart_sim/cueing/optimal.py).

One MPC step of length dt, zero-order hold on the inputs (Dagdelen et al. 2009, "Model-based
predictive motion cueing strategy for vehicle driving simulators", Control Eng. Practice 17;
Garrett and Best 2013, "Model predictive driving simulator motion cueing algorithm with
actuator-based constraints", Vehicle System Dynamics 51). States, all deviations from the
neutral pose `home`:

    x = (dq (6), qd (6), xv)      dq = q - home in the contract's pose coordinates (Euler angles),
                                  qd their rates, xv the vestibular states
    u = qdd (6)                   translational and Euler-angle accelerations, held over the step

The vestibular models (otolith per specific-force axis, semicircular canal per angular-velocity
axis, each a transfer function) run on the ERROR between what the platform delivers and what the
vehicle does: they are linear, so perceived(platform) - perceived(vehicle) = perceived(platform -
vehicle), and one set of states carries the perceived-motion error. Their input is

    s = [f_C - f_vehicle; omega_C - omega_vehicle]
    f_C     = R^T (a - g) + (R^T alpha) x h + w x (w x h)
            ~  f_0 + F_q dq + F_u u                      (gravity tilt, linearised at home)
    omega_C = R^T E thd     ~  F_v qd

f_C is felt at the head h (the scene's [cueing] head, in C; vestibular.delivered_motion). At
rest the rotation's terms vanish to first order except the tangential one, (R^T E thdd) x h,
which is linear in the Euler accelerations: F_u carries it exactly, and the centripetal
w x (w x h) (second order in the rates) enters with the rest of the non-linear remainder below.

With R = Rz Ry Rx at home = identity and g = (0, 0, -G): R^T w ~ w - theta x w, so
f_C ~ a - g + theta x g = (a_x - G thy, a_y + G thx, a_z + G): a positive pitch (nose down about
+Y, y to the left) delivers f_x = -G sin(thy), which is the braking cue. The matrices are not
typed in: `linearise` takes them by central differences of the exact expressions, so the signs
follow the contract's R, not a convention copied from a paper.

The leg lengths, rack forces and drive voltages are linearised by `leg_linearisation` through
our own inverse kinematics and inverse dynamics (every effect the scene declares), not at home
but at every point of the MPC's predicted trajectory (optimal.py re-linearises them each step):
far from home the mass matrix in pose coordinates and the leg Jacobian change too much for one
linearisation (the braking car's surge of 1.7 m took 1.47x the force limit with the home one).
What the home linearisation of the delivered motion leaves out (the tilt's sine, the yaw's
mixing of the axes) enters as a known input evaluated on the previous prediction, so the cost
matrix is built once.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import expm, solve_continuous_lyapunov
from scipy.signal import tf2ss

from controller.drive import AxisModel
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model

from .vestibular import delivered_motion, head_offset

NP = 12          # platform states: dq (6), qd (6)
NU = 6           # inputs: qdd
NS = 6           # vestibular inputs / perceived outputs: f (3), omega (3)
_STEP = 1e-6     # central-difference step (m, rad, m/s ...): the functions are smooth there


@dataclass(frozen=True)
class Linearisation:
    """The delivered motion linearised at the neutral pose, at rest (see the module doc)."""

    home: np.ndarray          # (6,) neutral pose
    gravity: np.ndarray       # (3,) in N
    force_neutral: np.ndarray  # (3,) f_C at home at rest: R^T (-g), m/s^2
    force_q: np.ndarray       # (3, 6) df_C / dq (gravity tilt)
    force_qdd: np.ndarray     # (3, 6) df_C / dqdd
    rate_qd: np.ndarray       # (3, 6) domega_C / dqd
    head: np.ndarray | None = None   # (3,) m in C where f_C is felt; None: C's origin


def delivered(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, gravity: np.ndarray,
              head: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """vestibular.delivered_motion (specific force and angular velocity in C, felt at `head`)
    of pose rows (N, 6)."""
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    return delivered_motion(np.zeros(Q.shape[0]), Q, qd, qdd, gravity, head)


def _jacobian(fun, x0: np.ndarray) -> np.ndarray:
    """d fun / dx at x0 by central differences (fun maps (6,) -> (m,))."""
    cols = []
    for j in range(x0.size):
        e = np.zeros_like(x0)
        e[j] = _STEP
        cols.append((fun(x0 + e) - fun(x0 - e)) / (2 * _STEP))
    return np.stack(cols, axis=1)


def linearise(home: np.ndarray, gravity: np.ndarray, head=None) -> Linearisation:
    """The delivered specific force (felt at `head`, m in C; None: C's origin) and angular
    velocity linearised at `home`, at rest."""
    home = np.asarray(home, dtype=float)
    g = np.asarray(gravity, dtype=float)
    h = head_offset(head)
    z = np.zeros(6)
    return Linearisation(
        home=home, gravity=g, force_neutral=delivered(home, z, z, g, h)[0][0],
        force_q=_jacobian(lambda q: delivered(q, z, z, g, h)[0][0], home),
        force_qdd=_jacobian(lambda a: delivered(home, z, a, g, h)[0][0], z),
        rate_qd=_jacobian(lambda qd: delivered(home, qd, z, g, h)[1][0], z), head=h)


@dataclass(frozen=True)
class LegLinearisation:
    """Leg lengths, rack forces and drive voltages at K points (q, qd, qdd), with their
    Jacobians in x = (q, qd) (12) and u = qdd (6): value(x, u) ~ value + d_x dx + d_u du."""

    lengths: np.ndarray         # (K, 6) m
    length_q: np.ndarray        # (K, 6, 6) dl / dq
    sigma: np.ndarray           # (K, 6) N, rack force (inverse_dynamics: every declared effect)
    sigma_x: np.ndarray         # (K, 6, 12)
    sigma_u: np.ndarray         # (K, 6, 6) (the mass matrix in pose coordinates)
    voltage: np.ndarray | None  # (K, 6) V: R sigma / Kf + Ke' ldot (None: no drive model)
    voltage_x: np.ndarray | None
    voltage_u: np.ndarray | None


def leg_linearisation(model: Model, axis: AxisModel | None, q, qd, qdd) -> LegLinearisation:
    """Values and Jacobians of the leg quantities at each point, by central differences in q
    and qd and an exact difference in qdd (sigma is affine in qdd), all points and
    perturbations in one batch through stewart_fmu's inverse kinematics and dynamics.

    The Jacobians leave Coulomb friction out (coulomb sign(ldot_i) along leg i is a jump, no
    slope, at rest): its value is in `sigma`, so a linear model through the point carries it.
    The stroke does not stop the dynamics here (as in feasibility.py): a prediction that leans
    on the stroke's slack is still linearised."""
    Q, QD, QDD = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    K = Q.shape[0]
    eye = np.eye(6) * _STEP
    # rows: base, q + e_j, q - e_j, qd + e_j, qd - e_j, qdd + e_j (j = 0..5): 31 per point
    dq = np.concatenate([np.zeros((1, 6)), eye, -eye, np.zeros((18, 6))])
    dqd = np.concatenate([np.zeros((13, 6)), eye, -eye, np.zeros((6, 6))])
    dqdd = np.concatenate([np.zeros((25, 6)), eye])
    P = dq.shape[0]
    Qb = (Q[:, None] + dq[None]).reshape(-1, 6)
    QDb = (QD[:, None] + dqd[None]).reshape(-1, 6)
    QDDb = (QDD[:, None] + dqdd[None]).reshape(-1, 6)
    kin = inverse_kinematics(model, Qb, QDb, with_cond=False)
    free = replace(model, leg_min=None, leg_max=None)
    sigma = inverse_dynamics(free, Qb, QDb, QDDb)
    coulomb = model.friction.coulomb_legs if model.friction is not None else 0.0
    smooth = (sigma - coulomb * np.sign(kin.rates)).reshape(K, P, 6)
    L = kin.lengths.reshape(K, P, 6)

    def central(a, first):
        return np.transpose(a[:, first:first + 6] - a[:, first + 6:first + 12], (0, 2, 1)) \
            / (2 * _STEP)

    sigma_x = np.concatenate([central(smooth, 1), central(smooth, 13)], axis=2)
    sigma_u = np.transpose(smooth[:, 25:31] - smooth[:, :1], (0, 2, 1)) / _STEP
    out = {"lengths": L[:, 0], "length_q": central(L, 1), "sigma": sigma.reshape(K, P, 6)[:, 0],
           "sigma_x": sigma_x, "sigma_u": sigma_u, "voltage": None, "voltage_x": None,
           "voltage_u": None}
    if axis is not None:
        ohm = axis.motor.resistance / axis.force_constant
        rates = kin.rates.reshape(K, P, 6)
        v_smooth = ohm * smooth + axis.emf_constant * rates
        out.update(voltage=axis.voltage(out["sigma"] / axis.force_constant, 0.0, rates[:, 0]),
                   voltage_x=np.concatenate([central(v_smooth, 1), central(v_smooth, 13)],
                                            axis=2),
                   voltage_u=ohm * sigma_u)
    return LegLinearisation(**out)


@dataclass(frozen=True)
class PredictionModel:
    """x+ = A x + B u + E w over one step dt (exact zero-order-hold discretisation), perceived
    error y = C x + D u + G w; w = (delivered minus vehicle specific force and angular velocity,
    beyond the linear part in x and u), held over the step."""

    dt: float
    A: np.ndarray   # (n, n)
    B: np.ndarray   # (n, 6)
    E: np.ndarray   # (n, 6)
    C: np.ndarray   # (6, n)
    D: np.ndarray   # (6, 6)
    G: np.ndarray   # (6, 6)

    @property
    def n(self) -> int:
        return self.A.shape[0]


def vestibular_state_space(channels: Sequence[tuple[Sequence[float], Sequence[float]]]
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Block-diagonal (A, B, C, D) of six single-input single-output transfer functions
    (num, den), in the order f_x, f_y, f_z, omega_x, omega_y, omega_z."""
    blocks = [_scaled(*tf2ss(np.asarray(num, float), np.asarray(den, float)))
              for num, den in channels]
    sizes = [b[0].shape[0] for b in blocks]
    n = sum(sizes)
    A, B, C = np.zeros((n, n)), np.zeros((n, len(blocks))), np.zeros((len(blocks), n))
    D = np.zeros((len(blocks), len(blocks)))
    i = 0
    for k, (a, b, c, d) in enumerate(blocks):
        m = a.shape[0]
        A[i:i + m, i:i + m], B[i:i + m, k], C[k, i:i + m], D[k, k] = a, b[:, 0], c[0], d[0, 0]
        i += m
    return A, B, C, D


def _scaled(a, b, c, d):
    """The same transfer function with each state divided by its RMS response to unit white
    noise (the square root of the controllability Gramian's diagonal): the companion form's
    states span orders of magnitude (a canal's 5 ms pole puts 200 in its output row), which
    the QP's solver would see as a badly scaled Hessian."""
    gramian = solve_continuous_lyapunov(a, -b @ b.T)
    T = np.sqrt(np.clip(np.diag(gramian), 0.0, None))
    T = np.where(T > 0, T, 1.0)
    return a * T[None, :] / T[:, None], b / T[:, None], c * T[None, :], d


def prediction_model(lin: Linearisation,
                     channels: Sequence[tuple[Sequence[float], Sequence[float]]],
                     dt: float) -> PredictionModel:
    """The augmented continuous model (double integrators per pose coordinate, vestibular
    transfer functions on the delivered-minus-vehicle motion) discretised exactly for a
    zero-order hold on u and w over dt (matrix exponential of the augmented system)."""
    Av, Bv, Cv, Dv = vestibular_state_space(channels)
    nv = Av.shape[0]
    n = NP + nv
    Fx = np.zeros((NS, NP))          # s = Fx [dq; qd] + Fu u + w
    Fx[:3, :6] = lin.force_q
    Fx[3:, 6:] = lin.rate_qd
    Fu = np.zeros((NS, NU))
    Fu[:3] = lin.force_qdd
    Ac = np.zeros((n, n))
    Ac[:6, 6:12] = np.eye(6)
    Ac[NP:, :NP] = Bv @ Fx
    Ac[NP:, NP:] = Av
    Bc = np.zeros((n, NU))
    Bc[6:12] = np.eye(6)
    Bc[NP:] = Bv @ Fu
    Ec = np.zeros((n, NS))
    Ec[NP:] = Bv
    M = np.zeros((n + NU + NS, n + NU + NS))
    M[:n, :n], M[:n, n:n + NU], M[:n, n + NU:] = Ac, Bc, Ec
    Phi = expm(M * dt)
    C = np.zeros((NS, n))
    C[:, :NP] = Dv @ Fx
    C[:, NP:] = Cv
    return PredictionModel(dt, Phi[:n, :n], Phi[:n, n:n + NU], Phi[:n, n + NU:], C, Dv @ Fu, Dv)
