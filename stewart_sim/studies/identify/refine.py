"""Output-error refinement (`identify --refine`): from the least-squares estimate, fit the
forward model's simulated leg lengths to the measured ones, with the measured forces as input,
optionally with a delay of the force signal and a bias of each leg's force sensor (the signal
modifiers of MuJoCo's sysid).

A force-driven platform is a free body: a rollout over a whole run drifts with any error.
The runs are therefore cut into short segments (multiple shooting), each started from the
filtered measured state (pose and rates) and simulated with stewart_sim.open_loop.forward.simulate
(the plant's own integrator; the force held over a sample interval is the measured signal at the
interval's middle, interpolated, so that a sampled continuous force is no delay).

The unknowns are the base parameters that the scene can hold (those acting on a standard
parameter other than the platform's first moment and products of inertia, which the scene's
model holds at zero), plus the delay d (the force measured at t is the force applied at t - d)
and the biases b_j (measured = applied + b_j). The base parameters move along the right
singular vectors of the stacked regressor over those standard parameters (in their scale,
_directions): coordinates that the data define, whichever columns the pivoted QR picked to
name the base parameters (among columns of equal norm, rounding picks). The fit starts from
the standard parameters with the estimate's base parameters that lie INSIDE the consistency
constraints (_inside): the dynamics depend on the base parameters only, and a start on a
constraint (the least-squares estimate often is) bends the residual at once. Every step's
standard parameters are projected onto the constraints (estimate.project), so the residual
has no cliff where a scene would be invalid. scipy's least_squares (trust region reflective)
minimises the length residuals; the result's standard parameters are then those with its base
parameters nearest the estimate's. The confidence intervals are those of the Jacobian at the
solution, s^2 (J^T J)^-1 with s^2 the residual variance.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.optimize

from stewart_fmu.errors import StewartError
from stewart_fmu.scene import load_scene
from stewart_fmu.standard import N_STANDARD, span
from stewart_sim.open_loop.forward import simulate

from .base import RANK_RTOL
from .estimate import consistent_point, project
from .runs import Run, pose_of
from .scene_out import scene_values
from .signal import choose_filter, derivatives
from .study import Identification

SEGMENT = 0.1          # s: length of one shooting segment
EVERY = 1.0            # s: one segment starts every EVERY seconds of each run
MAX_EVALUATIONS = 400  # residual evaluations of least_squares at most
FTOL = 1e-6            # least_squares stops when a step lowers the cost by less than this part
GTOL = 1e-8            # ... or when the gradient is this small (the cost at the start is 1)
BETA_RANGE = 0.5       # pi moves along a direction by this of its part there at most
MAX_DELAY = 0.05       # s: the largest force delay considered
BIAS_RANGE = 0.2       # the largest force bias, as a fraction of the force peak
INSIDE = 1e-2          # refine's start this far inside the consistency constraints (_inside)
_OUTSIDE = 1.0         # m: the residual of a step whose parameters make no valid scene
_UNHELD = np.zeros(N_STANDARD, dtype=bool)
_UNHELD[span("PLATFORM_MOMENT")] = True
_UNHELD[span("PLATFORM_INERTIA")] = [False, True, True, False, True, False]


@dataclass(frozen=True)
class Refinement:
    """The refined base parameters (a subset, `refined`), delay and biases, with 1-sigma."""

    refined: np.ndarray          # indices of the base parameters refined
    beta: np.ndarray             # (rank,) all base parameters after refinement
    std: np.ndarray              # (len(refined),) their standard deviations
    delay: float                 # s
    delay_std: float
    bias: np.ndarray             # (6,) N
    bias_std: np.ndarray
    pi: np.ndarray               # the standard parameters after refinement
    rms_before: float            # RMS length residual at the least-squares estimate (m)
    rms_after: float
    evaluations: int
    segments: int


@dataclass(frozen=True)
class _Segment:
    t: np.ndarray
    sigma: np.ndarray            # measured forces over the segment, one more sample at the end
    t_sigma: np.ndarray
    run_t: np.ndarray            # the whole run's times and forces (delay interpolation)
    run_sigma: np.ndarray
    q0: np.ndarray
    qd0: np.ndarray
    lengths: np.ndarray          # measured


def segments(ident: Identification, runs: list[Run], length: float = SEGMENT,
             every: float = EVERY) -> list[_Segment]:
    """The shooting segments of the runs (module docstring)."""
    out = []
    for run in runs:
        q = pose_of(ident.model, run)
        filt = choose_filter(run.t, q, ident.prepared[0].filter.cutoff, 1)
        qf, qd, _ = derivatives(q, filt)
        n = max(int(round(length * filt.rate)), 2)
        step = max(int(round(every * filt.rate)), n)
        margin = max(int(round(filt.rate / filt.cutoff)), 1) * 4   # clear of filter edges
        for k in range(margin, len(run.t) - n - margin, step):
            sl = slice(k, k + n)
            out.append(_Segment(run.t[sl], run.sigma[sl], run.t[sl], run.t, run.sigma,
                                qf[k], qd[k], run.lengths[sl]))
    if not out:
        raise StewartError(f"--refine: the runs are too short for one segment of {length} s")
    return out


def refine(ident: Identification, runs: list[Run], *,
           delay: bool = True, bias: bool = True, length: float = SEGMENT,
           every: float = EVERY, progress: Callable[[int, int], None] | None = None
           ) -> Refinement:
    """Refine the estimate of `ident` on `runs` (module docstring); `progress(k, total)` after
    each residual evaluation (total: MAX_EVALUATIONS, the most there can be)."""
    segs = segments(ident, runs, length, every)
    base = ident.base
    held = ~_UNHELD
    refined = np.flatnonzero(np.any((base.combination[:, held] != 0.0), axis=1))
    free = np.zeros(N_STANDARD, dtype=bool)
    free[base.columns] = True
    free &= held
    P = _directions(ident, free, len(refined))
    n_th = P.shape[1]
    start = ident.pi.copy()
    start[_UNHELD] = 0.0
    base_pi = _inside(ident, start, free)
    along = (P[free].T / ident.scale[free] ** 2) @ base_pi[free]   # pi's part along each
    reach = BETA_RANGE * np.maximum(np.abs(along), 1.0)

    length_c = ident.model.characteristic_length

    def unpack(x):
        # projected onto the consistency constraints: a step that would leave them gives the
        # nearest consistent body, so the residual stays continuous (no cliff of _OUTSIDE for
        # the trust region and the finite differences to fall off on the side rounding decides)
        pi = project(base_pi + P @ x[:n_th], free, length_c, ident.scale)
        d = x[n_th] * 1e-3 if delay else 0.0
        b = x[n_th + int(delay):] if bias else np.zeros(6)
        return pi, d, b

    count = [0]

    def residuals(x):
        count[0] += 1
        if progress is not None:
            progress(count[0], MAX_EVALUATIONS)
        pi, d, b = unpack(x)
        try:
            values, _ = scene_values(ident.model, pi, ident.written())
            model = load_scene(ident.model.source, overrides=values)
        except StewartError:         # a step outside what a scene may hold: a large residual
            return np.full(n_res, _OUTSIDE)
        res = []
        for s in segs:
            # held over [t_k, t_k+1): the measured signal at the interval's middle, d later
            mid = s.t + 0.5 * (s.run_t[1] - s.run_t[0]) + d
            applied = np.column_stack([np.interp(mid, s.run_t, s.run_sigma[:, j])
                                       for j in range(6)]) - b
            try:
                table = simulate(model, s.t, applied, q0=s.q0, qd0=s.qd0)
                sim = np.column_stack([table[f"l{i}"] for i in range(1, 7)])
            except StewartError:
                sim = np.full_like(s.lengths, np.nan)
            res.append(np.nan_to_num(sim - s.lengths, nan=1.0).ravel())
        return np.concatenate(res)

    n_res = sum(s.lengths.size for s in segs)
    x0 = np.zeros(n_th + int(delay) + (6 if bias else 0))
    r0 = residuals(x0)
    # bounds: pi along each direction within BETA_RANGE of its part there (in scale; at least
    # of the scale), the delay within MAX_DELAY, the biases within BIAS_RANGE of the force peak
    peak = max(float(np.max(np.abs(r.sigma))) for r in runs)
    hi = np.concatenate([reach, [MAX_DELAY * 1e3] if delay else [],
                         [BIAS_RANGE * peak] * (6 if bias else 0)])
    # in units of the start's RMS residual: gtol (on the gradient) is then relative to the cost
    unit = max(float(np.sqrt(np.mean(r0**2))), np.finfo(float).tiny)
    sol = scipy.optimize.least_squares(lambda x: residuals(x) / unit, x0, bounds=(-hi, hi),
                                       x_scale="jac", max_nfev=MAX_EVALUATIONS, method="trf",
                                       ftol=FTOL, xtol=1e-12, gtol=GTOL)
    fun, jac = sol.fun * unit, sol.jac * unit
    m, p = fun.size, sol.x.size
    s2 = float(fun @ fun) / max(m - p, 1)
    # s^2 (J^T J)^-1 by the SVD, no direction truncated: a poorly determined one gets its
    # large variance (inf for one the data do not touch at all), never a cut-off zero
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    with np.errstate(divide="ignore"):
        sd = np.sqrt(s2 * np.sum((vt / sv[:, None]) ** 2, axis=0))
    pi, d, b = unpack(sol.x)
    beta = base.beta(pi)
    nearest = consistent_point(base, beta, start, ident.scale, length_c, free)
    pi = pi if nearest is None else nearest
    # the refined base parameters' deviations: theirs is the linear image of theta's
    A = base.combination[refined] @ P
    with np.errstate(divide="ignore", invalid="ignore"):
        cov = (vt[:, :n_th] / sv[:, None]).T @ (vt[:, :n_th] / sv[:, None]) * s2
    std = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", A, cov, A), 0.0))
    return Refinement(refined, beta, std, d,
                      float(sd[n_th] * 1e-3) if delay else 0.0, b,
                      sd[n_th + int(delay):] if bias else np.zeros(6), pi,
                      float(np.sqrt(np.mean(r0**2))), float(np.sqrt(np.mean(fun**2))),
                      int(sol.nfev), len(segs))


def _directions(ident: Identification, free: np.ndarray, rank: int) -> np.ndarray:
    """P: the refinement's coordinates theta, pi = pi_start + P theta. P's columns are the
    right singular vectors of the stacked regressor over the free standard parameters (in
    their scale), the `rank` largest (those of the refined base parameters), each signed so
    that its largest part is positive: theta_k moves pi by a unit of scale along the k-th.
    They depend on the data only, not on which columns the pivoted QR of base_parameters chose
    to stand for the base parameters (a choice that rounding decides among columns of equal
    norm: the trust region's path, and where it stopped, followed that choice)."""
    W = np.vstack([p.W for p in ident.prepared])
    scale = ident.scale[free]
    _, sv, vt = np.linalg.svd(W[:, free] * scale, full_matrices=False)
    rank = min(rank, int(np.count_nonzero(sv > RANK_RTOL * sv[0])))
    vt = vt[:rank]
    lead = np.argmax(np.abs(vt), axis=1)
    vt = vt * np.sign(vt[np.arange(rank), lead])[:, None]
    P = np.zeros((N_STANDARD, rank))
    P[free] = scale[:, None] * vt.T
    return P


def _inside(ident: Identification, pi: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The standard parameters with the base parameters of pi nearest pi (in scale) that lie
    INSIDE (or, failing that, a tenth, a hundredth of it) times their mass scale inside the
    consistency constraints; pi when none does. The least-squares estimate often lies on a
    constraint (a leg part's pseudo-inertia at its margin): from there a step projected
    onto the constraints (project) bends the residual, and the trust region stalls at the
    kink, on the side that the rounding of its steps picks. The dynamics depend on the base
    parameters only, so the deeper point starts the fit at the same residual."""
    base, length = ident.base, ident.model.characteristic_length
    for inside in (INSIDE, 0.1 * INSIDE, 0.01 * INSIDE):
        out = consistent_point(base, base.beta(pi), pi, ident.scale, length, free, inside)
        if out is not None:
            return out
    return pi
