"""Inverse and forward kinematics, the leg Jacobian, stroke limits and the singularity measure.

The Jacobian maps the platform twist nu = (v, omega) in N to the leg rates: ldot = J nu, row i
= [u_i, (R p_i) x u_i]. The singularity measure is the condition number of J with its rotational
columns divided by the model's characteristic length (mean platform-joint radius), so that it
does not depend on the choice of units.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ForwardKinematicsError, SingularityError, StrokeLimitError
from .model import Model
from .native import core
from .rotations import euler_motion, solve_rate_matrices, solve_rate_matrix

COND_LIMIT = 1e10  # cond(J) above this counts as singular: forces keep fewer than ~6 digits
COARSE_STRIDE = 32  # forward_kinematics_many without a guess: the samples solved first


@dataclass(frozen=True)
class LegKinematics:
    """Inverse kinematics of N poses; rates and accelerations when the pose derivatives are given."""

    leg_vectors: np.ndarray    # (N, 6, 3) L_i = x + R p_i - a_i
    lengths: np.ndarray        # (N, 6)
    unit_vectors: np.ndarray   # (N, 6, 3)
    jacobian: np.ndarray       # (N, 6, 6) ldot = J nu
    cond: np.ndarray | None    # (N,) scaled condition number of J (None: not asked for)
    rates: np.ndarray | None = None          # (N, 6) ldot
    accelerations: np.ndarray | None = None  # (N, 6) lddot
    rotation: np.ndarray | None = None       # (N, 3, 3) R
    lever_arms: np.ndarray | None = None     # (N, 6, 3) R p_i, from C's origin to joint i, in N
    omega: np.ndarray | None = None          # (N, 3) platform angular velocity in N
    alpha: np.ndarray | None = None          # (N, 3) platform angular acceleration in N
    joint_velocities: np.ndarray | None = None     # (N, 6, 3) vp_i = v + omega x R p_i (with qd)
    joint_accelerations: np.ndarray | None = None  # (N, 6, 3) ap_i (with qd)


def inverse_kinematics(model: Model, q, qd=None, qdd=None, *, with_cond: bool = True
                       ) -> LegKinematics:
    """Leg vectors, lengths, unit vectors, Jacobian and cond(J); rates/accelerations if given.

    cond(J) takes an SVD per pose, the bulk of the cost: with_cond=False leaves it None."""
    q = np.asarray(q, dtype=float)
    single = q.ndim == 1
    Q = np.atleast_2d(q)
    QD = np.zeros_like(Q) if qd is None else np.atleast_2d(np.asarray(qd, dtype=float))
    QDD = np.zeros_like(Q) if qdd is None else np.atleast_2d(np.asarray(qdd, dtype=float))
    n = Q.shape[0]
    R, om, al = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    euler_motion(Q, QD, QDD, R, om, al)
    r = np.einsum("nij,kj->nki", R, model.platform_joints)          # R p_i
    L = Q[:, None, :3] + r - model.base_joints[None]
    l = np.linalg.norm(L, axis=-1)
    u = L / l[..., None]
    J = np.concatenate([u, np.cross(r, u)], axis=-1)
    scale = np.r_[np.ones(3), np.full(3, 1.0 / model.characteristic_length)]
    cond = None
    if with_cond:
        with np.errstate(all="ignore"):
            cond = np.linalg.cond(J * scale) if np.all(np.isfinite(J)) else np.full(n, np.inf)
    vp = ap = rates = accels = None      # without rates: poses only (forward kinematics' loop)
    if qd is not None:
        vp = QD[:, None, :3] + np.cross(om[:, None, :], r)
        ap = (QDD[:, None, :3] + np.cross(al[:, None, :], r)
              + np.cross(om[:, None, :], np.cross(om[:, None, :], r)))
        rates = np.einsum("nki,nki->nk", u, vp)
        # lddot = u . ap + |udot|^2 l, with udot = (vp - ldot u) / l.
        accels = np.einsum("nki,nki->nk", u, ap) + (np.einsum("nki,nki->nk", vp, vp)
                                                      - rates**2) / l
    out = LegKinematics(L, l, u, J, cond, rates, None if qdd is None else accels, R, r, om, al,
                        vp, ap)
    if single:
        out = LegKinematics(*(None if a is None else a[0] for a in vars(out).values()))
    return out


def check_poses(model: Model, q, t=None, qd=None, qdd=None) -> LegKinematics:
    """Inverse kinematics (with rates and accelerations when qd, qdd are given) that raises at
    the first pose past a stroke limit or near a singularity."""
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    kin = inverse_kinematics(model, Q, qd, qdd)
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else np.inf
    bad = np.flatnonzero(np.any((kin.lengths < lo) | (kin.lengths > hi)
                                | ~np.isfinite(kin.lengths) | (kin.lengths == 0), axis=1))
    time = (lambda k: None if t is None else float(t[k]))
    if bad.size:
        k = int(bad[0])
        legs = [i + 1 for i in range(6) if not lo <= kin.lengths[k, i] <= hi]
        raise StrokeLimitError(
            f"leg(s) {legs} with lengths {kin.lengths[k].tolist()} m outside the stroke "
            f"[{lo}, {hi}] m at pose {Q[k].tolist()}", index=k, time=time(k))
    bad = np.flatnonzero(~(kin.cond < COND_LIMIT))
    if bad.size:
        k = int(bad[0])
        raise SingularityError(
            f"Jacobian near-singular (cond = {kin.cond[k]:.3g} > {COND_LIMIT:.0e}) at pose "
            f"{Q[k].tolist()}", index=k, time=time(k))
    return kin


def forward_kinematics(model: Model, lengths, guess=None, tol: float = 1e-12,
                       max_iter: int = 50) -> np.ndarray:
    """The pose with the given six leg lengths, by Newton's method from `guess` (default home)."""
    target = np.asarray(lengths, dtype=float)
    if target.shape != (6,) or not np.all(np.isfinite(target)) or np.any(target <= 0):
        raise ForwardKinematicsError(f"leg lengths must be six finite positive numbers, got {target.tolist()}")
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else np.inf
    outside = [i + 1 for i in range(6) if not lo <= target[i] <= hi]
    if outside:
        raise StrokeLimitError(f"leg(s) {outside} with lengths {target.tolist()} m outside the "
                               f"stroke [{lo}, {hi}] m: no pose to find")
    start = np.array(model.home if guess is None else guess, dtype=float)
    q = start.copy()
    iterations, residual = _newton(model, target, q, tol * max(1.0, float(np.max(target))),
                                   max_iter)
    if iterations >= 0:
        return q
    raise ForwardKinematicsError(
        f"Newton did not converge for leg lengths {target.tolist()} from guess "
        f"{start.tolist()}: max residual {residual:.3g} m after {-iterations} iterations "
        f"(lengths unreachable or singular pose)")


