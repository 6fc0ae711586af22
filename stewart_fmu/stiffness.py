"""Stiffness and modes of the platform on its elastic legs (the C core's stiffness.c).

The scene's [stiffness] makes each leg a spring about the length that holds the pose in static
equilibrium under gravity (platform, leg parts, [payload]); the joints may add flexure bending
and torsion, and a [transmission] acts in series with the strut (the motor side held). Twist
coordinates throughout: chi = (dx, dtheta) about C's origin in N, wrenches (force, moment about
C's origin) in N. The 6x6 stiffness is the Hessian of the potential energy there, with the
geometric term of the loads turning with the platform (Griffis and Duffy); the modes solve
K v = w^2 M v with the model's mass matrix at rest (platform, leg parts, drives; the drives
left out with a [transmission], held by their motors) and the payload's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import raise_status
from .errors import SceneError, UnstablePoseError
from .kinematics import COND_LIMIT, inverse_kinematics
from .model import Model
from .native import core

ORIGIN = np.zeros(3)


@dataclass(frozen=True)
class Stiffness:
    """The stiffness at a pose and the compliance at a point of the platform."""

    pose: np.ndarray          # (6,)
    matrix: np.ndarray        # (6, 6) K about C's origin, in N (N/m, N/rad, N m/rad)
    leg_forces: np.ndarray    # (6,) static leg forces holding the pose (N, positive extends)
    pivot: np.ndarray         # (3,) the point of the compliance, in C
    compliance: np.ndarray    # (6, 6) at the pivot: (displacement, rotation) per (force, moment)

    @property
    def axis_compliance(self) -> np.ndarray:
        """Displacement per newton along x, y, z (m/N), rotation per newton-metre about x, y, z
        (rad/(N m)), the pivot's, every other direction free to move."""
        return np.diag(self.compliance).copy()

    @property
    def axis_stiffness(self) -> np.ndarray:
        """1 / axis_compliance: N/m along x, y, z and N m/rad about them (a datasheet's)."""
        return 1.0 / self.axis_compliance


@dataclass(frozen=True)
class Modes:
    """The small oscillations about the static equilibrium at a pose, ascending."""

    pose: np.ndarray          # (6,)
    omega2: np.ndarray        # (6,) w^2 (rad^2/s^2)
    shapes: np.ndarray        # (6, 6) row j: mode j's twist (v, omega), v^T M v = 1
    leg_rates: np.ndarray     # (6, 6) row j: the leg length rates J v of mode j
    damping: np.ndarray | None   # (6,) damping ratios of the legs' viscous friction ([friction])

    @property
    def frequency_hz(self) -> np.ndarray:
        return np.sqrt(self.omega2) / (2.0 * np.pi)


def _checked(model: Model, q) -> np.ndarray:
    if model.stiffness is None:
        raise SceneError("stiffness", "required table is missing: the stiffness and the modes "
                         "need each leg's axial stiffness ([stiffness] leg, N/m)", model.source)
    q = np.ascontiguousarray(q, dtype=float)
    if q.shape != (6,):
        raise ValueError(f"a pose is 6 numbers (x, y, z, thx, thy, thz), got shape {q.shape}")
    return q


def static_forces(model: Model, q) -> np.ndarray:
    """The leg forces (N, positive extends) that hold pose q at rest against gravity on the
    platform, the payload and the leg parts (no [stiffness] needed): the inverse dynamics at
    rest."""
    q = np.ascontiguousarray(q, dtype=float)
    if q.shape != (6,):
        raise ValueError(f"a pose is 6 numbers (x, y, z, thx, thy, thz), got shape {q.shape}")
    sigma, st = core.static_forces(model.native, q)
    raise_status(model, st, q)
    return sigma


def stiffness(model: Model, q, pivot=ORIGIN) -> Stiffness:
    """The stiffness at pose q and the compliance at `pivot` (a point of C, default its origin)."""
    q = _checked(model, q)
    K, sigma, st = core.stiffness(model.native, model.elastic, q)
    raise_status(model, st, q)
    pivot = np.ascontiguousarray(pivot, dtype=float)
    C, st = core.compliance(model.native, model.elastic, q, pivot)
    if st == core.SINGULAR:
        raise UnstablePoseError(
            f"the stiffness at pose {q.tolist()} is not positive definite (eigenvalues "
            f"{np.linalg.eigvalsh(K).tolist()}): the loads buckle the legs")
    raise_status(model, st, q)
    return Stiffness(q, K, sigma, pivot, C)


