"""Work-precision data: the error each integrator (and each co-simulation step) buys for its
run time, against a tight reference solution that a second method checks.

Open loop: from rest at home, the plant (stewart_fmu.plant.Plant) is driven over a fixed
horizon by the rack forces of the demonstration move (inverse dynamics at the middle of each
communication step, held over it) plus a smooth perturbation, so the motion departs from the
planned one but stays in the stroke. Every integrator integrates the same piecewise-constant
input, so the differences are integration error only.

Errors (dimensionless, the max over time):
  pose  = max(|x - x_ref|_max / translational range, |th - th_ref|_max / rotational range),
          the ranges being the reference motion's largest peak-to-peak coordinate;
  force = |f - f_ref|_max / max |sigma| over every part of the breakdown the plant reports
          (platform, legs, drives, gravity, friction: inverse_dynamics_parts) and leg.

Closed loop: controller.cosim.run_closed_loop tracking the `run` reference (a quintic move out
and back) with the scene's controllers at several communication steps (the controller rate is
the communication rate), against the same loop at a small step.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from controller.config import ControllerConfig
from controller.cosim import run_closed_loop
from controller.design import UnstableLoopError
from controller.moves import demo_trajectory, run_reference
from stewart_fmu.dynamics import forward_dynamics, inverse_dynamics, inverse_dynamics_parts
from stewart_fmu.errors import IntegrationError, TrajectoryError
from stewart_fmu.integrators import FIXED_STEP, INTEGRATORS, IntegratorOptions
from stewart_fmu.model import Model
from stewart_fmu.plant import Plant, StepRejected

COMM_STEP = 0.05          # s: open-loop communication step (forces held over it)
HORIZON = 1.0             # s: open-loop horizon
REPEATS = 3               # timings per run, the best kept (runs under 0.2 s repeat until then)
PERTURBATION = 0.05       # perturbation amplitude, a fraction of the peak planned force
PERTURBATION_HZ = (0.7, 1.1, 0.9, 1.3, 0.8, 1.2)
REFERENCE = IntegratorOptions("DOP853", rtol=1e-13, atol=1e-16)   # max_step: the comm step
SECOND = IntegratorOptions("Radau", rtol=1e-12, atol=1e-15)       # the reference's check
REFERENCE_TOLERANCE = 1e-11  # stated: reference and second method agree to this (pose, force)
ORDER_FLOOR = 30.0           # orders are fitted on errors above this many reference tolerances
ORDER_POINTS = 4             # ... over the finest so many of them (the asymptotic range)
ORDER_MIN_POINTS = 3         # fewer points above the floor: the order is not measurable

# Sweeps: internal steps per communication step (fixed-step methods), rtol (adaptive ones).
SWEEPS = {
    "default": {"rk4": (1, 2, 4, 8, 16, 32), "euler": (1, 4, 16, 64, 256, 1024),
                "rtol": (1e-3, 1e-5, 1e-7, 1e-9, 1e-11)},
    "fine": {"rk4": tuple(2**k for k in range(8)), "euler": tuple(2**k for k in range(13)),
             "rtol": tuple(10.0**-k for k in range(3, 13))},
}
ATOL_RATIO = 1e-3            # atol = ATOL_RATIO * rtol in the sweeps (states are O(0.01-1))
CLOSED_LOOP_STEPS = (0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3)   # s: communication steps
CLOSED_LOOP_REFERENCE = 1 / 16_000                         # s: the reference loop's step
CLOSED_LOOP_DURATION = 4.0                                 # s: as `stewart-sim run`
TIME_BUDGET = 2.0            # s: stop repeating a timed run once its repeats took this long
MIN_TIMING = 0.2             # s: ... and repeat short runs until they took this long
MAX_REPEATS = 50

ProgressFn = Callable[[int, int], None]  # progress(done, total)


@dataclass(frozen=True)
class OpenLoopCase:
    """The open-loop test case: comm_step-held rack forces (N, 6) from rest at home."""

    model: Model
    comm_step: float
    forces: np.ndarray

    @property
    def times(self) -> np.ndarray:
        return np.arange(len(self.forces) + 1) * self.comm_step


@dataclass(frozen=True)
class Reference:
    """The reference solution at every communication point and what it is checked against."""

    states: np.ndarray          # (N + 1, 12) q, qd
    parts: np.ndarray           # (N, parts, 6) the breakdown at the start of each step
    ranges: tuple[float, float] # translational (m) and rotational (rad) peak-to-peak range
    force_scale: float          # N: peak |sigma|
    agreement: tuple[float, float]  # (pose, force) error of the second method against it
    run_time: float             # s


def open_loop_case(model: Model, horizon: float = HORIZON, comm_step: float = COMM_STEP
                   ) -> OpenLoopCase:
    """The demonstration move's forces at mid-step plus PERTURBATION of their peak."""
    n = int(round(horizon / comm_step))
    if not (np.isfinite(horizon) and comm_step > 0 and n >= 2):
        raise TrajectoryError(f"accuracy: the horizon ({horizon!r} s) must span two or more "
                              f"communication steps of {comm_step!r} s")
    t, q, qd, qdd = demo_trajectory(model, n * comm_step, rate=2.0 / comm_step)
    mid = slice(1, None, 2)                              # t = (k + 1/2) comm_step
    sigma = inverse_dynamics(model, q[mid], qd[mid], qdd[mid])
    phase = 2 * np.pi * np.outer(t[mid], PERTURBATION_HZ)
    sigma = sigma + PERTURBATION * np.max(np.abs(sigma)) * np.sin(phase)
    return OpenLoopCase(model, comm_step, sigma)