@dataclass(frozen=True)
class ForwardSolution:
    """The poses of many samples' leg lengths (forward_kinematics_many)."""

    poses: np.ndarray       # (N, 6); a row that did not converge holds its last iterate
    residual: np.ndarray    # (N,) max |l(q) - target| (m) there; nan where the lengths are not
                            # six finite positive numbers
    converged: np.ndarray   # (N,) bool: residual <= tol * max(1 m, the longest leg)


def forward_kinematics_many(model: Model, lengths, guess=None, tol: float = 1e-12,
                            max_iter: int = 50) -> ForwardSolution:
    """The poses with the given leg lengths (N, 6), all samples at once: forward_kinematics's
    Newton step (J dnu = target - l, rotation mapped by E^-1) over numpy's batched inverse
    kinematics and np.linalg.solve, on the samples not yet converged.

    Starts from `guess` ((N, 6) per sample, (6,) for all; default: every COARSE_STRIDE-th
    sample from home, the others from those interpolated in sample index); a sample that does not
    converge from there starts again from the solution of its nearest converged sample (index
    distance), pass after pass while passes converge new samples: a run that leaves home's basin
    continues from its own neighbours. No stroke check (the caller's: it knows what the lengths
    are); nothing raises for a sample that fails, `converged` says which. The per-sample
    forward_kinematics stays on the core's calls: one pose per device tick, where numpy's
    per-call overhead would cost several times the C step."""
    target = np.atleast_2d(np.asarray(lengths, dtype=float))
    n = target.shape[0]
    if target.shape != (n, 6):
        raise ValueError(f"leg lengths must be (N, 6), got {target.shape}")
    q = np.empty((n, 6))
    q[:] = model.home if guess is None else np.asarray(guess, dtype=float)
    if guess is None and n > 2 * COARSE_STRIDE:
        # every COARSE_STRIDE-th sample first (from home, then its neighbours), the others
        # from the coarse poses interpolated in sample index: a good start, so two Newton
        # steps instead of the five or six that home would take.
        coarse = forward_kinematics_many(model, target[::COARSE_STRIDE], None, tol, max_iter)
        at = np.arange(0, n, COARSE_STRIDE)[coarse.converged]
        if at.size:
            good = coarse.poses[coarse.converged]
            q[:] = np.column_stack([np.interp(np.arange(n), at, good[:, c]) for c in range(6)])
    valid = np.all(np.isfinite(target) & (target > 0), axis=1)
    tol_abs = tol * np.maximum(1.0, np.max(np.where(np.isfinite(target), target, 0.0), axis=1))
    residual = np.full(n, np.nan)
    converged = np.zeros(n, dtype=bool)
    todo = np.flatnonzero(valid)
    while todo.size:
        r, c = _newton_many(model, target[todo], q, todo, tol_abs[todo], max_iter)
        residual[todo], converged[todo] = r, c
        if todo.size < np.count_nonzero(valid) and not c.any():
            break                                  # a pass from the neighbours gained nothing
        good, todo = np.flatnonzero(converged), todo[~c]
        if not good.size or not todo.size:
            break
        q[todo] = q[_nearest(good, todo)]
    return ForwardSolution(q, residual, converged)


