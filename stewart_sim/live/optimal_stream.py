"""The model-predictive cueing (optimal.py) live: telemetry samples in one at a time, the
platform's planned pose out at any time, the MPC stepped at its own rate in between.

    mpc = LiveOptimal(model, config, home, gravity, controller, options, synchronous=False)
    every loop period (1 kHz):
        mpc.push(t, specific_force, angular_velocity)    # each telemetry sample received
        q, qd, qdd = mpc.sample(t)                       # the pose to send now
    mpc.stats()                                          # SolveStats: the solve-time histogram
    mpc.close()                                          # (or `with LiveOptimal(...) as mpc:`)

Times are seconds on the caller's one clock, never decreasing; the first push or sample is the
MPC's time zero, its steps at t0 + k / options.rate (options.rate >= LIVE_RATE_MIN).

No preview: the future is unknown, so the window each MPC step is given is what has been
received, held over the horizon: the mean, over the last MPC step [t_k - dt, t_k], of the
received samples (linear between samples, the last one held; optimal.interval_means), minus
rest. `options.preview` is ignored. A vehicle at rest (specific force (0, 0, |g|), no rotation)
is zero deviation exactly, so the platform stays exactly at home: no false cue at rest.

Pipeline: the move flown on [t_k, t_k+1) is the first move of a QP started `lead` steps
before, at t_k-lead, from the state at t_k: the moves in between are fixed then (the current
plan's), so that state is their prediction; the window is the one received by t_k-lead. The
platform's states (pose and rates) are exactly those predicted; the model's perceived-error
states are advanced with the received mean over each step (not the true one, not known yet).
The first step flies rest. One solve is out at a time, so the MPC re-plans every `lead`
steps, and telemetry reaches the platform `lead` to 2 `lead` MPC steps later. In real time
`lead` is the most steps a solve took to come back over the last LEAD_WINDOW solves (1 to
steps - 1), unless fixed by `lead_steps`; synchronous, it is `lead_steps` or 1.

Solves do not run on the caller's thread in real time (synchronous=False): they run in a
worker process (forked at construction: construct before starting other threads). In a
thread they would stall the loop: OSQP's solve releases the GIL, but its update of the matrix
values (the refactorisation each step needs) holds it throughout, as do the linearisation's
numpy calls; measured with a 1 ms sleep loop beside a thread doing the shipped simulator's
50 Hz, 1 s horizon step on a loaded 2-core machine, the loop's longest gap was 29 ms beside
the update alone, 5.6 ms beside the solve alone. The loop's own work at an MPC step is the
mean, one state update and sending the state (SolveStats.tick_p99, tick_max); the prediction
over the lead is the worker's.
A result not back by the step it was made for is late (SolveStats.late): the steps until a
new plan fly the current plan's moves (as optimal_cueing does for an unsolved step), the late
result is dropped when it comes, the lead grows to what it took, and the next solve starts.
Unlike optimal_cueing, a plan flown to its end is not coasted past it at its last rates: the
next step stops the rates (the platform stays where the plan left it; SolveStats.stopped).
With synchronous=True (a simulated clock, tests) each solve runs inline when started and its
result waits for its step, never late, so a run is deterministic; real time flies the same
moves while no solve is late and the lead is the same.

Telemetry that is not finite, or older than the last sample, is refused (counted in
SolveStats.refused) without moving anything. Telemetry loss is not handled here: the window
holds the last sample; fading to neutral is the live loop's.
"""
from __future__ import annotations

import multiprocessing
import time
from collections import Counter, deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model

from stewart_sim.cueing.mpc_model import NP
from stewart_sim.cueing.optimal import (
    Move,
    OptimalStepper,
    Solution,
    StepperState,
    held_move,
    interval_means,
)
from stewart_sim.scene.cueing_config import CueingConfig, OptimalOptions

LIVE_RATE_MIN = 50.0       # Hz: the slowest MPC the live loop takes
WORKER_START_TIMEOUT = 30.0    # s: the forked worker's first word
WORKER_STOP_TIMEOUT = 5.0      # s, then it is terminated
BUFFER_MAX = 100_000       # telemetry samples kept when sample() is not called
LEAD_WINDOW = 20           # solves whose return times set the lead
STATS_WINDOW = 360_000     # solves and steps the percentiles keep: an hour at 100 Hz


