"""The base parameters of a stacked regressor W (rows: samples x legs, columns: standard
parameters): which combinations of the standard parameters the data determine.

QR with column pivoting of W with unit-norm columns (units then do not decide the order):
the first r pivots are independent, r the numerical rank; every other column is a combination
of them, W_D = W_I K_D, so that W pi = W_I beta with the base parameters
beta = pi_I + K_D pi_D. A column that is zero is not identifiable at all; a standard parameter
enters beta alone when no dependent column feeds its base parameter and it is not dependent
itself; otherwise only in combination (Gautier and Khalil's base parameters, found
numerically as in FIGAROH). The structural base of a model is that of a rich random set of
poses, rates and accelerations: what no data can separate. A run's base set smaller than the
structural one lacks excitation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from stewart_fmu.dynamics import regressor
from stewart_fmu.model import Model
from stewart_fmu.standard import NAMES, present

RANK_RTOL = 1e-7     # |R_kk| / |R_00| below this (unit-norm columns): dependent
ZERO_COLUMN = 1e-12  # a column whose norm is below this times the largest: not identifiable
_COEFF_TOL = 1e-9    # |K| below this: no contribution to a base parameter


@dataclass(frozen=True)
class BaseParameters:
    """The base parameters of the standard columns `columns` (indices into NAMES)."""

    columns: np.ndarray          # the standard columns considered (the scene's effects)
    independent: np.ndarray      # those that stand for a base parameter each (indices into NAMES)
    combination: np.ndarray      # (rank, len(NAMES)) K: beta = K pi
    alone: tuple[str, ...]       # standard parameters that are a base parameter by themselves
    combined: tuple[str, ...]    # those identifiable only in combination with others
    unidentifiable: tuple[str, ...]   # those that do not act on the data at all

    @property
    def rank(self) -> int:
        return len(self.independent)

    def names(self) -> tuple[str, ...]:
        """A readable name of each base parameter: the standard name, plus ' + k name' terms."""
        out = []
        for row, col in zip(self.combination, self.independent):
            terms = [NAMES[col]] + [f"{c:+.6g} {NAMES[j]}" for j, c in enumerate(row)
                                    if j != col and c != 0.0]
            out.append(" ".join(terms))
        return tuple(out)

    def beta(self, pi: np.ndarray) -> np.ndarray:
        """The base parameters of standard parameters pi."""
        return self.combination @ pi


def base_parameters(W: np.ndarray, columns: np.ndarray | None = None,
                    rtol: float = RANK_RTOL) -> BaseParameters:
    """The base parameters of the stacked regressor W (M, len(NAMES)), over `columns` (default
    all)."""
    cols = np.arange(W.shape[1]) if columns is None else np.asarray(columns)
    norms = np.linalg.norm(W[:, cols], axis=0)
    live = norms > ZERO_COLUMN * max(float(np.max(norms, initial=0.0)), np.finfo(float).tiny)
    dead = cols[~live]
    cols = cols[live]
    A = W[:, cols] / norms[live]
    _, R, piv = scipy.linalg.qr(A, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > rtol * diag[0])) if diag.size else 0
    ind, dep = piv[:rank], piv[rank:]
    # K_D in the unit-norm columns, back to the standard parameters' units
    Kd = scipy.linalg.solve_triangular(R[:rank, :rank], R[:rank, rank:]) if dep.size else \
        np.zeros((rank, 0))
    Kd = Kd * norms[live][dep][None, :] / norms[live][ind][:, None]
    Kd[np.abs(Kd) < _COEFF_TOL * np.maximum(1.0, np.abs(Kd).max(initial=0.0))] = 0.0
    K = np.zeros((rank, W.shape[1]))
    K[np.arange(rank), cols[ind]] = 1.0
    K[:, cols[dep]] = Kd
    fed = np.any(Kd != 0.0, axis=1)
    alone = tuple(NAMES[cols[i]] for k, i in enumerate(ind) if not fed[k])
    combined = tuple(NAMES[cols[i]] for k, i in enumerate(ind) if fed[k]) + tuple(
        NAMES[cols[j]] for j in dep if np.any(Kd[:, list(dep).index(j)] != 0.0))
    lost = tuple(NAMES[c] for c in dead) + tuple(
        NAMES[cols[j]] for j in dep if not np.any(Kd[:, list(dep).index(j)] != 0.0))
    order = lambda names: tuple(sorted(names, key=NAMES.index))  # noqa: E731
    return BaseParameters(np.asarray(columns if columns is not None else np.arange(W.shape[1])),
                          cols[ind], K, order(alone), order(combined), order(lost))


def scaled_condition(Wb: np.ndarray) -> float:
    """cond of W_b with unit-norm columns (Belsley's scaled condition number: the units of the
    parameters do not enter it); inf when a column is zero."""
    norms = np.linalg.norm(Wb, axis=0)
    if np.any(norms == 0.0):
        return float("inf")
    s = np.linalg.svd(Wb / norms, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def stacked(Y: np.ndarray) -> np.ndarray:
    """Y (N, 6, P) as the rows of W (6 N, P): sample-major, leg-minor."""
    return Y.reshape(-1, Y.shape[-1])


def structural_base(model: Model, n: int = 400, seed: int = 0) -> BaseParameters:
    """The base parameters no data can go beyond: those of random poses near home (a tenth of
    the stroke), rates and accelerations, over the columns of the scene's effects."""
    rng = np.random.default_rng(seed)
    q, qd, qdd = random_motion(model, n, rng)
    return base_parameters(stacked(regressor(model, q, qd, qdd)), np.flatnonzero(present(model)))


def random_motion(model: Model, n: int, rng: np.random.Generator):
    """n poses inside the stroke near home, with random rates and accelerations (both signs of
    every leg rate)."""
    c = model.characteristic_length
    span = 0.02 * c
    if model.leg_min is not None and model.leg_max is not None:
        span = min(span, 0.05 * (model.leg_max - model.leg_min))
    scale = np.array([span] * 3 + [0.03] * 3)
    q = np.asarray(model.home) + rng.uniform(-1.0, 1.0, (n, 6)) * scale
    qd = rng.normal(0.0, 1.0, (n, 6)) * scale * 20.0
    qdd = rng.normal(0.0, 1.0, (n, 6)) * scale * 400.0
    return q, qd, qdd
