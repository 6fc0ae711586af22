"""Running a design sweep on Dask: all cores of this machine (a LocalCluster of worker
processes, one thread each) or a Dask distributed cluster (`scheduler` = "tcp://HOST:PORT").

Points go out in tasks (evaluate_task) sized to a target duration from the measured cost of a
point (stewart_sim/studies/sweep/batching.py), a few tasks per worker at a time. A task is the ids
of its points: the points themselves, the evaluation's settings and the chunks' rules go to every
worker once (a TaskContext, scattered), and a worker returns its rows as a chunk file's text,
checked against the rules (stewart_sim/studies/sweep/chunks.py); each finished task's text is
written to a chunk file at once, so an interruption keeps every finished row and a rerun computes
only the points not yet in the directory: the rows of the chunks that pass their checks (the sweep's
fingerprint, their checksum, known points once each, plausible results); a chunk refused is set
aside and its points are computed again. The table is merged from the chunk files, read again
and checked again, in point order; no more than a task's rows are held at once, whatever the
sweep's size (the points are the grid's: a Latin hypercube's unit sample, 8 bytes per axis and
point, is what a worker holds of them). A worker that dies
takes its running tasks with it; the scheduler runs them again elsewhere, and a task's rows are
written once, when its future completes. With `adaptive` N, the rounds of refinement (their
points picked from the grid's rows, read back from its chunk files:
stewart_sim/studies/sweep/adaptive.py) run in the same sized tasks on the same cluster after the
grid, and the table merges the grid's and the rounds' chunk files with the column `refinement`.
"""
from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

from controller.config import controller_config
from stewart_fmu.errors import SceneError, SceneKeyError, SweepError
from stewart_fmu.io import read_trajectory
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.sweep.adaptive import REFINEMENT, Refinement, check_adaptive
from stewart_sim.studies.sweep.batching import BatchSizer, TaskCosts
from stewart_sim.studies.sweep.chunks import (ChunkRules, Ledger, check_task_text, checked_cells,
                                              chunk_rules, chunk_text, ledger_rows, merge_chunks,
                                              resume_ledger, write_chunk_text)
from stewart_sim.studies.sweep.cluster import dask_client
from stewart_sim.studies.sweep.evaluate import (EvalSpec, TrajectoryCache, columns, evaluate_batch,
                                                has_drive, point_label, point_model)
from stewart_sim.studies.sweep.grid import GridSpec
from stewart_sim.studies.sweep.result_table import open_sweep

WORKERS_POLL = 2.0       # s between two looks at the cluster's workers (they may come and go)


@dataclass(frozen=True)
class SweepSummary:
    """What a run of the sweep did."""

    table: Path
    points: int          # in the sweep
    resumed: int         # already in the directory when this run started
    computed: int        # by this run
    failed: int          # rows with status "error" in the table
    workers: int
    wall: float          # s, this run's evaluation (the cluster's start and close excluded)
    refused: int = 0     # chunk files set aside on resume (their points computed again)
    added: int = 0       # points added by refinement (sweep --adaptive), in `points`
    cpu: float = 0.0     # s of this process's CPU over `wall`: the client's share (sending
                         # tasks, checking and writing rows), and a local cluster's scheduler

    @property
    def rate(self) -> float:
        """Points per second of this run."""
        return self.computed / self.wall if self.wall > 0 else float("nan")


def eval_spec(scene: Path, grid: GridSpec) -> EvalSpec:
    """The shared part of every task: base scene, settings and trajectory files, checked."""
    data = read_scene_dict(scene)
    base = scene_from_dict(data, str(scene))
    if grid.evaluation == "closed_loop":
        controller_config(base)     # the scene's own [controller]: its file is at fault
    if grid.evaluation == "modes" and base.stiffness is None:
        raise SceneError("stiffness", "the modes evaluation needs the scene's [stiffness] "
                         "(each leg's axial stiffness, N/m)", str(scene))
    files = {}
    names = {grid.trajectory.file} | {v for a in grid.axes if a.key == "trajectory.file"
                                      for v in a.grid_values()}
    for name in sorted(n for n in names if n is not None):
        t, q, qd, qdd = read_trajectory(_beside(grid.source, name))
        files[name] = (t, q, qd, qdd)
    return EvalSpec(grid.evaluation, data, grid.trajectory, grid.envelope, files, str(scene))


def _beside(source: str | None, name: str) -> Path:
    """A path from GRID.toml: relative to the grid file's directory."""
    p = Path(name)
    return p if p.is_absolute() or source is None else Path(source).parent / p


def check_first_point(spec: EvalSpec, point: Mapping[str, Any], grid: GridSpec | None = None
                      ) -> None:
    """The first point's scene (and controller table) must take the grid's keys: a key the
    scene cannot take (e.g. legs.* on a scene without [legs], a value out of the key's range:
    SceneKeyError) fails here, naming the grid, the point and the key, before anything runs.
    A relation between keys the point breaks (leg_max not above leg_min, the home pose past
    the stroke) is not refused: the point becomes a row with its error (evaluate_point)."""
    try:
        model = point_model(spec, point)
        if spec.evaluation == "closed_loop":
            controller_config(model)
    except SceneKeyError as exc:
        where = f"{grid.source}: " if grid is not None and grid.source else ""
        raise SceneKeyError(exc.key, exc.reason, f"{where}{point_label(0, point)}") from None
    except SceneError:
        return      # a relation this point breaks: its row says so


