"""The paper's Kane terms, written out body by body (Section 2, Eqs. 1-14), for one sample.

This is the readable form of the model: partial velocities of every body with respect to the
generalized speeds ldot, the inertia forces and torques of every body, and their dot products.
The C core (native/src/kane.c) computes the same generalized forces through a reduction to the
platform twist; tests hold the two to 1e-10. Use these functions to inspect the model (a mass
matrix, the velocity terms at a state); use `dynamics` for speed.

Sign convention (docs/conventions.md): K* = -([m] lddot + b), K = g + [a] sigma + f, K* + K = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinematics import inverse_kinematics
from .model import Model


@dataclass(frozen=True)
class PartialVelocities:
    """Partial velocities with respect to ldot_j (Eqs. 1-2); axis -2 is j, axis -1 is x, y, z."""

    platform_linear: np.ndarray   # (6, 3) V_jP of C's origin (the platform's centre of mass)
    platform_angular: np.ndarray  # (6, 3) omega_jP
    lower_linear: np.ndarray      # (6 legs, 6, 3) V_jA_i of the lower parts' centres of mass
    upper_linear: np.ndarray      # (6 legs, 6, 3) V_jB_i
    leg_angular: np.ndarray       # (6 legs, 6, 3) omega_jL_i, shared by A_i and B_i
    payload_linear: np.ndarray | None = None   # (6, 3) V_j of the payload's centre of mass


@dataclass(frozen=True)
class BodyMotion:
    """Velocities and accelerations of every body's centre of mass, in N."""

    platform: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # v, a, omega, alpha
    lower: tuple[np.ndarray, np.ndarray]   # (6, 3) v_A, a_A
    upper: tuple[np.ndarray, np.ndarray]   # (6, 3) v_B, a_B
    leg: tuple[np.ndarray, np.ndarray]     # (6, 3) omega_L, alpha_L


def _leg_constants(model: Model) -> tuple[float, float, float, float, float, float, float, float]:
    """(m_A, c_A, It_A, Ia_A, m_B, c_B, It_B, Ia_B); zeros for massless legs."""
    lg = model.legs
    if lg is None:
        return (0.0,) * 8
    return (lg.lower_mass, lg.lower_com, *lg.lower_inertia,
            lg.upper_mass, lg.upper_com, *lg.upper_inertia)


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x for (..., 3) vectors."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def twist_partials(model: Model, q) -> tuple[np.ndarray, ...]:
    """Partial velocities with respect to the twist nu = (v, omega): (3, 6) maps per body."""
    kin = inverse_kinematics(model, q, with_cond=False)
    _, cA, _, _, _, cB, _, _ = _leg_constants(model)
    u, l, r = kin.unit_vectors, kin.lengths[:, None, None], kin.lever_arms
    P = np.eye(3) - u[:, :, None] * u[:, None, :]
    S = np.concatenate([np.broadcast_to(np.eye(3), (6, 3, 3)), -_skew(r)], axis=-1)  # vp = S nu
    VP = np.hstack([np.eye(3), np.zeros((3, 3))])
    WP = np.hstack([np.zeros((3, 3)), np.eye(3)])
    VA = (cA / l) * P @ S
    VB = (u[:, :, None] * u[:, None, :] + ((l - cB) / l) * P) @ S
    WL = (_skew(u) / l) @ S
    return VP, WP, VA, VB, WL


def partial_velocities(model: Model, q) -> PartialVelocities:
    """V_jP, omega_jP, V_jA_i, V_jB_i, omega_jL_i with respect to the leg rates (Eqs. 1-2), and
    with a [payload] its centre of mass's V_j (it turns with the platform: omega_jP)."""
    kin = inverse_kinematics(model, q, with_cond=False)
    Jinv = np.linalg.inv(kin.jacobian)  # nu = J^-1 ldot
    VP, WP, VA, VB, WL = twist_partials(model, q)
    speeds = lambda T: np.swapaxes(T @ Jinv, -1, -2)
    payload = None
    if model.payload is not None:   # v + omega x rho, rho = R c
        rho = kin.rotation @ np.asarray(model.payload.com, dtype=float)
        payload = speeds(np.hstack([np.eye(3), -_skew(rho)]))
    return PartialVelocities(speeds(VP), speeds(WP), speeds(VA), speeds(VB), speeds(WL), payload)