def modes(model: Model, q) -> Modes:
    """The six modes at pose q (K v = w^2 M v), ascending; UnstablePoseError when w^2 <= 0;
    with [friction] the damping ratios (damping_ratios)."""
    q = _checked(model, q)
    w2, shapes, st = core.modes(model.native, model.elastic, q)
    raise_status(model, st, q)
    if not w2[0] > 0.0:
        raise UnstablePoseError(
            f"the pose {q.tolist()} is not a stable equilibrium on the elastic legs: mode 1 has "
            f"w^2 = {w2[0]:.6g} rad^2/s^2 <= 0 (the loads buckle the legs)")
    J, _ = core.jacobian(model.native, q)
    zeta = None
    if model.friction is not None:
        K, _, _ = core.stiffness(model.native, model.elastic, q)
        M, _ = core.modes_mass(model.native, q)
        zeta = damping_ratios(M, K, J.T @ (model.friction.viscous_legs[:, None] * J))
    return Modes(q, w2, shapes, shapes @ J.T, zeta)


def damping_ratios(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The damping ratios of M x'' + D x' + K x = 0, exact: from the eigenvalues of its
    first-order form (a mode's pair -zeta w +- i w sqrt(1 - zeta^2): zeta = -Re / |lambda|; an
    overdamped mode's two real ones l1, l2: zeta = -(l1 + l2) / (2 sqrt(l1 l2)), the reals paired
    smallest with largest), ascending in w as the undamped modes. Not the modal projection
    v^T D v / 2w, which fails where two modes lie closer than their damping couples them."""
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    lam = np.linalg.eigvals(A)
    pairs = [(abs(x), -x.real / abs(x)) for x in lam if x.imag > 0]
    real = np.sort(lam[np.abs(lam.imag) == 0].real)
    for k in range(len(real) // 2):
        l1, l2 = real[k], real[-1 - k]
        pairs.append((np.sqrt(l1 * l2), -(l1 + l2) / (2 * np.sqrt(l1 * l2))))
    pairs.sort()
    return np.array([z for _, z in pairs])


def mass_matrix(model: Model, q) -> np.ndarray:
    """The mass matrix of the modes at pose q (twist, 6x6)."""
    q = _checked(model, q)
    M, st = core.modes_mass(model.native, q)
    raise_status(model, st, q)
    return M


@dataclass(frozen=True)
class ModesMap:
    """Over N poses: the lowest frequency and the weakest translational stiffness."""

    poses: np.ndarray            # (N, 6)
    lowest_hz: np.ndarray        # (N,) the first mode's frequency
    weakest: np.ndarray          # (N,) the least translational stiffness at the pivot (N/m)
    weakest_direction: np.ndarray   # (N, 3) its unit direction in N (z component >= 0)


def regular_poses(model: Model, Q) -> np.ndarray:
    """(N,) bool: the poses of Q (N, 6) within the stroke and away from singularities
    (cond(J) < COND_LIMIT), those modes_map takes."""
    kin = inverse_kinematics(model, np.atleast_2d(np.asarray(Q, dtype=float)))
    lo = model.leg_min if model.leg_min is not None else -np.inf
    hi = model.leg_max if model.leg_max is not None else np.inf
    return np.all((kin.lengths >= lo) & (kin.lengths <= hi), axis=1) & (kin.cond < COND_LIMIT)


def modes_map(model: Model, Q, pivot=ORIGIN) -> ModesMap:
    """The lowest frequency and the weakest translational direction (the force direction that
    moves the pivot most per newton) at each pose of Q (N, 6), in one C call."""
    Q = np.ascontiguousarray(Q, dtype=float)
    if model.stiffness is None:
        _checked(model, np.zeros(6))
    W2, Cp, index, st = core.modes_batch(model.native, model.elastic, Q,
                                         np.ascontiguousarray(pivot, dtype=float))
    if index >= 0:
        if st == core.SINGULAR and np.all(np.isfinite(Q[index])):
            K, _, st2 = core.stiffness(model.native, model.elastic, Q[index])
            if st2 == core.OK:
                raise UnstablePoseError(f"the stiffness at pose {Q[index].tolist()} (pose "
                                        f"{index}) is not positive definite: the loads buckle the legs")
        raise_status(model, st, Q[index])
    if not np.all(W2[:, 0] > 0.0):
        k = int(np.argmin(W2[:, 0]))
        raise UnstablePoseError(f"pose {k} {Q[k].tolist()} is not a stable equilibrium: "
                                f"w^2 = {W2[k, 0]:.6g} <= 0")
    lam, vec = np.linalg.eigh(Cp[:, :3, :3])
    direction = vec[:, :, -1] * np.where(vec[:, 2:3, -1] < 0, -1.0, 1.0)
    return ModesMap(Q, np.sqrt(W2[:, 0]) / (2 * np.pi), 1.0 / lam[:, -1], direction)
