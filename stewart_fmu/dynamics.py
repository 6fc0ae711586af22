"""Inverse and forward dynamics: compiled kernels over the Kane terms of `kane.py`.

inverse_dynamics(model, q, qd, qdd) -> sigma and forward_dynamics(model, q, qd, sigma) -> qdd
accept one sample (6,) or a trajectory (N, 6). sigma is the force the drive delivers at the rack
(Eq. 12): actuator force plus m_d lddot when the scene has a [drive].
"""
from __future__ import annotations

import numpy as np
from numba import njit

from stewart_fmu.kinematics import inverse_kinematics

from . import model as M
from .errors import SingularityError, StrokeLimitError, TrajectoryError
from .kane import twist_forces, twist_mass_matrix
from .linalg import cholesky_solve, lu_factor, lu_solve
from .model import Model
from .rotations import orientation, solve_rate_matrix
from .status import GIMBAL, NONFINITE, OK, OVERFLOW, SINGULAR, STROKE

# Smallest pivot of the LU of the scaled J^T (entries of order one) below which a pose counts as
# singular (cond(J) then exceeds ~1e10 and the forces would carry fewer than ~6 good digits).
SINGULAR_PIVOT = 1e-10
PARTS = ("platform", "lower_legs", "upper_legs", "drives", "gravity", "friction")


@njit(cache=True, error_model="numpy")
def _identity_order():
    order = np.empty((2, 6), np.int64)
    for k in range(6):
        order[0, k] = order[1, k] = k
    return order


@njit(cache=True, error_model="numpy")
def workspace():
    """Scratch for one sample, as views of one buffer (one allocation per kernel call):
    R, omega, alpha, U, R p_i, (l, ldot, lddot), J^T, gen, order, rhs, M_nu. order, where J^T's
    rows are stored for its LU, carries from sample to sample (see linalg.lu_factor)."""
    buf = np.empty(171)
    return (buf[0:9].reshape((3, 3)), buf[9:12], buf[12:15], buf[15:33].reshape((6, 3)),
            buf[33:51].reshape((6, 3)), buf[51:69].reshape((6, 3)), buf[69:105].reshape((6, 6)),
            buf[105:129].reshape((4, 6)), _identity_order(), buf[129:135],
            buf[135:171].reshape((6, 6)))


@njit(cache=True, error_model="numpy", inline="always")
def _finite(a) -> bool:
    """All six entries finite; a NaN or inf in any input reaches every output, so kernels test
    their outputs (cheap) and report NONFINITE only after the inputs are confirmed bad."""
    for j in range(6):
        if not np.isfinite(a[j]):
            return False
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _classify(status, a, b, c) -> int:
    """The error of a failed sample: a non-finite input explains any failure (an inf in x is
    not a stroke violation); otherwise an overflowed output means a near-singular pose."""
    if not (_finite(a) and _finite(b) and _finite(c)):
        return NONFINITE
    return SINGULAR if status == OVERFLOW else status


@njit(cache=True, error_model="numpy", inline="always")
def _friction(p, ld) -> float:
    """mu_i of Eq. 9: the force friction opposes to extension (sign(0) = 0)."""
    if p[M.P_HAS_FRICTION] == 0.0:
        return 0.0
    return p[M.P_VISCOUS] * ld + p[M.P_COULOMB] * np.sign(ld)


@njit(cache=True, error_model="numpy", inline="always")
def _drive_force(p, ldd) -> float:
    """m_d lddot_i of Eq. 12, the force the drive's inertia takes (absent: not computed)."""
    if p[M.P_HAS_DRIVE] == 0.0:
        return 0.0
    return p[M.P_DRIVE_MASS] * ldd


@njit(cache=True, error_model="numpy", inline="always")
def _net_force(p, sigma, leg, i) -> float:
    """sigma_i - mu_i - m_d lddot_0,i: the rack force left to move the mechanism (Eq. 12)."""
    return sigma[i] - _friction(p, leg[i, 1]) - _drive_force(p, leg[i, 2])


