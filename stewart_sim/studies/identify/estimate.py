"""The estimate of the base parameters from a stacked regressor and forces, and a physically
consistent set of standard parameters behind it.

1. Weighted least squares (IDIM-WLS, Gautier): ordinary least squares first; the noise level of
   each leg from its residuals (sigma_j^2 = |r_j|^2 / (n_j - rank / 6)); then least squares
   with rows weighted 1 / sigma_j. The covariance of beta is s^2 (W_b^T D^2 W_b)^-1 with s^2 the
   weighted residual variance (about 1 when the noise model holds); the standard deviations are
   its diagonal's square roots.
2. Physical consistency (Wensing, Kim and Slotine): the standard parameters pi behind beta must
   be those of real bodies: the platform's 4 x 4 pseudo-inertia [[tr(I)/2 1 - I, h], [h^T, m]]
   and each leg part's (axisymmetric about its joint: [[J_t - J_a / 2, m c], [m c, m]] and
   J_a >= 0) positive semidefinite, the drives' masses and the frictions >= 0. First the
   standard point closest to the prior (in the prior's scale) with K pi = beta exactly: a
   semidefinite feasibility problem. If none exists, the WLS estimate is not physical and the
   estimate becomes the constrained least squares fit (the same objective with the constraints;
   beta then differs from WLS and the report says so). Either is a semidefinite program, solved
   by cvxpy with Clarabel (an interior-point conic solver with semidefinite cones, open source,
   maintained, shipped as a wheel; SCS, the alternative, is first-order and less accurate).
   The nearest point is sought first with what the data do not determine held at the prior
   (estimate), in closed form when that point meets the constraints; the solver's result is
   projected onto the constraints (project), which it meets to its tolerance only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model
from stewart_fmu.standard import N_STANDARD, NAMES, span

from .base import BaseParameters

_NOISE_FLOOR = 1e-13   # relative to the RMS force: a noise estimate below it is numerical zero
MARGIN = 1e-6          # pseudo-inertias kept this much (times their mass scale) inside the cone


class IdentificationError(StewartError):
    """The data cannot give the estimate (rank, solver)."""


@dataclass(frozen=True)
class Estimate:
    """Base parameters beta (with standard deviations), the standard parameters behind them."""

    beta: np.ndarray          # (rank,) the estimate (the WLS one unless `constrained`)
    std: np.ndarray           # (rank,) standard deviations of beta (WLS covariance)
    beta_wls: np.ndarray      # (rank,) the unconstrained WLS estimate
    pi: np.ndarray            # (N_STANDARD,) physically consistent standard parameters, K pi = beta
    noise: np.ndarray         # (6,) noise level of each leg's force in the data used (N)
    residual_rms: np.ndarray  # (6,) RMS residual of each leg (N)
    constrained: bool         # True when the consistency constraints changed beta
    samples: int              # rows used (samples x legs)
    moved: tuple[str, ...] = ()   # standard parameters the data do not determine that the
                                  # consistency constraints moved off the prior


def wls(Wb: np.ndarray, s: np.ndarray, legs: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                     np.ndarray, np.ndarray]:
    """(beta, covariance, per-leg noise, per-leg residual RMS) by OLS then WLS over rows of leg
    index `legs` (0..5). Solved on the forces divided by their RMS (the result scaled back), so
    that no force level between the smallest and the largest float64 over- or underflows in
    the weights."""
    M, r = Wb.shape
    if M <= r:
        raise IdentificationError(f"{M} equations for {r} base parameters: record more samples")
    if not (np.all(np.isfinite(Wb)) and np.all(np.isfinite(s))):
        raise IdentificationError("the regressor or the forces hold non-finite values: check "
                                  "the runs' leg lengths, times and forces")
    unit = _rms(s)
    if not (np.isfinite(unit) and unit > 0.0):
        raise IdentificationError(f"the runs' forces have RMS {unit!r} N: nothing to identify "
                                  "(a run needs the forces that moved the platform)")
    beta, cov, noise, rms = _wls_unit(Wb, s / unit, legs)
    return beta * unit, cov * unit * unit, noise * unit, rms * unit


def _rms(x: np.ndarray) -> float:
    """The RMS of x, computed without overflow or underflow of the squares."""
    peak = float(np.max(np.abs(x), initial=0.0))
    return peak * float(np.sqrt(np.mean((x / peak) ** 2))) if peak > 0.0 else peak


def _wls_unit(Wb: np.ndarray, s: np.ndarray, legs: np.ndarray):
    """wls on forces of RMS 1."""
    M, r = Wb.shape
    beta0 = np.linalg.lstsq(Wb, s, rcond=None)[0]
    res = s - Wb @ beta0
    noise = np.empty(6)
    for j in range(6):
        rows = legs == j
        noise[j] = np.sqrt(np.sum(res[rows] ** 2) / max(np.count_nonzero(rows) - r / 6, 1.0))
    noise = np.maximum(noise, _NOISE_FLOOR)     # the RMS force is 1 here
    w = 1.0 / noise[legs]
    A = Wb * w[:, None]
    beta, *_ = np.linalg.lstsq(A, s * w, rcond=None)
    wres = (s - Wb @ beta) * w
    s2 = float(wres @ wres) / (M - r)
    Rf = np.linalg.qr(A, mode="r")
    try:
        Rinv = np.linalg.inv(Rf)
    except np.linalg.LinAlgError:
        raise IdentificationError(
            f"the weighted regressor is singular (per-leg force noise {noise.tolist()} of the "
            "RMS force): the runs' forces are not those of one machine") from None
    if not np.all(np.isfinite(Rinv)) or not np.isfinite(s2):
        raise IdentificationError(f"the estimate's covariance is not finite (per-leg force "
                                  f"noise {noise.tolist()} of the RMS force): check the runs' "
                                  "forces")
    cov = s2 * (Rinv @ Rinv.T)
    rms = np.array([np.sqrt(np.mean((s - Wb @ beta)[legs == j] ** 2)) for j in range(6)])
    return beta, cov, noise, rms


def estimate(W: np.ndarray, s: np.ndarray, legs: np.ndarray, base: BaseParameters,
             prior: np.ndarray, scale: np.ndarray, length: float,
             hold: np.ndarray | None = None) -> Estimate:
    """The estimate from rows W (M, N_STANDARD), forces s (M,), leg of each row; `prior` the
    scene's standard parameters (zero where the scene lacks the effect), `scale` a typical
    magnitude of each standard parameter, `length` the platform's characteristic length (it
    scales the pseudo-inertias); `hold` (bool per standard parameter) those to keep at the
    prior where the data leave the choice (the ones the scene cannot hold).

    The consistent point is first sought with the standard parameters the data do not
    determine, and those of `hold` that they determine only in combination, held at the prior
    (they then keep it exactly: the estimate moves the prior only along what the data
    determine); only when no consistent point exists so are they freed, and Estimate.moved
    names those the data do not determine that moved."""
    Wb = W[:, base.independent]
    beta, cov, noise, rms = wls(Wb, s, legs)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    scene = np.zeros(N_STANDARD, dtype=bool)
    scene[base.columns] = True
    determined = scene & np.any(base.combination != 0.0, axis=0)
    alone = np.isin(np.array(NAMES), base.alone)
    first = determined & ~(np.zeros(N_STANDARD, dtype=bool) if hold is None else hold & ~alone)
    pi = _nearest(base, beta, prior, scale, first)
    if pi is None or not meets(pi, first, length, scale):
        # the programs: with all free first, as a WLS estimate that no consistent set
        # reproduces (noise) needs no second program to tell
        pi = consistent_point(base, beta, prior, scale, length, scene)
        held = consistent_point(base, beta, prior, scale, length, first) \
            if pi is not None and not np.array_equal(first, scene) else None
        pi = held if held is not None else pi
    constrained = pi is None
    if constrained:
        w = noise.min() / noise[legs]    # the weights 1 / noise to a common factor
        Rf = np.linalg.qr(np.column_stack([Wb * w[:, None], s * w]), mode="r")
        pi = constrained_fit(base, Rf, prior, scale, length, scene)
    pi = project(pi, scene, length, scale)
    moved = tuple(NAMES[k] for k in np.flatnonzero(scene & ~determined & (pi != prior)))
    beta_c = base.beta(pi) if constrained else beta   # pi reproduces the WLS beta to rounding
    return Estimate(beta_c, std, beta, pi, noise, rms, constrained, len(s), moved)


def scales(model: Model, prior: np.ndarray) -> np.ndarray:
    """A typical magnitude of each standard parameter: its prior, or for a prior of zero the
    platform's mass times the characteristic length (first moments) or its square (inertia),
    1 N for Coulomb friction, 1 for anything else."""
    L, m = model.characteristic_length, model.platform_mass
    out = np.abs(prior).astype(float)
    for name, typical in (("PLATFORM_MOMENT", m * L), ("PLATFORM_INERTIA", m * L * L),
                          ("LOWER_MOMENT", m * L), ("UPPER_MOMENT", m * L),
                          ("LOWER_INERTIA", m * L * L), ("UPPER_INERTIA", m * L * L),
                          ("LOWER_AXIAL", m * L * L), ("UPPER_AXIAL", m * L * L),
                          ("COULOMB", 1.0)):
        sl = span(name)
        out[sl] = np.where(out[sl] > 0, out[sl], typical)
    out[out == 0] = 1.0
    return out



# ---------------------------------------------------------------- the semidefinite programs

def _variables(prior: np.ndarray, scale: np.ndarray, free: np.ndarray):
    import cvxpy as cp

    x = cp.Variable(int(np.count_nonzero(free)))
    idx = np.flatnonzero(free)
    pi = [float(prior[k]) for k in range(N_STANDARD)]
    for n, k in enumerate(idx):
        pi[k] = prior[k] + scale[k] * x[n]
    return x, pi


def _physical(pi, free: np.ndarray, length: float, scale: np.ndarray,
              inside: float = MARGIN) -> list:
    """The consistency constraints (module docstring) on the free standard parameters; the
    pseudo-inertias scaled by diag(1/length, 1/length, 1/length, 1) (a congruence: same
    semidefiniteness, better conditioned), and kept MARGIN times their body's mass scale inside
    the cone: a solution on its boundary (a body of zero thickness) would be refused by the
    scene's own rules (axial <= 2 x transverse, the triangle inequality) for a rounding error.
    `inside` replaces MARGIN for a point deeper inside (refine's start)."""
    import cvxpy as cp

    margin = inside * scale[[span(n).start for n in ("PLATFORM_MASS", "LOWER_MASS",
                                                     "UPPER_MASS")]]
    cons = []
    m = pi[span("PLATFORM_MASS").start]
    h = [pi[k] for k in range(*span("PLATFORM_MOMENT").indices(N_STANDARD))]
    xx, xy, xz, yy, yz, zz = (pi[k] for k in range(*span("PLATFORM_INERTIA").indices(N_STANDARD)))
    tr = (xx + yy + zz) / 2
    L, L2 = length, length * length
    rows = [[(tr - xx) / L2, -xy / L2, -xz / L2, h[0] / L],
            [-xy / L2, (tr - yy) / L2, -yz / L2, h[1] / L],
            [-xz / L2, -yz / L2, (tr - zz) / L2, h[2] / L],
            [h[0] / L, h[1] / L, h[2] / L, m]]
    P = cp.bmat([[_expr(v) for v in row] for row in rows])
    cons.append((P + P.T) / 2 >> margin[0] * np.eye(4))
    for part in ("LOWER", "UPPER"):
        k = span(f"{part}_MASS").start
        if not free[k] and not free[span(f"{part}_MOMENT").start]:
            continue
        mp, mc = pi[k], pi[span(f"{part}_MOMENT").start]
        jt, ja = pi[span(f"{part}_INERTIA").start], pi[span(f"{part}_AXIAL").start]
        Q = cp.bmat([[_expr((jt - ja / 2) / L2), _expr(mc / L)], [_expr(mc / L), _expr(mp)]])
        cons += [(Q + Q.T) / 2 >> margin[1 if part == "LOWER" else 2] * np.eye(2),
                 _expr(ja) >= 0]
    for name in ("DRIVE_MASS", "VISCOUS", "COULOMB"):
        for k in range(*span(name).indices(N_STANDARD)):
            if free[k]:
                cons.append(_expr(pi[k]) >= 0)
    return cons


def _expr(v):
    import cvxpy as cp

    return v if isinstance(v, cp.Expression) else cp.Constant(v)


def _solve(problem) -> bool:
    import cvxpy as cp

    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError:
        return False
    return problem.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


def consistent_point(base: BaseParameters, beta: np.ndarray, prior: np.ndarray,
                     scale: np.ndarray, length: float, free: np.ndarray,
                     inside: float = MARGIN) -> np.ndarray | None:
    """The physically consistent pi nearest the prior (scaled) with K pi = beta, the standard
    parameters not `free` held at the prior, or None; the pseudo-inertias `inside` (times
    their mass scale) inside the cone (_physical). When the nearest point with K pi = beta
    (least squares, closed form) is consistent it is that point, and no semidefinite program is
    set up (nor cvxpy imported): the constraints are then inactive and the program's optimum is
    the same point."""
    nearest = _nearest(base, beta, prior, scale, free)
    if nearest is not None and meets(nearest, free, length, scale, inside):
        return nearest
    import cvxpy as cp

    x, pi = _variables(prior, scale, free)
    K = base.combination
    # K pi = beta, in the base parameters' own scale
    bscale = np.abs(K) @ scale
    eq = [(K[i] @ cp.hstack([_expr(v) for v in pi]) - beta[i]) / bscale[i] == 0
          for i in range(len(beta))]
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x)),
                         eq + _physical(pi, free, length, scale, inside))
    if not _solve(problem) or problem.status != cp.OPTIMAL:
        return None
    out = _values(pi)
    return _polish(base, out, beta, scale, free)