class LiveOptimalError(StewartError, ValueError):
    """Bad input to the live MPC (its options, a time), or its worker failed."""


@dataclass(frozen=True)
class SolveStats:
    """The live MPC's solve-time histogram and its record. Times in s; a solve's wall time is
    the whole MPC step (linearisation, vectors and OSQP), `osqp_*` OSQP's own part. The
    percentiles, maxima and `over_deadline` are over the last STATS_WINDOW solves and steps,
    the counts over the whole run."""

    rate: float                  # Hz, MPC steps
    steps: int                   # MPC steps flown
    solves: int                  # solves returned (late ones included)
    wall_p50: float
    wall_p99: float
    wall_p999: float
    wall_max: float
    osqp_p50: float
    osqp_p99: float
    osqp_p999: float
    osqp_max: float
    iterations_p50: float
    iterations_max: int
    over_deadline: int           # solves whose wall time exceeded 1 / rate
    late: int                    # solves not back by the step they were made for
    status_counts: dict[str, int]   # OSQP's status of each returned solve
    tick_p99: float              # the caller's own work at an MPC step (with the solve when
    tick_max: float              # synchronous)
    refused: int                 # telemetry samples refused (not finite, out of order)
    lead_max: int                # the most steps ahead a solve was started
    stopped: int                 # steps flown past a plan's end (no new plan): rates stopped


def solve_stats(rate: float, steps: int, solves: Sequence[tuple[float, float, int]],
                statuses: Mapping[str, int], ticks: Sequence[float], late: int, refused: int,
                lead_max: int, stopped: int) -> SolveStats:
    """SolveStats of the solves' (wall time, OSQP time, iterations), their status counts and
    the per-step tick times."""
    record = np.array(solves, dtype=float).reshape(-1, 3) if solves else np.zeros((1, 3))
    tick = np.array(ticks) if ticks else np.zeros(1)
    wall, osqp_t, its = record.T

    def pct(a, p):
        return float(np.percentile(a, p))

    return SolveStats(rate, steps, sum(statuses.values()), pct(wall, 50), pct(wall, 99),
                      pct(wall, 99.9), float(wall.max()), pct(osqp_t, 50), pct(osqp_t, 99),
                      pct(osqp_t, 99.9), float(osqp_t.max()), pct(its, 50), int(its.max()),
                      int(np.sum(wall > 1.0 / rate)) if solves else 0, late, dict(statuses),
                      pct(tick, 99), float(tick.max()), refused, lead_max, stopped)