@njit(cache=True, error_model="numpy", inline="always")
def _factor_jacobian(JT, order) -> bool:
    """LU of the scaled J^T written by twist_forces; False if singular."""
    return lu_factor(JT, order) >= SINGULAR_PIVOT


@njit(cache=True, error_model="numpy", inline="always")
def _solve_jt(p, JT, order, rhs) -> None:
    """rhs <- J^-T rhs with the factors of _factor_jacobian; rhs comes in their row order
    (rhs[k] the entry order[0, k]) and has its moments scaled like J^T here."""
    ic = 1.0 / p[M.P_CHAR_LENGTH]
    for k in range(6):
        if order[0, k] >= 3:
            rhs[k] *= ic
    lu_solve(JT, rhs)


# Samples travel as tuples of six floats, not array views: a view costs an atomic reference
# count pair in numba, and a dozen of them per sample cost more than the arithmetic.

@njit(cache=True, error_model="numpy", inline="always")
def _row(A, n):
    """Row n of an (N, 6) array as a tuple."""
    return (A[n, 0], A[n, 1], A[n, 2], A[n, 3], A[n, 4], A[n, 5])


@njit(cache=True, error_model="numpy", inline="always")
def _inverse_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, out, n) -> int:
    """sigma = J^-T (-K*_nu - K_g,nu) + mu + m_d lddot for one sample into out[n]."""
    orientation(q, qd, qdd, R, om, al)
    status = twist_forces(p, q, R, qd, om, qdd, al, U, Rr, leg, JT, order, gen)
    if status != OK:
        return status
    if not _factor_jacobian(JT, order):
        return SINGULAR
    for k in range(6):
        j = order[0, k]
        rhs[k] = -(gen[0, j] + gen[1, j] + gen[2, j] + gen[3, j])
    _solve_jt(p, JT, order, rhs)
    ok = True
    for i in range(6):
        s = rhs[i] + _friction(p, leg[i, 1]) + _drive_force(p, leg[i, 2])
        out[n, i] = s
        ok = ok and np.isfinite(s)
    return OK if ok else OVERFLOW


@njit(cache=True, error_model="numpy", inline="always")
def _parts_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, total, out, n) -> int:
    """The contributions of PARTS for one sample into out[n] (6 parts, 6 legs)."""
    status = _inverse_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, total, 0)
    if status != OK:
        return status
    has_legs = p[M.P_HAS_LEGS] != 0.0
    for k, slot in ((0, 0), (1, 1), (2, 2), (3, 4)):   # reuse the LU of J^T
        if slot in (1, 2) and not has_legs:             # absent: no solve (slot is dropped)
            for j in range(6):
                out[n, slot, j] = 0.0
            continue
        for j in range(6):
            rhs[j] = -gen[k, order[0, j]]
        _solve_jt(p, JT, order, rhs)
        for j in range(6):
            out[n, slot, j] = rhs[j]
    ok = True
    for i in range(6):
        out[n, 3, i] = _drive_force(p, leg[i, 2])
        out[n, 5, i] = _friction(p, leg[i, 1])
        for k in range(6):
            ok = ok and np.isfinite(out[n, k, i])
    return OK if ok else OVERFLOW