def simulate(case: OpenLoopCase, options: IntegratorOptions) -> np.ndarray:
    """(N + 1, 12) states at the communication points through the Plant's FMI life cycle."""
    plant = Plant(case.model, options)
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    plant.set_force(case.forces[0])      # a [transmission] starts preloaded with it
    plant.exit_initialization_mode()
    states = np.empty((len(case.forces) + 1, 12))
    states[0] = np.r_[plant.outputs.q, plant.outputs.qd]
    for k, force in enumerate(case.forces):
        plant.set_force(force)
        plant.do_step(plant.time, case.comm_step)
        states[k + 1, :6], states[k + 1, 6:] = plant.outputs.q, plant.outputs.qd
    return states


def best_of(run: Callable[[], tuple[object, float]], repeats: int, warmup: bool = True
            ) -> tuple[object, float]:
    """run() -> (result, seconds): the last result and the least seconds over at least
    `repeats` calls, more while they took under MIN_TIMING (unless repeats is 1: one call),
    fewer once past TIME_BUDGET.

    Warm-up: with `warmup` (the default) one call of the same run comes first, untimed and
    discarded, so one-time costs (loading the plant's C core and scipy's solvers, first
    allocations, caches) never count in a timing, also with --repeats 1 where the timed call
    is the only one. (Measured with the C core: the first call is no slower than the next
    ones any more, so this only guards against such costs coming back.)"""
    if warmup:
        run()
    best, spent, calls, result = np.inf, 0.0, 0, None
    min_time = MIN_TIMING if repeats > 1 else 0.0
    while calls < max(1, repeats) or (spent < min_time and calls < MAX_REPEATS):
        result, took = run()
        best, spent, calls = min(best, took), spent + took, calls + 1
        if spent > TIME_BUDGET:
            break
    return result, best


def timed(run: Callable[[], object], repeats: int, warmup: bool = True) -> tuple[object, float]:
    """(result, best perf_counter wall time) of run() after an untimed warm-up call, see
    best_of."""
    def clocked():
        start = time.perf_counter()
        result = run()
        return result, time.perf_counter() - start
    return best_of(clocked, repeats, warmup)


def breakdown(case: OpenLoopCase, states: np.ndarray) -> np.ndarray:
    """(N, parts, 6): the parts of the rack force at the start of every step (Plant.outputs.parts
    for the states and held forces, evaluated as one batch)."""
    q, qd = states[:-1, :6].copy(), states[:-1, 6:].copy()
    qdd = forward_dynamics(case.model, q, qd, case.forces)
    return np.stack(list(inverse_dynamics_parts(case.model, q, qd, qdd).values()), axis=1)


def reference_solution(case: OpenLoopCase) -> Reference:
    """REFERENCE at the case's communication step, with its agreement with SECOND."""
    opts = [replace(o, max_step=case.comm_step) for o in (REFERENCE, SECOND)]
    states, seconds = timed(lambda: simulate(case, opts[0]), 1)
    spread = np.ptp(states[:, :6], axis=0)
    ref = Reference(states, breakdown(case, states), (float(np.max(spread[:3])),
                    float(np.max(spread[3:]))), float(np.max(np.abs(case.forces))),
                    (np.nan, np.nan), seconds)
    return replace(ref, agreement=errors(case, ref, simulate(case, opts[1])))


