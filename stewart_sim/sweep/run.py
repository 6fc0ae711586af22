"""Running a design sweep on Dask: all cores of this machine (a LocalCluster of worker
processes, one thread each) or a Dask distributed cluster (`scheduler` = "tcp://HOST:PORT").

Points go out in tasks of `batch` points (sweep_eval.evaluate_batch); each finished task's rows
are written to a chunk file at once (stewart_sim/sweep/chunks.py), so an interruption keeps every
finished row and a rerun computes only the points not yet in the directory: the rows of the
chunks that pass their checks (the sweep's fingerprint, their checksum, known points once each,
plausible results); a chunk refused is set aside and its points are computed again. The table
is written from these rows only, checked before anything is merged. A worker that dies takes its
running tasks with it; the scheduler runs them again elsewhere, and a task's rows are written
once, when its future completes. With `adaptive` N, the rounds of refinement (their points
picked from the rows: stewart_sim/sweep/adaptive.py) run on the same cluster after the grid.
"""
from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from controller.config import controller_config
from stewart_fmu.errors import SceneError, SceneKeyError, SweepError
from stewart_fmu.io import read_trajectory
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from stewart_sim.progress import Progress
from stewart_sim.sweep.adaptive import REFINEMENT, Refinement, check_adaptive
from stewart_sim.sweep.chunks import ChunkRules, chunk_rules, resume_rows, write_chunk
from stewart_sim.sweep.cluster import dask_client
from stewart_sim.sweep.evaluate import (EvalSpec, columns, evaluate_batch, has_drive, point_label,
                                        point_model)
from stewart_sim.sweep.grid import GridSpec
from stewart_sim.sweep.table import merge, open_sweep


@dataclass(frozen=True)
class SweepSummary:
    """What a run of the sweep did."""

    table: Path
    points: int          # in the sweep
    resumed: int         # already in the directory when this run started
    computed: int        # by this run
    failed: int          # rows with status "error" in the table
    workers: int
    wall: float          # s, this run's evaluation (cluster start-up excluded)
    refused: int = 0     # chunk files set aside on resume (their points computed again)
    added: int = 0       # points added by refinement (sweep --adaptive), in `points`

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
              adaptive: int = 0) -> SweepSummary:
    """Run (or resume) the sweep into `out` and merge its table; see the module doc.
    `notice` gets one line for each chunk file refused on resume. `adaptive` N: then N more
    points where the outcome changes (stewart_sim/sweep/adaptive.py), the table with the
    column `refinement`."""
    spec = eval_spec(scene, grid)
    check_adaptive(grid, adaptive, has_drive(spec.scene))
    points = grid.points()
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

    rows = resume_rows(out, rules, refuse)
    resumed = len(rows)
    refine = Refinement(grid, fp, cols, has_drive(spec.scene), adaptive) if adaptive else None
    runner = _Runner(scheduler, workers, spec, grid.batch, len(points) + adaptive, progress,
                     timeout)
    try:
        with runner.stack:
            computed = runner([p for p in points if p[0] not in rows], out, rules, rows)
            if refine is not None:
                refine.run(rows, out, runner, refuse)
    finally:
        wall = time.monotonic() - runner.start
        if refine is None:
            merge(out, cols, rows)
        else:
            merge(out, (*cols, REFINEMENT), refine.table_rows(rows))
    table = out / "sweep.csv"
    failed = sum(1 for r in rows.values() if r[cols.index("status")] != "ok")
    added = len(refine.rounds) if refine is not None else 0
    if len(rows) != len(points) + added:
        raise SweepError(None, f"{table}: {len(rows)} rows for {len(points) + added} points")
    if refine is not None:
        resumed, computed = resumed + refine.resumed, computed + refine.computed
    return SweepSummary(table, len(points) + added, resumed, computed, failed, runner.workers,
                        wall, len(refused), added)


class _Runner:
    """Evaluates points on the cluster, started for the first points to compute and closed
    with `stack`; `start`: when it was up (the wall time excludes the start-up)."""

    def __init__(self, scheduler: str | None, workers: int | None, spec: EvalSpec, batch: int,
                 total: int, progress: Progress | None, timeout: float | None):
        self.scheduler, self.n, self.spec, self.batch = scheduler, workers, spec, batch
        self.total, self.progress, self.timeout = total, progress, timeout
        self.stack, self.client, self.workers, self.start = ExitStack(), None, 0, time.monotonic()

    def __call__(self, todo: Sequence[tuple[int, Mapping[str, Any]]], out: Path,
                 rules: ChunkRules, rows: dict[int, list[str]]) -> int:
        """Evaluate `todo` into chunk files under `out` and `rows`; returns the points done."""
        if not todo:
            return 0
        if self.client is None:
            self.client = self.stack.enter_context(dask_client(self.scheduler, self.n))
            self.workers = len(self.client.scheduler_info()["workers"])
            self.start = time.monotonic()
        batches = [todo[i:i + self.batch] for i in range(0, len(todo), self.batch)]
        return _run_batches(self.client, self.spec, batches, out, rules, rows, self.total,
                            self.progress, self.timeout)


def _run_batches(client, spec: EvalSpec, batches: Sequence[list], out: Path,
                 rules: ChunkRules, rows: dict[int, list[str]], total: int,
                 progress: Progress | None, timeout: float | None) -> int:
    """Submit every batch, write each task's rows as it completes (into a chunk file and
    `rows`); returns the points done."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    futures = [client.submit(evaluate_batch, spec, b, pure=False) for b in batches]
    pending, resumed = set(futures), len(rows)
    try:
        for fut in as_completed(futures, timeout=timeout):
            rows.update(write_chunk(out, rules, fut.result()))
            pending.discard(fut)
            if progress is not None:
                progress.update("sweep", len(rows), total, unit="points")
    except (KilledWorker, FutureCancelledError) as exc:
        raise SweepError(None, f"a task was lost on the cluster: {exc}") from None
    except TimeoutError:
        raise SweepError(None, f"the sweep took longer than {timeout} s") from None
    finally:
        for fut in [f for f in pending if f.status == "finished"]:  # finished meanwhile: keep
            rows.update(write_chunk(out, rules, fut.result()))
        client.cancel(list(pending))
    return len(rows) - resumed

