"""The optimisation of an excitation trajectory: the Fourier coefficients (fourier.py) that
minimise the scaled condition number of the stacked base regressor, inside the limits
(bounds.py).

Objective: log10 of identify.base.scaled_condition of W_b, the regressor
(stewart_fmu.dynamics.regressor) of the prior scene stacked over the samples of one period,
restricted to the columns of the scene's structural base parameters
(identify.base.structural_base). One period suffices: the trajectory repeats it, and stacking
the same rows n times leaves the condition number as it is.

Grid: GRID_PER_HARMONIC samples per period of the highest harmonic, evenly over one period
(100 for 5 harmonics). The regressor's columns are products of the pose's harmonics (velocity
squared, sin and cos of the angles), so they reach a few times H w_f: 20 samples a period of
the top harmonic keep even its third harmonic (about 7 a period) above the Nyquist rate, and
the sum over the grid close to the integral over the period. A sinusoid's peak between two
grid samples is at most 1 - cos(pi / 20) = 1.2 % above the larger of them, well inside the
limits' margins; the trajectory written is checked again at every sample of the output rate.

Method: SLSQP (scipy.optimize) with every limit at every grid sample as an inequality
constraint (bounds.slack of bounds.Samples: each a smooth function of x, where the peak over
the samples is not: its gradient jumps when another sample becomes the peak, and SLSQP's steps
then depend on which sample wins by the last bit), forward-difference gradients (FD_STEP),
from STARTS random starts (seed SEED) each scaled down until it lies well inside every limit,
MAX_ITERATIONS each, then up to POLISH_ITERATIONS more from the best point of all starts,
each run ending early when the objective changes by less than FTOL. The best point inside the
limits seen over all runs is kept. The objective is taken from R of a Householder QR of W
(backward stable; W^T W would square the condition number). The result is deterministic for a
seed on a given machine; across BLAS builds, threads and CPU kernels the path differs in its
last bits, and the starts and the polish bring each to a comparable optimum
(docs/guides/identification-and-calibration.md: the spread measured).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
import scipy.optimize
from threadpoolctl import threadpool_limits

from controller.config import ControllerConfig
from controller.drive import constant_load
from controller.trajectory import Trajectory
from stewart_fmu.budget import check_count
from stewart_fmu.dynamics import regressor
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model
from stewart_fmu.standard import N_STANDARD
from stewart_sim.studies.excite.bounds import (MAX_SLACKS, Kept, Peaks, limits, peaks, samples,
                                               slack, tightest)
from stewart_sim.studies.excite.fourier import FourierSeries
from stewart_sim.studies.identify.base import (BaseParameters, scaled_condition, stacked,
                                               structural_base)

PERIOD = 5.0             # s: the fundamental period (0.2 Hz)
HARMONICS = 5            # harmonics per axis (up to 1 Hz)
PERIODS = 12             # default duration: 12 periods, 60 s
GRID_PER_HARMONIC = 20   # grid samples per period of the highest harmonic (see the module doc)
STARTS = 2               # random starts
MAX_STARTS = 100         # --starts at most this: each start is SLSQP's work of a few seconds
MAX_ITERATIONS = 40      # SLSQP iterations per start
POLISH_ITERATIONS = 60   # SLSQP iterations from the best point of all starts
FTOL = 1e-6              # a run ends when log10 cond changes by less than this
ACCEPT_TOL = 1e-4        # a point within this below GRID_SLACK counts as inside (SLSQP's
                         # iterates meet an active constraint to about this); every sample of
                         # the trajectory written is checked against the bound itself
SEED = 0
START_SLACK = 0.05       # a start is scaled down until every limit has this much slack
GRID_SLACK = 0.01        # slack kept on the grid: peaks between its samples (see the module doc)
FD_STEP = 1e-6           # forward-difference step in x (x is of order 1)
_FAILED = 10.0           # log10 cond of a point where the dynamics cannot be evaluated


# bytes each count below takes: a constraint derivative is held by _Problem.gradients, by
# scipy's stacked copy and by SLSQP; a basis entry by the SVD of scipy.linalg.null_space and the
# two bases; an output sample holds its sin and cos of each harmonic (8 bytes each) and
# OUTPUT_FLOATS more floats: q, qd, qdd, feasibility's per-leg arrays and the regressor with
# its stacked copy and QR (3 x 6 x N_STANDARD)
DERIVATIVE_BYTES = 3 * 8
BASIS_BYTES = 3 * 8
OUTPUT_FLOATS = 18 + 12 * 6 + 3 * 6 * N_STANDARD


def check_sizes(harmonics: int, period: float, periods: int, rate: float) -> None:
    """Refuse (BudgetError, StewartError: one line naming the argument) a design whose arrays
    would not fit the memory budget (stewart_fmu.budget), or whose top harmonic the output rate
    cannot represent, before anything of that size is allocated."""
    h = float(harmonics)
    check_count(f"excite: --harmonics {harmonics}: entries of the series' bases", h * h,
                BASIS_BYTES, "fewer harmonics")
    grid, size = GRID_PER_HARMONIC * h, 12.0 * (h - 1.0)
    check_count(f"excite: --harmonics {harmonics}: the optimiser's constraint derivatives "
                f"({grid:.0f} grid samples x {MAX_SLACKS} limits x {size:.0f} coefficients)",
                grid * MAX_SLACKS * size, DERIVATIVE_BYTES, "fewer harmonics")
    samples_out = periods * period * rate + 1.0
    check_count(f"excite: --harmonics {harmonics} over {periods * period:g} s (--duration) at "
                f"{rate:g} Hz: trajectory samples", samples_out, 8.0 * (2.0 * h + OUTPUT_FLOATS),
                "fewer harmonics or a shorter --duration")
    top = harmonics / period
    if not top < 0.5 * rate:
        raise StewartError(f"excite: --harmonics {harmonics} of a --period of {period:g} s reach "
                           f"{top:.4g} Hz, not below half the trajectory's rate of {rate:g} Hz: "
                           "its samples would not represent them (fewer harmonics or a longer "
                           "period)")


@dataclass(frozen=True)
class Design:
    """An optimised excitation: the series and its x, the condition number on the grid, the
    base parameters it is measured over, the scene's limits and what each start reached."""

    series: FourierSeries
    x: np.ndarray
    cond: float
    base: BaseParameters
    limits: Kept
    starts: tuple[float, ...]     # cond reached from each start (inf: none feasible)
    evaluations: int              # regressor evaluations (objective and gradients)