def constrained_fit(base: BaseParameters, Rf: np.ndarray, prior: np.ndarray,
                    scale: np.ndarray, length: float, free: np.ndarray) -> np.ndarray:
    """Least squares of the weighted rows (their R factor with the right-hand side as last
    column) under the consistency constraints, with a vanishing pull to the prior (1e-6 in the
    prior's scale) for what the data do not determine; the standard parameters not `free`
    held at the prior."""
    import cvxpy as cp

    x, pi = _variables(prior, scale, free)
    r = Rf.shape[1] - 1
    piv = cp.hstack([_expr(v) for v in pi])
    norm = max(abs(Rf[-1, -1]), float(np.abs(Rf).max()) * 1e-12)
    fit = (Rf[:r, :r] @ (base.combination @ piv) - Rf[:r, r]) / norm
    problem = cp.Problem(cp.Minimize(cp.sum_squares(fit) + 1e-6 * cp.sum_squares(x)),
                         _physical(pi, free, length, scale))
    if not _solve(problem):
        raise IdentificationError(
            f"the physically consistent fit failed (Clarabel: {problem.status})")
    return _values(pi)


def _nearest(base: BaseParameters, beta: np.ndarray, prior: np.ndarray, scale: np.ndarray,
             free: np.ndarray) -> np.ndarray | None:
    """The pi nearest the prior (in scale) with K pi = beta moving only `free` ones, or None
    when those cannot reproduce beta (to 1e-12 of each base parameter's scale)."""
    K = base.combination[:, free] * scale[free]
    gap = beta - base.beta(prior)
    d = np.linalg.lstsq(K, gap, rcond=None)[0]
    out = prior.astype(float).copy()
    out[free] += scale[free] * d
    bscale = np.abs(base.combination) @ scale
    if not np.all(np.abs(base.beta(out) - beta) <= 1e-12 * bscale):
        return None
    return out