def fingerprint(spec: EvalSpec, grid: GridSpec) -> str:
    """The sweep's identity: grid, scene and the trajectory files' contents."""
    files = {k: [a.tolist() for a in v] for k, v in spec.files.items()}
    return grid.fingerprint({"scene": spec.scene, "files": files})


def run_sweep(scene: Path, grid: GridSpec, out: Path, scheduler: str | None = None,
              workers: int | None = None, progress: Progress | None = None,
              timeout: float | None = None, notice: Callable[[str], None] | None = None,
              dashboard: Callable[[str], None] | None = None, adaptive: int = 0
              ) -> SweepSummary:
    """Run (or resume) the sweep into `out` and merge its table; see the module doc.
    `notice` gets one line for each chunk file refused on resume; `dashboard` the address of
    the scheduler's dashboard once the cluster is up (when it serves one). `adaptive` N: then
    N more points where the outcome changes (stewart_sim/studies/sweep/adaptive.py), the table with
    the column `refinement`."""
    spec = eval_spec(scene, grid)
    check_adaptive(grid, adaptive, has_drive(spec.scene))
    points = grid.point_sequence()
    check_first_point(spec, points[0][1], grid)
    cols = columns(grid.evaluation, grid.keys)
    fp = fingerprint(spec, grid)
    open_sweep(out, fp, cols, len(points))
    rules = chunk_rules(fp, cols, points, grid.batch, has_drive(spec.scene))
    refused: list[str] = []

    def refuse(line: str) -> None:
        refused.append(line)
        if notice is not None:
            notice(line)

    ledger = resume_ledger(out, rules, refuse)
    resumed = ledger.count
    refine = Refinement(grid, fp, cols, has_drive(spec.scene), adaptive) if adaptive else None
    runner = _Runner(scheduler, workers, spec, grid, fp, len(points) + adaptive, progress,
                     timeout, dashboard)
    try:
        with runner.stack:
            computed = runner(points, out, rules, ledger)
            if refine is not None:   # the grid's rows read back: cheap at refinement's sizes
                refine.run(ledger_rows(ledger, rules), out, runner, refuse)
    finally:
        wall = (runner.end or time.monotonic()) - runner.start
        cpu = (runner.end_cpu or time.process_time()) - runner.start_cpu
        if refine is None:
            merged, failed = merge_chunks(out, rules, ledger)
        else:
            merged, failed = merge_chunks(out, rules, ledger, refine.parts, REFINEMENT)
    table = out / "sweep.csv"
    added = len(refine.rounds) if refine is not None else 0
    if merged != len(points) + added:
        raise SweepError(None, f"{table}: {merged} rows for {len(points) + added} points")
    if refine is not None:
        resumed, computed = resumed + refine.resumed, computed + refine.computed
    return SweepSummary(table, len(points) + added, resumed, computed, failed, runner.workers,
                        wall, len(refused), added, cpu)


class _Runner:
    """Evaluates points on the cluster in sized tasks (_run_tasks), the cluster started for the
    first points to compute and closed with `stack`; the grid and the refinement rounds share
    it, its task sizer and the measured cost of a point. `start`: when the cluster was up;
    `end`: when the last part's tasks were done (the wall time excludes the cluster's start and
    its close, which take about 0.4 s each on a local cluster); `start_cpu`, `end_cpu`: this
    process's CPU time then."""

    def __init__(self, scheduler: str | None, workers: int | None, spec: EvalSpec,
                 grid: GridSpec, sweep: str, total: int, progress: Progress | None,
                 timeout: float | None, dashboard: Callable[[str], None] | None):
        self.scheduler, self.n, self.spec, self.sweep = scheduler, workers, spec, sweep
        self.total, self.progress, self.timeout, self.dashboard = (total, progress, timeout,
                                                                   dashboard)
        self.sizer, self.costs = BatchSizer(grid.batch, fixed=not grid.sized), TaskCosts()
        self.stack, self.client, self.workers, self.start = ExitStack(), None, 0, time.monotonic()
        self.start_cpu = time.process_time()
        self.before = 0          # points of the earlier parts (grid, rounds): the progress
        self.end: float | None = None
        self.end_cpu: float | None = None

    def __call__(self, points: Sequence[tuple[int, Mapping[str, Any]]], out: Path,
                 rules: ChunkRules, ledger: Ledger) -> int:
        """Evaluate the points not in `ledger` into chunk files under `out`, recorded in the
        ledger; returns the points done."""
        try:
            if ledger.count >= len(points):
                return 0
            if self.client is None:
                self.client = self.stack.enter_context(dask_client(self.scheduler, self.n))
                self.workers = len(self.client.scheduler_info()["workers"])
                # the workers import the evaluation now, not in a task, and so does the
                # scheduler (it unpickles each task, whose function is this module's), which
                # takes a second and more in a `dask scheduler` process of its own
                self.client.run(_ready)
                self.client.run_on_scheduler(_ready)
                link = _dashboard_link(self.client)
                if self.dashboard is not None and link is not None:
                    self.dashboard(link)
                self.start, self.start_cpu = time.monotonic(), time.process_time()
            return _run_tasks(self.client, self.spec, points, out, rules, ledger, self)
        finally:
            self.before += ledger.count
            self.end, self.end_cpu = time.monotonic(), time.process_time()