class _Problem:
    """Objective and constraints of x on the grid, cached per x (SLSQP asks each one apart)."""

    def __init__(self, model: Model, controller: ControllerConfig | None, series: FourierSeries,
                 lim: Kept, columns: np.ndarray) -> None:
        self.series, self.lim = series, lim
        # the drive's constant load once (axis_model would derive it at every evaluation)
        self.controller = controller if controller is None or controller.load_mass is not None \
            or model.drive is None else replace(controller, load_mass=constant_load(model))
        # the dynamics outside the stroke too: the constraints, not an error, keep x inside
        self.free = replace(model, leg_min=None, leg_max=None)
        self.columns = columns
        m = GRID_PER_HARMONIC * series.harmonics
        self.t = np.arange(m) * (series.period / m)
        self.cache: dict[bytes, tuple[float, np.ndarray]] = {}
        self.count = 0
        self.best: tuple[float, np.ndarray] | None = None
        self.constraints = None

    def values(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """(log10 cond, slack) at x."""
        key = x.tobytes()
        if key not in self.cache:
            if len(self.cache) > 64:
                self.cache.clear()
            self.cache[key] = self._evaluate(x)
        return self.cache[key]

    def _evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        self.count += 1
        # far outside the limits an overflow is possible; it shows as a non-finite slack or
        # objective, which marks the point as failed, so numpy's warning would only be noise
        with np.errstate(all="ignore"):
            return self._evaluate_quietly(x)

    def _evaluate_quietly(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        q, qd, qdd = self.series.evaluate(x, self.t)
        try:
            g = slack(self.lim, samples(self.free, self.controller, self.t, q, qd, qdd)).ravel()
        except StewartError:        # a pose the kinematics cannot take: far outside
            return _FAILED, np.full(self.constraint_count(), -1.0)
        if not np.all(np.isfinite(g)):
            return _FAILED, np.full(g.size, -1.0)
        try:
            W = stacked(regressor(self.free, q, qd, qdd)[:, :, self.columns])
            # R of W = QR has W's singular values and column norms (Q is orthonormal), so the
            # same scaled condition number from a (P, P) SVD; Householder QR is backward stable,
            # where W^T W would square the condition number
            f = float(np.log10(scaled_condition(np.linalg.qr(W, mode="r"))))
        except np.linalg.LinAlgError:
            f = _FAILED
        if not f < _FAILED:   # inf: a column of zeros, a parameter not excited at all; or NaN
            f = _FAILED
        inside = f < _FAILED and np.all(g >= GRID_SLACK - ACCEPT_TOL)
        if inside and (self.best is None or f < self.best[0]):
            self.best = (f, x.copy())
        return f, g

    def constraint_count(self) -> int:
        if self.constraints is None:
            x0 = np.zeros(self.series.size)
            q, qd, qdd = self.series.evaluate(x0, self.t)
            self.constraints = slack(self.lim, samples(self.free, self.controller, self.t, q, qd,
                                                       qdd)).size
        return self.constraints

    def gradients(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forward differences of the objective (n,) and the constraints (m, n)."""
        f0, g0 = self.values(x)
        df = np.empty(x.size)
        dg = np.empty((g0.size, x.size))
        for i in range(x.size):
            xi = x.copy()
            xi[i] += FD_STEP
            f, g = self._evaluate(xi)      # not cached: each is asked once
            df[i] = (f - f0) / FD_STEP
            dg[:, i] = (g - g0) / FD_STEP
        return df, dg


def design(model: Model, controller: ControllerConfig | None, *, period: float = PERIOD,
           harmonics: int = HARMONICS, starts: int = STARTS, max_iterations: int = MAX_ITERATIONS,
           seed: int = SEED, polish: int = POLISH_ITERATIONS,
           progress: Callable[[str, int, int], None] | None = None) -> Design:
    """The excitation of lowest scaled condition number found inside the scene's limits;
    StewartError when no start lies inside them (a scene with no room to move).

    BLAS runs on one thread here: the regressors are a few hundred rows, too small to gain from
    more, and the order in which several threads add would steer SLSQP along another path (the
    condition number reached would then depend on the machine's core count)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _design(model, controller, period, harmonics, starts, max_iterations, seed,
                       polish, progress)


def _design(model: Model, controller: ControllerConfig | None, period: float, harmonics: int,
            starts: int, max_iterations: int, seed: int, polish: int,
            progress: Callable[[str, int, int], None] | None) -> Design:
    lim = limits(model, controller)
    base = structural_base(model)
    series = FourierSeries(period, harmonics, np.asarray(model.home, dtype=float),
                           _scale(model, lim))
    problem = _Problem(model, controller, series, lim, base.independent)
    problem.constraint_count()
    rng = np.random.default_rng(seed)
    reached = []
    for s in range(starts):
        x0 = _inside(problem, rng.standard_normal(series.size))
        found = _minimise(problem, x0, max_iterations, f"start {s + 1}/{starts}", progress)
        reached.append(np.inf if found is None else 10.0 ** found[0])
    if problem.best is None:
        raise StewartError("excite: no excitation found inside the limits (see the margins of "
                           "`stewart-sim excite --help`)")
    _minimise(problem, problem.best[1], polish, "polish", progress)
    f, x = problem.best
    return Design(series, x, 10.0 ** f, base, lim, tuple(reached), problem.count)


def _minimise(problem: _Problem, x0: np.ndarray, iterations: int, stage: str,
              progress: Callable[[str, int, int], None] | None) -> tuple[float, np.ndarray] | None:
    """SLSQP from x0 for at most `iterations` (fewer when the objective changes by less than
    FTOL): the best point inside the limits it met (None: none), kept in problem.best when
    better than what that held."""
    before, problem.best = problem.best, None
    iteration = [0]

    def step(_x: np.ndarray) -> None:
        iteration[0] += 1
        if progress is not None:
            best = "" if problem.best is None else f", cond {10.0 ** problem.best[0]:.4g}"
            progress(f"excite: {stage}{best}", iteration[0], iterations)

    memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def grads(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = problem.gradients(x)
        return memo[key]

    if iterations > 0:
        scipy.optimize.minimize(
            lambda x: problem.values(x)[0], x0, jac=lambda x: grads(x)[0], method="SLSQP",
            constraints=[{"type": "ineq", "fun": lambda x: problem.values(x)[1] - GRID_SLACK,
                          "jac": lambda x: grads(x)[1]}],
            options={"maxiter": iterations, "ftol": FTOL}, callback=step)
    found = problem.best
    if before is not None and (found is None or before[0] <= found[0]):
        problem.best = before
    return found


def _scale(model: Model, lim: Kept) -> np.ndarray:
    """The amplitude per unit of x: a tenth of the stroke for x, y, z (m), that over the
    scene's characteristic length for the angles (rad)."""
    span = 0.1 * (lim.leg_max - lim.leg_min)
    return np.array([span] * 3 + [span / model.characteristic_length] * 3)


def _inside(problem: _Problem, x: np.ndarray) -> np.ndarray:
    """x scaled down until every limit has START_SLACK to spare (or half what it has at rest
    at home, when that is less)."""
    at_rest = problem.values(np.zeros_like(x))[1]
    if np.min(at_rest) <= GRID_SLACK:
        raise StewartError("excite: no room to move: at rest at home the scene is already at "
                           f"a limit ({tightest(problem.lim, at_rest)})")
    target = min(START_SLACK, 0.5 * float(np.min(at_rest)))
    for _ in range(60):
        if np.min(problem.values(x)[1]) >= target:
            return x
        x = 0.7 * x
    raise StewartError("excite: no room to move: every motion tried crosses a limit "
                       f"({tightest(problem.lim, problem.values(x)[1])})")


@dataclass(frozen=True)
class Excitation:
    """The trajectory of a design at the output rate, what it asks at every sample and the
    scaled condition number of its stacked base regressor over every sample."""

    design: Design
    trajectory: Trajectory
    periods: int
    rate: float
    peaks: Peaks
    slack: np.ndarray      # bounds.slack of `peaks`, all >= 0
    cond: float
    shrunk: float          # design.x was scaled by this to keep every limit at every sample


def excitation(model: Model, controller: ControllerConfig | None, d: Design, periods: int,
               rate: float) -> Excitation:
    """`periods` periods of the design at `rate`, checked against every limit at every sample
    (scaled down by 1 % steps in the rare case a peak between grid samples crosses one)."""
    free = replace(model, leg_min=None, leg_max=None)
    factor = 1.0
    for _ in range(100):
        traj = d.series.trajectory(factor * d.x, periods, rate)
        p = peaks(free, controller, traj.t, traj.q, traj.qd, traj.qdd)
        g = slack(d.limits, p)
        if np.min(g) >= 0.0:
            break
        factor *= 0.99
    else:
        raise StewartError(f"excite: the trajectory crosses a limit ({tightest(d.limits, g)})")
    W = stacked(regressor(free, traj.q, traj.qd, traj.qdd)[:, :, d.base.independent])
    cond = scaled_condition(W)
    if not np.isfinite(cond):
        raise StewartError("excite: the trajectory leaves a base parameter unexcited (scaled "
                           "condition number not finite): no trajectory to identify from")
    return Excitation(d, traj, periods, rate, p, g, cond, factor)