class LiveOptimal:
    """The optimal cueing without preview, stepped live: see the module doc."""

    def __init__(self, model: Model, config: CueingConfig, home, gravity,
                 controller: ControllerConfig | None, options: OptimalOptions, *,
                 synchronous: bool = False, lead_steps: int | None = None):
        if not options.rate >= LIVE_RATE_MIN:
            raise LiveOptimalError(f"live MPC: rate must be >= {LIVE_RATE_MIN:g} Hz, got "
                                   f"{options.rate!r}")
        self._stepper = OptimalStepper(model, config, home, gravity, controller=controller,
                                       options=options)
        self.dt, self.home = self._stepper.dt, self._stepper.home
        top = max(1, self._stepper.steps - 1)
        if lead_steps is not None and not (isinstance(lead_steps, int)
                                           and 1 <= lead_steps <= top):
            raise LiveOptimalError(f"live MPC: lead_steps must be an integer in 1..{top}, got "
                                   f"{lead_steps!r}")
        self._sync, self._fixed_lead, self._top = synchronous, lead_steps, top
        self._lead = lead_steps or 1
        self._t0: float | None = None
        self._k = 0                      # the next MPC step
        self._times: list[float] = []
        self._values: list[np.ndarray] = []
        self._move: tuple[float, Move] | None = None
        self._ready: tuple[int, Solution] | None = None   # a solution waiting for its step
        self._inflight: tuple[int, int] | None = None     # (step made for, step started at)
        self._took: list[int] = []       # steps each recent solve took to come back
        self._solves: deque[tuple[float, float, int]] = deque(maxlen=STATS_WINDOW)
        self._statuses: Counter[str] = Counter()
        self._ticks: deque[float] = deque(maxlen=STATS_WINDOW)
        self._late = self._refused = self._lead_max = self._stopped = 0
        self._age = self._stepper.steps   # moves flown from the current plan (none yet)
        self._planned = False             # a plan has been flown
        self._worker = self._conn = None
        if not synchronous:
            self._start_worker()

    def _start_worker(self) -> None:
        # forked: the worker starts with a copy of this stepper, QP built (a Model does not
        # pickle, so it could not be sent to a spawned one)
        ctx = multiprocessing.get_context("fork")
        self._conn, child = ctx.Pipe()
        self._worker = ctx.Process(target=_serve, daemon=True, name="live-mpc",
                                   args=(child, self._stepper))
        self._worker.start()
        child.close()
        if not self._conn.poll(WORKER_START_TIMEOUT) or self._recv() != "ready":
            self.close()
            raise LiveOptimalError("live MPC: the solver's worker did not start")

    def _recv(self):
        try:
            return self._conn.recv()
        except (EOFError, OSError) as exc:
            raise LiveOptimalError(f"live MPC: the solver's worker died ({exc})") from None

    def push(self, t: float, specific_force, angular_velocity) -> None:
        """One telemetry sample: specific force (3,) m/s^2 and angular velocity (3,) rad/s in
        the vehicle frame at time t. Refused (counted) when not finite or not after the last."""
        value = np.r_[np.asarray(specific_force, float).ravel(),
                      np.asarray(angular_velocity, float).ravel()]
        if (value.shape != (6,) or not np.isfinite(t) or not np.all(np.isfinite(value))
                or (self._times and t <= self._times[-1])):
            self._refused += 1
            return
        if self._t0 is None:
            self._t0 = float(t)
        self._times.append(float(t))
        self._values.append(value - self._stepper.rest)
        if len(self._times) > BUFFER_MAX:
            del self._times[:BUFFER_MAX // 2], self._values[:BUFFER_MAX // 2]

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The planned pose q, its rates qd and accelerations qdd (6,) at time t (running the
        MPC steps due by t first)."""
        if not np.isfinite(t):
            raise LiveOptimalError(f"live MPC: time must be finite, got {t!r}")
        if self._t0 is None:
            self._t0 = float(t)
        while self._t0 + self._k * self.dt <= t:   # bounded: t is finite
            clock = time.perf_counter()
            self._tick(self._t0 + self._k * self.dt)
            self._ticks.append(time.perf_counter() - clock)
        start, move = self._move
        dq, qd, qdd = held_move(move.dq, move.qd, move.qdd, max(t - start, 0.0))
        return self.home + dq, qd, qdd.copy()

    def _tick(self, tk: float) -> None:
        """MPC step k at tk: fly the solution made for it (or the current plan), advance the
        state over the step with the received mean, start the next solve if none is out."""
        k = self._k
        vehicle = self._received_mean(tk)
        if not self._sync:
            self._collect(k)
        solution = None
        if self._ready is not None and self._ready[0] == k:
            solution, self._ready = self._ready[1], None
        elif self._inflight is not None and self._inflight[0] == k:
            self._late += 1
        fresh = solution is not None and solution.states is not None
        if self._age >= self._stepper.steps and self._planned and not fresh:
            self._stopped += 1
        self._planned = self._planned or fresh
        move, self._age = _fly(self._stepper, solution, vehicle, self._age)
        self._move = (tk, move)
        self._k = k + 1
        if self._inflight is None and self._ready is None:
            self._start(k, vehicle)

    def _start(self, k: int, vehicle: np.ndarray) -> None:
        """Start the solve for step k + lead (see _solve_ahead), in the worker or inline."""
        lead = self._lead
        self._lead_max = max(self._lead_max, lead)
        if self._sync:
            now = self._stepper.state
            solution = _solve_ahead(self._stepper, now, self._age, lead, vehicle)
            self._stepper.state = now
            self._record(solution)
            self._ready = (k + lead, solution)
        else:
            self._conn.send((k + lead, self._stepper.state, self._age, lead, vehicle))
            self._inflight = (k + lead, k)

    def _collect(self, k: int) -> None:
        """Take the worker's result if it is back: kept for its step, dropped if that step is
        past; the lead follows the steps solves take."""
        if not (self._inflight is not None and self._conn.poll()):
            return
        tag, solution = self._recv()
        took = k - self._inflight[1]
        self._inflight = None
        self._record(solution)
        self._took = (self._took + [took])[-LEAD_WINDOW:]
        if self._fixed_lead is None:
            self._lead = min(max(self._took), self._top)
        if tag >= k:
            self._ready = (tag, solution)

    def _received_mean(self, tk: float) -> np.ndarray:
        """The mean deviation from rest received over [tk - dt, tk]; rest when none; the
        samples before the last one at or before tk are dropped."""
        if not self._times:
            return np.zeros(6)
        t, y = np.array(self._times), np.array(self._values)
        mean = interval_means(t, y, np.array([tk - self.dt, tk]))[0]
        first = max(int(np.searchsorted(t, tk, side="right")) - 1, 0)
        del self._times[:first], self._values[:first]
        return mean

    def stats(self) -> SolveStats:
        """The solve-time histogram and the record so far."""
        return solve_stats(float(1.0 / self.dt), self._k, self._solves, self._statuses,
                           self._ticks, self._late, self._refused, self._lead_max,
                           self._stopped)

    def _record(self, solution: Solution) -> None:
        self._solves.append((solution.wall_time, solution.solve_time, solution.iterations))
        self._statuses[solution.status] += 1

    def close(self) -> None:
        """Stop the worker (nothing in synchronous mode)."""
        if self._worker is None:
            return
        try:
            self._conn.send(None)
        except (OSError, ValueError):
            pass
        self._worker.join(WORKER_STOP_TIMEOUT)
        if self._worker.is_alive():
            self._worker.terminate()
            self._worker.join(WORKER_STOP_TIMEOUT)
        self._conn.close()
        self._worker = None

    def __enter__(self) -> LiveOptimal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _fly(stepper: OptimalStepper, solution: Solution | None, vehicle: np.ndarray, age: int
         ) -> tuple[Move, int]:
    """OptimalStepper.apply, and the age of the plan flown (moves flown from it). A plan flown
    past its end (age >= steps) is not coasted at its last rates, as its zero padding would:
    the step's acceleration stops the rates over the step, so the platform stays where the
    plan left it until a new plan comes."""
    if solution is not None and solution.states is not None:
        return stepper.apply(solution, vehicle), 1
    if age >= stepper.steps:
        s = stepper.state
        U = s.U.copy()
        U[0] = 0.0 - s.x[6:NP] / stepper.dt
        stepper.state = StepperState(s.x, s.X, U)
    return stepper.apply(None, vehicle), age + 1


def _solve_ahead(stepper: OptimalStepper, state: StepperState, age: int, lead: int,
                 vehicle: np.ndarray) -> Solution:
    """The solve for the step `lead` steps after `state`'s, from the state predicted there on
    the current plan, of age `age` (the moves in between are fixed: they are the plan's, or
    _fly's stop), the received mean `vehicle` held over the horizon. Leaves the stepper at
    that predicted state."""
    stepper.state = state
    for _ in range(lead - 1):
        age = _fly(stepper, None, vehicle, age)[1]
    return stepper.solve(np.repeat(vehicle[None], stepper.steps + 1, axis=0))


def _serve(conn, stepper: OptimalStepper) -> None:
    """The worker: its copy of the stepper (QP and warm start); each request (k, state, age,
    lead, vehicle) is answered (k, _solve_ahead's Solution); None stops it."""
    conn.send("ready")
    while True:   # ends on None or when the parent goes
        try:
            request = conn.recv()
        except (EOFError, OSError):
            return
        if request is None:
            return
        k, state, age, lead, vehicle = request
        conn.send((k, _solve_ahead(stepper, state, age, lead, vehicle)))