def meets(pi: np.ndarray, free: np.ndarray, length: float, scale: np.ndarray,
          inside: float = MARGIN) -> bool:
    """Whether pi meets the consistency constraints of _physical (with their margins, `inside`)
    on the bodies with a free parameter: project would return it unchanged, and no leg part's
    mass is within its margin of zero."""
    for part in ("LOWER", "UPPER"):
        k_m = span(f"{part}_MASS").start
        if free[k_m:span(f"{part}_AXIAL").stop].any() and pi[k_m] <= inside * scale[k_m]:
            return False
    return bool(np.array_equal(project(pi, free, length, scale, inside), pi))


def project(pi: np.ndarray, free: np.ndarray, length: float, scale: np.ndarray,
            inside: float = MARGIN) -> np.ndarray:
    """pi meeting the consistency constraints (_physical) exactly, where the solver met them
    to its tolerance only: a drive mass or friction below zero set to zero; a platform
    pseudo-inertia with an eigenvalue below its margin shifted by the identity (mass and
    diagonal inertia up by the deficit, first moment and products kept); a leg part's axial
    moment below zero set to zero, then its transverse term raised to the least value that
    makes its pseudo-inertia meet the margin (mass and first moment kept). Only bodies with a
    free parameter are touched, and a parameter that meets its constraint is returned as is.
    `inside` replaces MARGIN (_physical)."""
    out = np.array(pi, dtype=float)
    for name in ("DRIVE_MASS", "VISCOUS", "COULOMB"):
        sl = span(name)
        out[sl] = np.where(free[sl] & (out[sl] < 0.0), 0.0, out[sl])
    L, L2 = length, length * length
    margin = inside * scale[span("PLATFORM_MASS").start]
    P = _platform_pseudo_inertia(out, L)
    deficit = margin - float(np.linalg.eigvalsh(P).min())
    if deficit > 0.0 and free[:span("PLATFORM_INERTIA").stop].any():
        shift = deficit * (1.0 + 1e-6) + np.finfo(float).eps * float(np.abs(P).max())
        out[span("PLATFORM_MASS")] += shift
        out[[span("PLATFORM_INERTIA").start + k for k in (0, 3, 5)]] += 2.0 * shift * L2
    for part in ("LOWER", "UPPER"):
        k_m, k_c = span(f"{part}_MASS").start, span(f"{part}_MOMENT").start
        k_j, k_a = span(f"{part}_INERTIA").start, span(f"{part}_AXIAL").start
        if not free[[k_m, k_c, k_j, k_a]].any():
            continue
        margin = inside * scale[k_m]
        if free[k_a] and out[k_a] < 0.0:
            out[k_a] = 0.0
        m, mc = out[k_m], out[k_c] / L
        if m <= margin:
            continue          # no transverse moment helps: left to the scene's check
        least = L2 * (margin + mc * mc / (m - margin)) * (1.0 + 1e-9) + out[k_a] / 2.0
        if out[k_j] < least:
            out[k_j] = least
    return out


def _platform_pseudo_inertia(pi: np.ndarray, length: float) -> np.ndarray:
    """The platform's pseudo-inertia, scaled by diag(1/length (x3), 1) (as in _physical)."""
    m, h = pi[span("PLATFORM_MASS")][0], pi[span("PLATFORM_MOMENT")]
    xx, xy, xz, yy, yz, zz = pi[span("PLATFORM_INERTIA")]
    inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    P = np.zeros((4, 4))
    P[:3, :3] = (np.trace(inertia) / 2 * np.eye(3) - inertia) / length**2
    P[:3, 3] = P[3, :3] = h / length
    P[3, 3] = m
    return P


def _values(pi) -> np.ndarray:
    return np.array([float(v.value) if hasattr(v, "value") else float(v) for v in pi])


def _polish(base: BaseParameters, pi: np.ndarray, beta: np.ndarray, scale: np.ndarray,
            free: np.ndarray) -> np.ndarray:
    """pi moved the least (in scale) so that K pi = beta to rounding (the solver's equality is
    good to its tolerance only)."""
    K = base.combination[:, free] * scale[free]
    d = np.linalg.lstsq(K, beta - base.beta(pi), rcond=None)[0]
    out = pi.copy()
    out[free] += scale[free] * d
    return out
