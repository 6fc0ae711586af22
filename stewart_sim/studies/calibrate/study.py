"""Kinematic calibration of a Stewart platform from measured poses and encoder leg lengths (data,
no files: stewart_sim/studies/calibrate/report.py writes them).

Measurement model, leg i (i = 1..6), pose k (docs/conventions.md: R = Rz Ry Rx, a point p fixed
in C is at x + R p in N):

    l_ik = |x_k + R_k p_i - a_i| + delta_i

l_ik the length the encoder reports, a_i the base joint (N), p_i the platform joint (C), delta_i
the leg-length offset: what the encoder reads beyond the joint-to-joint distance (an encoder
zeroed 0.3 mm short reads 0.3 mm less: delta_i = -0.3 mm). 42 parameters, 7 per leg; given the
poses the legs decouple, so each leg is its own 7-parameter least-squares problem (block-diagonal
identification Jacobian: its singular values are the union of the legs').

Estimation: Levenberg-Marquardt (scipy.optimize.least_squares, method "lm") per leg from the
scene's joints and zero offsets, with the analytic Jacobian dl/da = -u, dl/dp = R^T u,
dl/ddelta = 1 (u the leg's unit vector in N). Observability: singular values of each leg's
Jacobian with its columns scaled to unit norm (so metres and the offset's ones compare); a
direction whose scaled singular value is below OBSERVABLE_RTOL times the largest is not
observable from the poses given. Standard deviations: s_i^2 (J_i^T J_i)^-1, s_i^2 = the leg's
residual sum of squares / (N - 7); pose noise reaches the leg lengths linearly, so it counts in
s_i like encoder noise.

Pose selection (--select N): greedy D-optimal. Each step adds the candidate pose that raises
log det of the scaled information matrix sum_i J_i^T J_i most (matrix determinant lemma, the
six legs' gains summed), from a small ridge so that the first steps are defined; the Jacobian is
that of the nominal scene (the estimate is not known before).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from stewart_fmu.budget import CSV_BYTES, InputFileError, check_count, open_input
from stewart_fmu.errors import StewartError
from stewart_fmu.io import POSE
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.rotations import euler_motion

LENGTHS = tuple(f"l{i}" for i in range(1, 7))
POSE_COLUMNS = (*POSE, *LENGTHS)     # the columns of a poses file (any order, more allowed)
PER_LEG = 7                          # a_i (3), p_i (3), delta_i
MIN_POSES = PER_LEG + 1              # 7 parameters per leg and one degree of freedom for s_i
OBSERVABLE_RTOL = 1e-8               # scaled singular value / largest below this: not observable
RIDGE = 1e-6                         # start of the greedy selection: RIDGE * I (scaled units)
AXES = ("x", "y", "z")
ANGLE_BOUND = 2 * math.pi            # rad: a tracker's Euler angle, in either wrap convention
# bytes a candidate pose costs while calibrating and selecting (its rotation, six legs' vectors
# and Jacobians, the scaled copy of select_poses, the residuals; a few copies each)
POSE_BYTES = 4096


class CalibrationError(StewartError, ValueError):
    """A poses file or a calibration request is at fault (the message names it and why)."""


def parameter_names() -> tuple[str, ...]:
    """The 42 parameters, leg by leg: a1.x a1.y a1.z p1.x p1.y p1.z delta1, a2.x ..."""
    return tuple(n for i in range(1, 7)
                 for n in (*(f"a{i}.{c}" for c in AXES), *(f"p{i}.{c}" for c in AXES),
                           f"delta{i}"))


@dataclass(frozen=True)
class PoseSet:
    """Measured poses (N, 6: x, y, z, thx, thy, thz) and the leg lengths reported (N, 6)."""

    poses: np.ndarray
    lengths: np.ndarray


@dataclass(frozen=True)
class Calibration:
    """The outcome of calibrate: every array over the 42 parameters is in parameter_names()
    order."""

    names: tuple[str, ...]
    nominal: np.ndarray          # (42,) the scene's joints, zero offsets
    estimate: np.ndarray         # (42,)
    std: np.ndarray              # (42,) m; inf where not observable
    observable: np.ndarray       # (42,) bool: the parameter takes part in no unobservable direction
    singular_values: np.ndarray  # (6, 7) per leg, scaled columns, descending
    weakest: tuple[str, ...]     # per leg: the direction of its smallest singular value
    unobservable: tuple[str, ...]  # the directions below OBSERVABLE_RTOL (empty: all observable)
    used: np.ndarray             # indices of the poses calibrated on (rows of the file, from 0)
    selected: bool               # used came from select_poses
    residuals: np.ndarray        # (len(used), 6) m, measured - model at the estimate
    rms: np.ndarray              # (6,) m per leg
    held_out_rms: np.ndarray | None  # (6,) m on the poses not used (None: all used)
    cond: float                  # scaled condition number of the identification Jacobian
    nominal_rms: np.ndarray      # (6,) m per leg at the nominal parameters

    @property
    def base_joints(self) -> np.ndarray:
        return self.estimate.reshape(6, PER_LEG)[:, 0:3]

    @property
    def platform_joints(self) -> np.ndarray:
        return self.estimate.reshape(6, PER_LEG)[:, 3:6]

    @property
    def offsets(self) -> np.ndarray:
        return self.estimate.reshape(6, PER_LEG)[:, 6]

    @property
    def offsets_std(self) -> np.ndarray:
        return self.std.reshape(6, PER_LEG)[:, 6]


def read_poses(path: str | Path) -> PoseSet:
    """Read a poses CSV (POSE_COLUMNS in any order; further columns ignored). Errors
    (CalibrationError) name the file, the line and the column."""
    path = Path(path)
    try:
        with open_input(path, CSV_BYTES) as raw, \
                io.TextIOWrapper(raw, newline="", encoding="utf-8") as fh:
            rows = []
            for row in csv.reader(fh):   # as Python strings: each cell costs ~60 bytes
                rows.append(row)
                check_count(f"{path}: poses", len(rows), 60 * max(len(row), 1) + 100)
    except InputFileError as exc:
        raise CalibrationError(f"{path}: cannot read poses: {exc.reason}") from None
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read poses: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise CalibrationError(f"{path}: not a CSV text file: {exc}") from None
    if not rows:
        raise CalibrationError(f"{path}: empty file, expected header {','.join(POSE_COLUMNS)}")
    header = [c.strip() for c in rows[0]]
    missing = [c for c in POSE_COLUMNS if c not in header]
    twice = [c for c in POSE_COLUMNS if header.count(c) > 1]
    if missing or twice:
        raise CalibrationError(f"{path}: header must hold {','.join(POSE_COLUMNS)} (any order); "
                               f"missing {missing or 'none'}, more than once {twice or 'none'}")
    picks = [header.index(c) for c in POSE_COLUMNS]
    data = np.empty((len(rows) - 1, len(POSE_COLUMNS)))
    for r, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise CalibrationError(f"{path}: line {r + 2} has {len(row)} fields, expected "
                                   f"{len(header)}")
        for c, k in enumerate(picks):
            try:
                data[r, c] = float(row[k])
            except ValueError:
                raise CalibrationError(f"{path}: line {r + 2}, column '{POSE_COLUMNS[c]}': "
                                       f"not a number: {row[k]!r}") from None
            if not math.isfinite(data[r, c]):
                raise CalibrationError(f"{path}: line {r + 2}, column '{POSE_COLUMNS[c]}': "
                                       f"non-finite value {row[k].strip()}")
    bad = np.argwhere(data[:, 6:] <= 0)
    if bad.size:
        r, c = bad[0]
        raise CalibrationError(f"{path}: line {r + 2}, column '{LENGTHS[c]}': leg length must "
                               f"be > 0, got {data[r, 6 + c]!r}")
    enough(len(data), str(path))
    return PoseSet(data[:, :6], data[:, 6:])


def enough(n: int, where: str) -> None:
    """Refuse fewer than MIN_POSES poses, saying how many are needed."""
    if n < MIN_POSES:
        raise CalibrationError(
            f"{where}: {n} pose(s), need at least {MIN_POSES} (7 parameters per leg: a_i, p_i, "
            "delta_i, and one more for the noise level)")


def machine_size(model: Model) -> float:
    """max |a_i| + max |p_i| + |home position| (m): no leg of the scene is longer at home
    (triangle inequality), the scale of the physical bounds of check_bounds."""
    return float(np.linalg.norm(model.base_joints, axis=1).max()
                 + np.linalg.norm(model.platform_joints, axis=1).max()
                 + np.linalg.norm(np.asarray(model.home, dtype=float)[:3]))


def check_bounds(model: Model, data: PoseSet, where: str) -> None:
    """Refuse (CalibrationError naming the line and column of `where`) a measurement no pose
    of this machine can give: a coordinate farther than machine_size from home's, an angle
    beyond ANGLE_BOUND, a leg length not above 0 or above 3 machine_size (the longest a pose within those
    bounds has: |x + R p - a| <= |x| + |p| + |a| <= (1 + sqrt 3) machine_size)."""
    size = machine_size(model)
    home = np.asarray(model.home, dtype=float)[:3]
    values = np.column_stack([data.poses, data.lengths])
    bad = np.column_stack([np.abs(data.poses[:, :3] - home) > size,
                           np.abs(data.poses[:, 3:]) > ANGLE_BOUND,
                           (data.lengths <= 0) | (data.lengths > 3 * size)])
    if not bad.any():
        return
    r, c = (int(k) for k in np.argwhere(bad)[0])
    why = (f"is more than the machine's size {size:.4g} m from home's {home[c]:g} m" if c < 3
           else "is beyond +-2 pi rad" if c < 6
           else "is not a leg length: must be > 0" if values[r, c] <= 0
           else f"is above {3 * size:.4g} m (3 times the machine's size: no pose within reach "
                "has a longer leg)")
    raise CalibrationError(f"{where}: line {r + 2}, column '{POSE_COLUMNS[c]}': "
                           f"{float(values[r, c])!r} {why}")


def check_finite(cal: "Calibration", where: str) -> None:
    """Refuse (CalibrationError naming `where`) a calibration whose numbers are not all finite
    (a standard deviation is inf only where its parameter is not observable, as documented):
    numerical trouble is reported, never written."""
    numbers = {"estimate": cal.estimate, "standard deviation": cal.std[cal.observable],
               "residual": cal.residuals, "nominal residual": cal.nominal_rms,
               "singular value": cal.singular_values,
               "held-out residual": cal.held_out_rms if cal.held_out_rms is not None else ()}
    for what, values in numbers.items():
        values = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(values)):
            raise CalibrationError(f"{where}: the calibration's {what}s are not finite "
                                   "(numerical trouble: check the poses' units and the scene)")


def rotations(poses: np.ndarray) -> np.ndarray:
    """R (N, 3, 3) of pose rows (N, 6)."""
    q = np.atleast_2d(np.asarray(poses, dtype=float))
    R, om, al = np.empty((len(q), 3, 3)), np.empty((len(q), 3)), np.empty((len(q), 3))
    zero = np.zeros_like(q)
    euler_motion(q, zero, zero, R, om, al)
    return R


def nominal_parameters(model: Model) -> np.ndarray:
    """The scene's joints and zero offsets, in parameter_names() order."""
    return np.column_stack([model.base_joints, model.platform_joints,
                            np.zeros(6)]).reshape(-1)