@dataclass(frozen=True)
class TaskContext:
    """What every task of one part of a sweep (the grid, a refinement round) shares, sent to
    each worker once: the evaluation's settings, the points (point k at k - the rules' first
    id) and the rules of their chunks."""

    spec: EvalSpec
    points: Sequence[tuple[int, Mapping[str, Any]]]
    rules: ChunkRules


def evaluate_task(context: TaskContext, ids: np.ndarray, sweep: str = ""
                  ) -> tuple[list[int], bytes, float, bool]:
    """One task on a worker: the points `ids` evaluated, their rows checked and made into a
    chunk file's text (chunks.checked_cells, chunk_text); returns the ids, the text, the seconds
    the evaluation took there, and whether it was this worker's first task of the sweep `sweep`
    (a fingerprint: the worker keeps the trajectories of that sweep's geometries from task to
    task, and drops them for another)."""
    global _WORKER_CACHE
    begin = time.perf_counter()
    first = _WORKER_CACHE[0] != sweep or not sweep
    if first:
        _WORKER_CACHE = (sweep, TrajectoryCache())
    base = context.rules.first
    points = [context.points[pid - base] for pid in ids.tolist()]
    rows = evaluate_batch(context.spec, points, _WORKER_CACHE[1])
    seconds = time.perf_counter() - begin
    cells = checked_cells(context.rules, rows)
    return list(cells), chunk_text(context.rules, cells), seconds, first


_WORKER_CACHE: tuple[str, TrajectoryCache] = ("", TrajectoryCache())   # see evaluate_task


def _ready() -> None:
    """Run on every worker and the scheduler at start-up: unpickling it imports this module,
    and with it the evaluation's (controller design, closed loop), so that no task's time
    includes imports."""


def _dashboard_link(client) -> str | None:
    """The scheduler's dashboard (/status), None when it serves none."""
    if "dashboard" not in client.scheduler_info().get("services", {}):
        return None
    return client.dashboard_link


def _run_tasks(client, spec: EvalSpec, points: Sequence[tuple[int, Mapping[str, Any]]],
               out: Path, rules: ChunkRules, ledger: Ledger, runner: _Runner) -> int:
    """Send the points not in the ledger in tasks sized by the runner's sizer, a few per worker
    at a time (their TaskContext scattered to every worker first); write each task's rows as it
    completes (a chunk file, recorded in the ledger); returns the points done."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    sizer, costs, progress, timeout = runner.sizer, runner.costs, runner.progress, runner.timeout
    todo: Iterator[int] = (i for i in range(len(points)) if not ledger.done[i])
    left, resumed = len(points) - ledger.count, ledger.count
    context = client.scatter(TaskContext(spec, points, rules), broadcast=True, hash=False)
    pending: dict = {}     # future: the ids it was sent
    finished = as_completed(timeout=timeout)
    workers, looked = _workers(client), time.monotonic()

    def submit() -> int:
        ids = np.fromiter(islice(todo, sizer.size(costs.per_point, left, workers)),
                          dtype=np.int64) + rules.first
        if len(ids):
            fut = client.submit(evaluate_task, context, ids, runner.sweep, pure=False)
            pending[fut] = ids
            finished.add(fut)
        return len(ids)

    def record(fut) -> None:
        got, text, seconds, first = fut.result()
        check_task_text(rules, pending.pop(fut).tolist(), got, text)
        ledger.add(write_chunk_text(out, rules, got, text), got)
        costs.add(len(got), seconds, first)

    try:
        for _ in range(sizer.in_flight(workers)):
            left -= submit()
        for fut in finished:
            record(fut)
            if time.monotonic() - looked > WORKERS_POLL:
                workers, looked = _workers(client), time.monotonic()
            while left and len(pending) < sizer.in_flight(workers):
                left -= submit()
            if progress is not None:
                progress.update("sweep", runner.before + ledger.count, runner.total,
                                unit="points", rate=True)
    except (KilledWorker, FutureCancelledError) as exc:
        raise SweepError(None, f"a task was lost on the cluster: {exc}") from None
    except TimeoutError:
        raise SweepError(None, f"the sweep took longer than {timeout} s") from None
    finally:
        for fut in [f for f in pending if f.status == "finished"]:  # finished meanwhile: keep
            record(fut)
        client.cancel(list(pending))
        client.cancel([context])
    return ledger.count - resumed


def _workers(client) -> int:
    """The cluster's workers now (at least 1: tasks wait for one to join)."""
    return max(1, len(client.scheduler_info()["workers"]))