@njit(cache=True, error_model="numpy", inline="always")
def forward_sample(p, q, qd, sigma, R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt, out, n) -> int:
    """(M_nu + m_d J^T J) nudot = J^T (sigma - mu - m_d lddot_0) + K*_0 + K_g, then Euler rates."""
    zero = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    orientation(q, qd, zero, R, om, al)        # al = Edot thd, the Euler-rate part
    status = twist_forces(p, q, R, qd, om, zero, zero, U, Rr, leg, JT, order, gen)
    if status != OK:
        return status
    twist_mass_matrix(p, R, U, Rr, leg, Mt)
    c = p[M.P_CHAR_LENGTH]
    net = (_net_force(p, sigma, leg, 0), _net_force(p, sigma, leg, 1),
           _net_force(p, sigma, leg, 2), _net_force(p, sigma, leg, 3),
           _net_force(p, sigma, leg, 4), _net_force(p, sigma, leg, 5))
    for k in range(6):
        s = 0.0
        for i in range(6):
            s += JT[k, i] * net[i]
        # Row k of JT is row order[0, k] of J^T, its moment rows scaled by 1/c: undo that.
        j = order[0, k]
        rhs[j] = gen[0, j] + gen[1, j] + gen[2, j] + gen[3, j] + (s if j < 3 else s * c)
    if not _factor_jacobian(JT, order):
        return SINGULAR
    if not cholesky_solve(Mt, rhs):
        return SINGULAR
    ok, a0, a1, a2 = solve_rate_matrix(q, rhs[3] - al[0], rhs[4] - al[1], rhs[5] - al[2])
    if not ok:
        return GIMBAL
    result = (rhs[0], rhs[1], rhs[2], a0, a1, a2)
    for k in range(6):
        out[n, k] = result[k]
    return OK if _finite(result) else OVERFLOW


@njit(cache=True, error_model="numpy")
def _inverse_batch(p, Q, QD, QDD, out):
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    for n in range(Q.shape[0]):
        q, qd, qdd = _row(Q, n), _row(QD, n), _row(QDD, n)
        status = _inverse_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, out, n)
        if status != OK:
            return n, _classify(status, q, qd, qdd)
    return -1, OK


@njit(cache=True, error_model="numpy")
def _inverse_one(p, q, qd, qdd):
    out = np.empty((1, 6))
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    status = _inverse_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, out, 0)
    return out[0], (OK if status == OK else _classify(status, q, qd, qdd))


@njit(cache=True, error_model="numpy")
def _parts_batch(p, Q, QD, QDD, out):
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    total = np.empty((1, 6))
    for n in range(Q.shape[0]):
        q, qd, qdd = _row(Q, n), _row(QD, n), _row(QDD, n)
        status = _parts_sample(p, q, qd, qdd, R, om, al, U, Rr, leg, JT, gen, order, rhs, total,
                               out, n)
        if status != OK:
            return n, _classify(status, q, qd, qdd)
    return -1, OK


@njit(cache=True, error_model="numpy")
def _forward_batch(p, Q, QD, F, out):
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    for n in range(Q.shape[0]):
        q, qd, sigma = _row(Q, n), _row(QD, n), _row(F, n)
        status = forward_sample(p, q, qd, sigma, R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt,
                                 out, n)
        if status != OK:
            return n, _classify(status, q, qd, sigma)
    return -1, OK


@njit(cache=True, error_model="numpy")
def _forward_one(p, q, qd, sigma):
    out = np.empty((1, 6))
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    status = forward_sample(p, q, qd, sigma, R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt, out, 0)
    return out[0], (OK if status == OK else _classify(status, q, qd, sigma))


@njit(cache=True, error_model="numpy")
def leg_state_kernel(p, q, qd):
    """Leg lengths, rates and the platform's angular velocity at one pose (the kinematics part
    of the inverse kernel, at zero acceleration)."""
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = workspace()
    zero = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    orientation(q, qd, zero, R, om, al)
    twist_forces(p, q, R, qd, om, zero, al, U, Rr, leg, JT, order, gen)
    return leg[:, 0].copy(), leg[:, 1].copy(), om.copy()