def _payload_inertia_n(model: Model, R: np.ndarray) -> np.ndarray:
    """The payload's inertia tensor about its centre of mass, in N."""
    return R @ model.payload.inertia_tensor @ R.T


def body_motion(model: Model, q, qd, qdd) -> BodyMotion:
    """Every body's velocity and acceleration from the pose and its derivatives."""
    kin = inverse_kinematics(model, q, qd, qdd, with_cond=False)
    _, cA, _, _, _, cB, _, _ = _leg_constants(model)
    u, l = kin.unit_vectors, kin.lengths[:, None]
    ld, ldd = kin.rates[:, None], kin.accelerations[:, None]
    ud = (kin.joint_velocities - ld * u) / l
    udd = (kin.joint_accelerations - ldd * u - 2.0 * ld * ud) / l   # from L'' = ap
    platform = (np.asarray(qd[:3], float), np.asarray(qdd[:3], float), kin.omega, kin.alpha)
    lower = (cA * ud, cA * udd)
    upper = (ld * u + (l - cB) * ud, ldd * u + 2.0 * ld * ud + (l - cB) * udd)
    return BodyMotion(platform, lower, upper, (np.cross(u, ud), np.cross(u, udd)))


def inertia_forces(model: Model, q, qd, qdd) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Inertia force F* and torque T* of every body in N (Eqs. 3-5): name -> (F*, T*)."""
    mot = body_motion(model, q, qd, qdd)
    kin = inverse_kinematics(model, q, with_cond=False)
    R, u = kin.rotation, kin.unit_vectors
    _, a, om, al = mot.platform
    Ic = model.platform_inertia
    wc, ac = R.T @ om, R.T @ al                               # in C, where I_P is diagonal
    TP = R @ -(Ic * ac + np.cross(wc, Ic * wc))               # Eq. 4 then Eq. 5
    out = {"platform": (-model.platform_mass * a, TP)}
    if model.payload is not None:   # a body off C: its centre of mass's acceleration, Eq. 4 in N
        rho = R @ np.asarray(model.payload.com, dtype=float)
        I_N = _payload_inertia_n(model, R)
        a_c = a + np.cross(al, rho) + np.cross(om, np.cross(om, rho))
        out["payload"] = (-model.payload.mass * a_c, -(I_N @ al + np.cross(om, I_N @ om)))
    mA, _, ItA, IaA, mB, _, ItB, IaB = _leg_constants(model)
    w, alL = mot.leg
    uu = u[:, :, None] * u[:, None, :]
    for name, m, It, Ia, acc in (("lower", mA, ItA, IaA, mot.lower[1]),
                                 ("upper", mB, ItB, IaB, mot.upper[1])):
        I_N = It * (np.eye(3) - uu) + Ia * uu                 # axisymmetric part about its CoM
        Iw = np.einsum("kij,kj->ki", I_N, w)
        out[name] = (-m * acc, -(np.einsum("kij,kj->ki", I_N, alL) + np.cross(w, Iw)))
    return out


def generalized_inertia_forces(model: Model, q, qd, qdd) -> np.ndarray:
    """K*_j = sum over bodies of V_j . F* + omega_j . T* (Eqs. 6-7), shape (6,)."""
    pv = partial_velocities(model, q)
    f = inertia_forces(model, q, qd, qdd)
    K = pv.platform_linear @ f["platform"][0] + pv.platform_angular @ f["platform"][1]
    if model.payload is not None:
        K = K + pv.payload_linear @ f["payload"][0] + pv.platform_angular @ f["payload"][1]
    if model.legs is not None:
        K = K + np.einsum("ijk,ik->j", pv.lower_linear, f["lower"][0])
        K = K + np.einsum("ijk,ik->j", pv.upper_linear, f["upper"][0])
        K = K + np.einsum("ijk,ik->j", pv.leg_angular, f["lower"][1] + f["upper"][1])
    return K


def gravity_terms(model: Model, q) -> np.ndarray:
    """g: the generalized active force of gravity (Eq. 8), shape (6,)."""
    pv = partial_velocities(model, q)
    mA, _, _, _, mB, _, _, _ = _leg_constants(model)
    g = model.gravity
    K = pv.platform_linear @ (model.platform_mass * g)
    if model.payload is not None:
        K = K + pv.payload_linear @ (model.payload.mass * g)
    if model.legs is not None:
        K = K + (pv.lower_linear @ (mA * g) + pv.upper_linear @ (mB * g)).sum(axis=0)
    return K


def actuator_matrix(model: Model, q) -> np.ndarray:
    """[a]_ji = (V_jB_i - V_jA_i) . u_i (Eq. 9): the identity, as the leg rates are the speeds."""
    pv = partial_velocities(model, q)
    u = inverse_kinematics(model, q, with_cond=False).unit_vectors
    return np.einsum("ijk,ik->ji", pv.upper_linear - pv.lower_linear, u)


def friction_forces(model: Model, ldot) -> np.ndarray:
    """mu_i: the friction force of each joint (its own coefficients), opposing extension
    (sign(0) = 0)."""
    ldot = np.asarray(ldot, dtype=float)
    if model.friction is None:
        return np.zeros_like(ldot)
    return model.friction.viscous_legs * ldot + model.friction.coulomb_legs * np.sign(ldot)


def friction_terms(model: Model, q, qd) -> np.ndarray:
    """f = -[a] mu: the generalized active force of joint friction (Eq. 9), shape (6,)."""
    ldot = inverse_kinematics(model, q, qd, with_cond=False).rates
    return -actuator_matrix(model, q) @ friction_forces(model, ldot)


def mass_matrix(model: Model, q) -> np.ndarray:
    """[m]_jk = sum over bodies of m V_j . V_k + omega_j . I omega_k (Eq. 7), shape (6, 6)."""
    pv = partial_velocities(model, q)
    kin = inverse_kinematics(model, q, with_cond=False)
    I_P = kin.rotation @ np.diag(model.platform_inertia) @ kin.rotation.T
    Mm = (model.platform_mass * pv.platform_linear @ pv.platform_linear.T
          + pv.platform_angular @ I_P @ pv.platform_angular.T)
    if model.payload is not None:
        Mm = Mm + (model.payload.mass * pv.payload_linear @ pv.payload_linear.T
                   + pv.platform_angular @ _payload_inertia_n(model, kin.rotation) @ pv.platform_angular.T)
    if model.legs is not None:
        mA, _, ItA, IaA, mB, _, ItB, IaB = _leg_constants(model)
        u = kin.unit_vectors
        uu = u[:, :, None] * u[:, None, :]
        I_L = (ItA + ItB) * (np.eye(3) - uu) + (IaA + IaB) * uu
        Mm = Mm + mA * np.einsum("ijk,ilk->jl", pv.lower_linear, pv.lower_linear)
        Mm = Mm + mB * np.einsum("ijk,ilk->jl", pv.upper_linear, pv.upper_linear)
        Mm = Mm + np.einsum("ijk,ikm,ilm->jl", pv.leg_angular, I_L, pv.leg_angular)
    return Mm


def velocity_terms(model: Model, q, qd) -> np.ndarray:
    """b = -K* - [m] lddot, the centrifugal and Coriolis part of Eq. 7 (any qdd gives it)."""
    zero = np.zeros(6)
    lddot = inverse_kinematics(model, q, qd, zero, with_cond=False).accelerations
    return -generalized_inertia_forces(model, q, qd, zero) - mass_matrix(model, q) @ lddot


def drive_inertia(model: Model) -> np.ndarray:
    """[m_d] = diag(zeta^2 I_i / r^2) (Eqs. 13-14, typo corrected), zeros without a drive."""
    return np.diag(model.drive.reflected_masses) if model.drive is not None else np.zeros((6, 6))


def actuator_forces(model: Model, q, qd, qdd) -> np.ndarray:
    """sigma = [a]^-1 (([m] + [m_d]) lddot + b - g - f) (Eqs. 11-12), the rack forces."""
    lddot = inverse_kinematics(model, q, qd, qdd, with_cond=False).accelerations
    rhs = ((mass_matrix(model, q) + drive_inertia(model)) @ lddot + velocity_terms(model, q, qd)
           - gravity_terms(model, q) - friction_terms(model, q, qd))
    return np.linalg.solve(actuator_matrix(model, q), rhs)