def errors(case: OpenLoopCase, ref: Reference, states: np.ndarray) -> tuple[float, float]:
    """(pose, force) relative errors of states against the reference (see the module doc)."""
    e = np.abs(states[:, :6] - ref.states[:, :6])
    pose = max(float(np.max(e[:, :3])) / ref.ranges[0], float(np.max(e[:, 3:])) / ref.ranges[1])
    force = float(np.max(np.abs(breakdown(case, states) - ref.parts))) / ref.force_scale
    return pose, force


def settings_for(sweep: dict, comm_step: float) -> list[IntegratorOptions]:
    """Every integrator at every setting of a SWEEPS entry: fixed-step methods at comm_step / n,
    adaptive ones at every rtol (atol = ATOL_RATIO rtol, steps up to comm_step)."""
    out = []
    for method in INTEGRATORS:
        if method in FIXED_STEP:
            out += [IntegratorOptions(method, max_step=comm_step / n) for n in sweep[method]]
        else:
            out += [IntegratorOptions(method, rtol=r, atol=ATOL_RATIO * r, max_step=comm_step)
                    for r in sweep["rtol"]]
    return out


OPEN_LOOP_FIELDS = [("method", "U12"), ("step", "f8"), ("rtol", "f8"), ("pose_error", "f8"),
                    ("force_error", "f8"), ("run_time", "f8"), ("outcome", "U80")]


def open_loop_sweep(case: OpenLoopCase, ref: Reference, settings: Sequence[IntegratorOptions],
                    repeats: int = REPEATS, progress: ProgressFn | None = None) -> np.ndarray:
    """One row per setting: method, step (fixed-step methods) or rtol, errors, run time (s)."""
    rows = np.zeros(len(settings), dtype=OPEN_LOOP_FIELDS)
    # every timed setting gets its own untimed warm-up call first (timed -> best_of)
    for k, o in enumerate(settings):
        fixed = o.method in FIXED_STEP
        try:
            states, seconds = timed(lambda: simulate(case, o), repeats)
            errs, outcome = errors(case, ref, states), "ok"
        except (IntegrationError, StepRejected) as exc:  # caught and reported, never garbage
            errs, seconds = (np.inf, np.inf), np.nan
            outcome = f"{type(exc).__name__} at t = {exc.time:g} s"
        rows[k] = (o.method, o.max_step if fixed else np.nan, np.nan if fixed else o.rtol,
                   *errs, seconds, outcome)
        if progress is not None:
            progress(k + 1, len(settings))
    return rows


@dataclass(frozen=True)
class Order:
    """A fixed-step method's measured convergence order and where it was fitted."""

    method: str
    theory: int
    measured: float
    steps: tuple[float, ...]   # the step sizes (s) of the fit


def convergence_orders(rows: np.ndarray, floor: float, column: str = "pose_error") -> list[Order]:
    """Slope of log(error) against log(step) per fixed-step method, fitted on the finest
    ORDER_POINTS errors above ORDER_FLOOR * floor (below it the reference's error shows)."""
    out = []
    for method, theory in FIXED_STEP.items():
        sel = rows[(rows["method"] == method) & (rows[column] > ORDER_FLOOR * floor)
                   & np.isfinite(rows[column])]
        sel = np.sort(sel, order="step")[:ORDER_POINTS]
        measured = (float(np.polyfit(np.log(sel["step"]), np.log(sel[column]), 1)[0])
                    if len(sel) >= ORDER_MIN_POINTS else np.nan)
        out.append(Order(method, theory, measured, tuple(sel["step"].tolist())))
    return out


def cheapest(rows: np.ndarray, target: float, column: str = "pose_error") -> np.ndarray | None:
    """The fastest row whose error is at most target (None if none reaches it)."""
    ok = rows[rows[column] <= target]
    return ok[np.argmin(ok["run_time"])] if len(ok) else None


# --- closed loop ---------------------------------------------------------------------------

CLOSED_LOOP_FIELDS = [("step", "f8"), ("pose_error", "f8"), ("tracking_error", "f8"),
                      ("run_time", "f8"), ("stable", "f8")]