def _nearest(good: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """For each index of idx, the nearest of the sorted indices `good` (the earlier on a tie)."""
    if len(good) == 1:
        return np.full(idx.size, good[0])
    k = np.clip(np.searchsorted(good, idx), 1, len(good) - 1)
    before, after = good[k - 1], good[k]
    return np.where(np.abs(idx - before) <= np.abs(after - idx), before, after)


def _newton_many(model: Model, target: np.ndarray, q: np.ndarray, rows: np.ndarray,
                 tol: np.ndarray, max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Newton (as _newton) in place on q[rows], target and tol per row of `rows`: returns the
    last residual and whether each converged."""
    m = rows.size
    residual, converged = np.full(m, np.inf), np.zeros(m, dtype=bool)
    active = np.arange(m)                           # positions in rows still iterating
    for it in range(max_iter):
        kin = inverse_kinematics(model, q[rows[active]], with_cond=False)
        f = target[active] - kin.lengths
        r = np.max(np.abs(f), axis=1)
        residual[active] = r
        done = r <= tol[active]
        converged[active[done]] = True
        go = ~done & np.isfinite(r)
        active, J, f = active[go], kin.jacobian[go], f[go]
        if not active.size or it == max_iter - 1:
            break
        dnu, solvable = _solve_many(J, f)
        dth, ok = solve_rate_matrices(q[rows[active]], dnu[:, 3:])
        ok &= solvable & np.all(np.isfinite(dnu), axis=1)
        q[rows[active[ok]]] += np.concatenate([dnu[ok, :3], dth[ok]], axis=1)
        active = active[ok]
    return residual, converged


def _solve_many(J: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x with J x = f for each sample, and which could be solved: an exactly singular J makes
    np.linalg.solve refuse the whole batch, so then those samples are set aside (x = 0)."""
    try:
        return np.linalg.solve(J, f[..., None])[..., 0], np.ones(len(f), dtype=bool)
    except np.linalg.LinAlgError:
        x, ok = np.zeros_like(f), np.linalg.det(J) != 0.0
        x[ok] = np.linalg.solve(J[ok], f[ok, :, None])[..., 0]
        return x, ok


def condition_number(model: Model, q) -> float:
    """cond(J) of one pose (scaled as in inverse_kinematics; the C core's SVD): for per-step
    checks. inf where the pose is not finite."""
    cond, _ = core.condition_number(model.native, np.ascontiguousarray(q, dtype=float))
    return float(cond)


def _newton(model: Model, target: np.ndarray, q: np.ndarray, tol: float, max_iter: int):
    """Newton on the leg lengths, in place on q: the step solves J dnu = -(l - target) for the
    twist increment and maps its rotation to Euler angles with E^-1 (first order, as dl/dq =
    J diag(I, E)). Returns (iterations, residual); iterations < 0: no convergence after -it."""
    zero, residual = np.zeros(6), np.inf
    for it in range(max_iter):
        lengths, _, _, _ = core.leg_state(model.native, q, zero)
        f = target - lengths
        residual = float(np.max(np.abs(f)))
        if not np.isfinite(residual):
            return -(it + 1), residual
        if residual <= tol:
            return it, residual
        J, _ = core.jacobian(model.native, q)
        try:
            dnu = np.linalg.solve(J, f)
        except np.linalg.LinAlgError:  # exactly singular on the way
            return -(it + 1), residual
        ok, d3, d4, d5 = solve_rate_matrix(q, dnu[3], dnu[4], dnu[5])
        if not ok or not np.all(np.isfinite(dnu)):
            return -(it + 1), residual
        q += (dnu[0], dnu[1], dnu[2], d3, d4, d5)
    return -max_iter, residual