def predicted_lengths(poses: np.ndarray, params: np.ndarray) -> np.ndarray:
    """l_ik = |x_k + R_k p_i - a_i| + delta_i (N, 6) for the 42 parameters."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    R = rotations(poses)
    P = np.asarray(params, dtype=float).reshape(6, PER_LEG)
    return np.column_stack([_leg(poses, R, P[i])[0] for i in range(6)])


def leg_jacobians(poses: np.ndarray, params: np.ndarray) -> np.ndarray:
    """d l_ik / d(a_i, p_i, delta_i): (6, N, 7), leg by leg."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    R = rotations(poses)
    P = np.asarray(params, dtype=float).reshape(6, PER_LEG)
    return np.stack([_leg(poses, R, P[i])[1] for i in range(6)])


def _leg(poses: np.ndarray, R: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One leg's model lengths (N,) and Jacobian (N, 7) for its parameters x = (a, p, delta):
    dl/da = -u, dl/dp = R^T u, dl/ddelta = 1."""
    L = poses[:, :3] + R @ x[3:6] - x[0:3]
    length = np.linalg.norm(L, axis=1)
    u = L / length[:, None]
    J = np.empty((len(poses), PER_LEG))
    J[:, 0:3] = -u
    J[:, 3:6] = np.einsum("nji,nj->ni", R, u)
    J[:, 6] = 1.0
    return length + x[6], J


def scaled_condition(poses: np.ndarray, params: np.ndarray) -> float:
    """Condition number of the 42-column identification Jacobian, columns scaled to unit norm
    (block-diagonal: the largest scaled singular value over the smallest, over all legs)."""
    sv = np.concatenate([_scaled_svd(J)[1] for J in leg_jacobians(poses, params)])
    return float(sv.max() / sv.min()) if sv.min() > 0 else math.inf


def select_poses(poses: np.ndarray, params: np.ndarray, n: int) -> np.ndarray:
    """Greedy D-optimal choice of n of the candidate poses (module doc); sorted indices."""
    count = len(poses)
    if not MIN_POSES <= n <= count:
        raise CalibrationError(f"--select {n}: must be between {MIN_POSES} and the {count} "
                               "candidate poses")
    J = leg_jacobians(poses, params)
    J = J / np.linalg.norm(J, axis=1, keepdims=True)           # column scaling of the candidates
    inverse = np.repeat(np.eye(PER_LEG)[None] / RIDGE, 6, axis=0)   # M_i^-1, M_i = RIDGE I
    chosen: list[int] = []
    free = np.ones(count, dtype=bool)
    for _ in range(n):
        # gain of pose k: sum_i log(1 + j_ik^T M_i^-1 j_ik)
        quad = np.einsum("ikp,ipq,ikq->ik", J, inverse, J)
        gain = np.where(free, np.log1p(quad).sum(axis=0), -np.inf)
        k = int(np.argmax(gain))
        chosen.append(k)
        free[k] = False
        for i in range(6):                                     # Sherman-Morrison update
            v = inverse[i] @ J[i, k]
            inverse[i] -= np.outer(v, v) / (1.0 + J[i, k] @ v)
    return np.sort(np.array(chosen))


def calibrate(model: Model, data: PoseSet, select: int | None = None) -> Calibration:
    """Estimate the 42 parameters from the poses (all, or the `select` most informative)."""
    enough(len(data.poses), "poses")
    nominal = nominal_parameters(model)
    count = check_count("poses", len(data.poses), POSE_BYTES, "calibrate on fewer poses")
    used = (select_poses(data.poses, nominal, select) if select is not None
            else np.arange(count))
    poses, lengths = data.poses[used], data.lengths[used]
    R = rotations(poses)
    n = len(used)
    estimate = nominal.copy()
    std = np.empty(42)
    observable = np.ones(42, dtype=bool)
    singular = np.empty((6, PER_LEG))
    weakest, unobservable = [], []
    names = parameter_names()
    for i in range(6):
        leg = slice(PER_LEG * i, PER_LEG * (i + 1))

        def residual(x: np.ndarray, i: int = i) -> np.ndarray:
            return _leg(poses, R, x)[0] - lengths[:, i]

        def jacobian(x: np.ndarray) -> np.ndarray:
            return _leg(poses, R, x)[1]

        fit = least_squares(residual, nominal[leg], jac=jacobian, method="lm",
                            x_scale="jac", ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=500)
        estimate[leg] = fit.x
        J = _leg(poses, R, fit.x)[1]
        scale, sv, Vt = _scaled_svd(J)
        singular[i] = sv
        small = sv < OBSERVABLE_RTOL * sv[0]
        weakest.append(_direction(Vt[-1], names[leg]))
        for v in Vt[small]:
            unobservable.append(_direction(v, names[leg]))
            observable[leg] &= np.abs(v) < 1e-3
        s2 = float(fit.fun @ fit.fun) / (n - PER_LEG)
        # cov = s^2 (J^T J)^-1 through the scaled SVD: J = U S Vt D^-1 -> (J^T J)^-1 = D V S^-2 Vt D
        inv = np.zeros_like(sv)     # unobservable directions out; the rest >= 1e-8 (sv[0] >= 1)
        inv[~small] = 1.0 / sv[~small] ** 2
        cov = (Vt.T * inv) @ Vt / np.outer(scale, scale) * s2
        std[leg] = np.where(observable[leg], np.sqrt(np.diag(cov)), math.inf)
    residuals = lengths - predicted_lengths(poses, estimate)
    rest = np.setdiff1d(np.arange(count), used)
    held_out = None
    if rest.size:
        held_out = _rms(data.lengths[rest] - predicted_lengths(data.poses[rest], estimate))
    return Calibration(
        names, nominal, estimate, std, observable, singular, tuple(weakest),
        tuple(unobservable), used, select is not None, residuals, _rms(residuals), held_out,
        scaled_condition(poses, estimate),
        _rms(lengths - predicted_lengths(poses, nominal)))


def _scaled_svd(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column norms D, and the singular values and right vectors of J D^-1."""
    scale = np.linalg.norm(J, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    _, sv, Vt = np.linalg.svd(J / scale, full_matrices=False)
    return scale, sv, Vt


def _direction(v: np.ndarray, names: tuple[str, ...]) -> str:
    """A scaled singular direction as text: its components above 0.1, largest first."""
    order = np.argsort(-np.abs(v))
    sign = 1.0 if v[order[0]] > 0 else -1.0
    terms = [f"{sign * v[k]:+.2f} {names[k]}" for k in order if abs(v[k]) > 0.1]
    return " ".join(terms)


def _rms(r: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(np.asarray(r) ** 2, axis=0))


def random_poses(model: Model, n: int, rng: np.random.Generator, reach: float = 0.015,
                 tilt: float = 0.12, margin: float = 2e-3) -> np.ndarray:
    """n poses drawn uniformly around home (+-reach m in x, y, z, +-tilt rad about each axis)
    with every leg at least `margin` m inside the scene's stroke (so that a machine whose
    joints are off by a millimetre stays inside too) and cond(J) below 100
    (stewart_fmu.kinematics): synthetic candidates for tests and the shipped example."""
    home = np.asarray(model.home, dtype=float)
    lo = (model.leg_min if model.leg_min is not None else 0.0) + margin
    hi = (model.leg_max if model.leg_max is not None else math.inf) - margin
    out: list[np.ndarray] = []
    span = np.r_[np.full(3, reach), np.full(3, tilt)]
    while len(out) < n:
        q = home + rng.uniform(-1.0, 1.0, (4 * n, 6)) * span
        kin = inverse_kinematics(model, q)
        ok = np.all((kin.lengths > lo) & (kin.lengths < hi), axis=1) & (kin.cond < 100.0)
        out.extend(q[ok])
    return np.array(out[:n])


def measure(poses: np.ndarray, truth: np.ndarray, rng: np.random.Generator,
            position_noise: float = 0.0, angle_noise: float = 0.0,
            length_noise: float = 0.0) -> PoseSet:
    """What a tracker and the encoders report for `poses` on a machine with parameters `truth`:
    the leg lengths of the true poses (plus length_noise m), and the poses with position_noise m
    and angle_noise rad of Gaussian noise (standard deviations)."""
    lengths = predicted_lengths(poses, truth)
    lengths = lengths + rng.normal(0.0, length_noise, lengths.shape)
    noise = np.column_stack([rng.normal(0.0, position_noise, (len(poses), 3)),
                             rng.normal(0.0, angle_noise, (len(poses), 3))])
    return PoseSet(poses + noise, lengths)


def perturbed_truth(model: Model, rng: np.random.Generator, joints: float = 1e-3,
                    offsets: float = 5e-4) -> np.ndarray:
    """A synthetic machine: the scene's joints each moved by up to +-joints m per axis, offsets
    up to +-offsets m (uniform), in parameter_names() order."""
    truth = nominal_parameters(model).reshape(6, PER_LEG)
    truth[:, :6] += rng.uniform(-joints, joints, (6, 6))
    truth[:, 6] = rng.uniform(-offsets, offsets, 6)
    return truth.reshape(-1)


def pose_table(data: PoseSet) -> dict[str, np.ndarray]:
    """The columns of a poses file (POSE_COLUMNS) of a PoseSet."""
    cols = np.column_stack([data.poses, data.lengths])
    return {name: cols[:, k] for k, name in enumerate(POSE_COLUMNS)}