def leg_state(model: Model, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lengths, rates, omega) of one pose and its rates: compiled, for per-step outputs."""
    return leg_state_kernel(model.params, q, qd)


def inverse_dynamics(model: Model, q, qd, qdd) -> np.ndarray:
    """Actuator (rack) forces sigma (Eq. 12) for poses and their derivatives, (N, 6) or (6,)."""
    return _evaluate(model, _inverse_one, _inverse_batch, ("q", "qd", "qdd"), q, qd, qdd)


def present_parts(model: Model) -> tuple[str, ...]:
    """The PARTS a model computes: absent effects are left out, not reported as zeros."""
    absent = set()
    if model.legs is None:
        absent |= {"lower_legs", "upper_legs"}
    if model.drive is None:
        absent.add("drives")
    if model.friction is None:
        absent.add("friction")
    return tuple(p for p in PARTS if p not in absent)


def inverse_dynamics_parts(model: Model, q, qd, qdd) -> dict[str, np.ndarray]:
    """inverse_dynamics by contribution: {part: (N, 6)} for the present_parts, summing to sigma."""
    q, qd, qdd = (np.atleast_2d(_as_float(a, n)) for a, n in ((q, "q"), (qd, "qd"), (qdd, "qdd")))
    _check_shapes(("q", "qd", "qdd"), (q, qd, qdd))
    out = np.empty((q.shape[0], len(PARTS), 6))
    index, status = _parts_batch(model.params, q, qd, qdd, out)
    if status:
        _raise(model, status, index, ("q", "qd", "qdd"), (q[index], qd[index], qdd[index]))
    return {name: out[:, PARTS.index(name), :] for name in present_parts(model)}


def forward_dynamics(model: Model, q, qd, sigma) -> np.ndarray:
    """Pose accelerations qdd from rack forces sigma (the inverse of inverse_dynamics)."""
    return _evaluate(model, _forward_one, _forward_batch, ("q", "qd", "sigma"), q, qd, sigma)


def _evaluate(model: Model, one, batch, names, a, b, c) -> np.ndarray:
    """Run the single-sample kernel on (6,) inputs, the batch kernel on (N, 6) ones."""
    a, b, c = _as_float(a, names[0]), _as_float(b, names[1]), _as_float(c, names[2])
    if a.ndim == 1 and a.shape == b.shape == c.shape == (6,):
        result, status = one(model.params, a, b, c)
        if status:
            _raise(model, status, 0, names, (a, b, c))
        return result
    _check_shapes(names, (a, b, c))
    out = np.empty(a.shape)
    index, status = batch(model.params, a, b, c, out)
    if status:
        _raise(model, status, index, names, (a[index], b[index], c[index]))
    return out


def _as_float(a, name: str) -> np.ndarray:
    """The input as a contiguous float64 array (no copy when it already is one)."""
    if type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous:
        return a
    try:
        return np.ascontiguousarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TrajectoryError(f"'{name}' must be numbers of shape (N, 6) or (6,): {exc}") from None


def _check_shapes(names, arrays) -> None:
    shape = arrays[0].shape
    for name, a in zip(names, arrays):
        if a.ndim not in (1, 2) or a.shape[-1] != 6 or a.shape != shape:
            raise TrajectoryError(
                f"'{name}' must have shape (N, 6) or (6,) like '{names[0]}' {shape}, got {a.shape}")


def _raise(model: Model, status: int, index: int, names, rows) -> None:
    """Turn a kernel status into the typed error, naming the sample and the values."""

    q = rows[0]
    if status == NONFINITE:
        bad = [n for n, r in zip(names, rows) if not np.all(np.isfinite(r))]
        raise TrajectoryError(
            f"non-finite value in {', '.join(bad)} at sample {index}: "
            + "; ".join(f"{n} = {np.asarray(r).tolist()}" for n, r in zip(names, rows)),
            index=index)
    if status == STROKE:
        lengths = inverse_kinematics(model, q).lengths
        raise StrokeLimitError(
            f"leg lengths {lengths.tolist()} leave the stroke [{model.leg_min}, {model.leg_max}] m "
            f"at pose {np.asarray(q).tolist()}", index=index)
    if status == GIMBAL:
        raise SingularityError(
            f"pitch thy = {q[4]!r} rad is at gimbal lock (|cos thy| < 1e-9): Euler rates undefined",
            index=index)
    cond = inverse_kinematics(model, q).cond
    raise SingularityError(f"Jacobian singular at pose {np.asarray(q).tolist()} (cond = {cond:.3g})",
                           index=index)