def closed_loop_sweep(model: Model, controller: ControllerConfig,
                      steps: Sequence[float] = CLOSED_LOOP_STEPS,
                      duration: float = CLOSED_LOOP_DURATION,
                      reference_step: float = CLOSED_LOOP_REFERENCE, repeats: int = REPEATS,
                      progress: ProgressFn | None = None) -> tuple[np.ndarray, float]:
    """The scene's controllers (`controller`, its [controller] table) at several communication
    steps. Rows per communication step: pose error against the reference loop (relative to the
    motion's range, as the open loop), the max translational tracking error (relative), the
    loop's run time and whether the sampled loop is stable; and the reference's own check.

    The loop converges with order one in its step (the held voltages and the sampled PID), so
    the reference is the Richardson extrapolation 2 q(h) - q(2h) at h = reference_step; its
    check is its difference from the same extrapolation at h / 2."""

    fine, ref_q, coarse = (_closed_loop(model, controller, h, duration, 1, warmup=False)[0]
                           for h in (reference_step / 2, reference_step, 2 * reference_step))
    reference = 2 * ref_q[::2] - coarse
    ranges = (float(np.max(np.ptp(reference[:, :3], axis=0))),
              float(np.max(np.ptp(reference[:, 3:], axis=0))))

    def pose_error(q, step):
        e = np.abs(q - reference[::int(round(step / (2 * reference_step)))][:len(q)])
        return max(float(np.max(e[:, :3])) / ranges[0], float(np.max(e[:, 3:])) / ranges[1])

    check = pose_error((2 * fine[::2] - ref_q)[::2], 2 * reference_step)
    rows = np.zeros(len(steps), dtype=CLOSED_LOOP_FIELDS)
    for k, h in enumerate(steps):
        try:
            q, track, wall = _closed_loop(model, controller, h, duration, repeats)
            rows[k] = (h, pose_error(q, h), track / ranges[0], wall, 1.0)
        except UnstableLoopError:
            rows[k] = (h, np.nan, np.nan, np.nan, 0.0)
        if progress is not None:
            progress(k + 1, len(steps))
    return rows, check


def closed_loop_order(rows: np.ndarray) -> float:
    """Slope of log(pose error) against log(communication step) over the stable rows."""
    ok = rows[(rows["stable"] > 0) & (rows["pose_error"] > 0)]
    return float(np.polyfit(np.log(ok["step"]), np.log(ok["pose_error"]), 1)[0]) if len(ok) > 1 else np.nan


def _closed_loop(model: Model, controller: ControllerConfig, step: float, duration: float,
                 repeats: int, warmup: bool = True):
    """(pose (N, 6), max translational tracking error (m), least loop wall time (s)) of the
    `run` reference tracked with the scene's controllers at communication step `step`; the
    timed loops come after an untimed warm-up loop of the same step (best_of)."""

    config = replace(controller, rate=1.0 / step)
    traj = run_reference(model, config, duration)

    def run():
        result = run_closed_loop(model, config, traj)
        return result, result.summary.wall_time
    result, wall = best_of(run, repeats, warmup)
    q = np.column_stack([result.table[c] for c in ("x", "y", "z", "thx", "thy", "thz")])
    return q, float(np.max(result.summary.pose_max[:3])), wall


# --- the whole study -----------------------------------------------------------------------

@dataclass(frozen=True)
class AccuracyResults:
    """Everything the accuracy report shows for one scene."""

    scene: str
    case: OpenLoopCase
    reference: Reference
    floor: float                    # errors below this are not resolved by the reference
    open_loop: np.ndarray           # OPEN_LOOP_FIELDS rows
    orders: list[Order]             # from the pose errors
    force_orders: list[Order]       # from the force errors
    closed_loop: np.ndarray | None  # CLOSED_LOOP_FIELDS rows; None without [controller]
    closed_loop_check: float        # the closed-loop reference's own error estimate
    closed_loop_duration: float | None
    sweep: str
    repeats: int


def accuracy_study(model: Model, controller: ControllerConfig | None,
                   horizon: float = HORIZON, comm_step: float = COMM_STEP,
                   sweep: str = "default", repeats: int = REPEATS,
                   closed_loop_duration: float | None = CLOSED_LOOP_DURATION,
                   progress: Callable[[str, int, int], None] | None = None) -> AccuracyResults:
    """Open-loop work-precision of every integrator, orders, and (with the scene's [controller]
    table, `controller`, and a closed_loop_duration) the closed loop's communication steps."""
    def stage(name: str) -> ProgressFn | None:
        return None if progress is None else (lambda done, total: progress(name, done, total))

    case = open_loop_case(model, horizon, comm_step)
    ref = reference_solution(case)
    floor = max(REFERENCE_TOLERANCE, *ref.agreement)
    rows = open_loop_sweep(case, ref, settings_for(SWEEPS[sweep], comm_step), repeats,
                           stage("open loop"))
    closed, check = None, np.nan
    if controller is not None and closed_loop_duration is not None:
        closed, check = closed_loop_sweep(model, controller, duration=closed_loop_duration,
                                          repeats=repeats, progress=stage("closed loop"))
    return AccuracyResults(model.name, case, ref, floor, rows, convergence_orders(rows, floor),
                           convergence_orders(rows, floor, "force_error"), closed, check,
                           closed_loop_duration, sweep, repeats)
