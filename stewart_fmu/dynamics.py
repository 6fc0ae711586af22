"""Inverse and forward dynamics: the Python API over the C core's Kane kernels.

inverse_dynamics(model, q, qd, qdd) -> sigma and forward_dynamics(model, q, qd, sigma) -> qdd
accept one sample (6,) or a trajectory (N, 6). sigma is the force the drive delivers at the rack
(Eq. 12): actuator force plus m_d lddot when the scene has a [drive]. The arithmetic is the C
core's (stewart_fmu/native/src/dynamics.c: Eqs. 9-14); this module checks shapes and turns a
status code into the typed error that names the sample.
"""
from __future__ import annotations

import numpy as np

from .errors import SingularityError, StrokeLimitError, TrajectoryError
from .kinematics import inverse_kinematics
from .model import Model
from .native import core
from .status import GIMBAL, NONFINITE, STROKE

PARTS = ("platform", "lower_legs", "upper_legs", "drives", "gravity", "friction")


def leg_state(model: Model, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lengths, rates, omega) of one pose and its rates (C core), for per-step outputs."""
    lengths, rates, omega, _ = core.leg_state(model.native, np.ascontiguousarray(q, float),
                                              np.ascontiguousarray(qd, float))
    return lengths, rates, omega


def inverse_dynamics(model: Model, q, qd, qdd) -> np.ndarray:
    """Actuator (rack) forces sigma (Eq. 12) for poses and their derivatives, (N, 6) or (6,)."""
    done = _single(core.inverse_dynamics, model, q, qd, qdd)
    if done is not None and not done[1]:
        return done[0]
    return _evaluate(model, core.inverse_dynamics, core.inverse_dynamics_batch,
                     ("q", "qd", "qdd"), q, qd, qdd)


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
    out, index, status = core.inverse_dynamics_parts_batch(model.native, q, qd, qdd)
    if index >= 0:
        _raise(model, status, index, ("q", "qd", "qdd"), (q[index], qd[index], qdd[index]))
    return {name: out[:, PARTS.index(name), :] for name in present_parts(model)}


def regressor(model: Model, q, qd, qdd) -> np.ndarray:
    """Y (N, 6, N_STANDARD) of poses and their derivatives, with inverse_dynamics = Y pi for pi
    the model's standard parameters (stewart_fmu.standard): the identification model, linear in
    the inertial and friction parameters (native/src/regressor.c)."""
    q, qd, qdd = (np.atleast_2d(_as_float(a, n)) for a, n in ((q, "q"), (qd, "qd"), (qdd, "qdd")))
    _check_shapes(("q", "qd", "qdd"), (q, qd, qdd))
    out, index, status = core.regressor_batch(model.native, q, qd, qdd)
    if index >= 0:
        _raise(model, status, index, ("q", "qd", "qdd"), (q[index], qd[index], qdd[index]))
    return out


def forward_dynamics(model: Model, q, qd, sigma) -> np.ndarray:
    """Pose accelerations qdd from rack forces sigma (the inverse of inverse_dynamics)."""
    done = _single(core.forward_dynamics, model, q, qd, sigma)
    if done is not None and not done[1]:
        return done[0]
    return _evaluate(model, core.forward_dynamics, core.forward_dynamics_batch,
                     ("q", "qd", "sigma"), q, qd, sigma)


_F64 = np.dtype(np.float64)


def _single(call, model: Model, a, b, c):
    """The fast path of one sample given as float64 (6,) arrays: (result, status), or None for
    anything else (lists, other shapes or dtypes, strided views: _evaluate checks those)."""
    try:
        if a.shape == b.shape == c.shape == (6,) and a.dtype is _F64 and b.dtype is _F64 \
                and c.dtype is _F64:
            return call(model.native, a, b, c)
    except (AttributeError, ValueError):   # not an array; not contiguous (cffi's from_buffer)
        pass
    return None


def _evaluate(model: Model, one, batch, names, a, b, c) -> np.ndarray:
    """Run the single-sample call on (6,) inputs, the batch call on (N, 6) ones."""
    a, b, c = _as_float(a, names[0]), _as_float(b, names[1]), _as_float(c, names[2])
    if a.ndim == 1 and a.shape == b.shape == c.shape == (6,):
        result, status = one(model.native, a, b, c)
        if status:
            _raise(model, status, 0, names, (a, b, c))
        return result
    _check_shapes(names, (a, b, c))
    out, index, status = batch(model.native, a, b, c)
    if index >= 0:
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


def raise_status(model: Model, status: int, q) -> None:
    """The typed error of a kernel's status at one pose q (nothing when it is OK)."""
    if status != core.OK:
        _raise(model, status, 0, ("q",), (np.asarray(q),))


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
