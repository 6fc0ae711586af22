"""Running a design sweep on Dask: all cores of this machine (a LocalCluster of worker
processes, one thread each) or a Dask distributed cluster (`scheduler` = "tcp://HOST:PORT").

Points go out in tasks of `batch` points (sweep_eval.evaluate_batch); each finished task's rows
are written to a chunk file at once (sweep_table), so an interruption keeps every finished row
and a rerun computes only the points not yet in the directory. A worker that dies takes its
running tasks with it; the scheduler runs them again elsewhere, and a task's rows are written
once, when its future completes.
"""
from __future__ import annotations

import logging
import os
import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from controller.config import controller_config
from stewart_fmu.errors import SceneError, SceneKeyError, SweepError
from stewart_fmu.io import read_trajectory
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from stewart_sim.progress import Progress
from stewart_sim.sweep.evaluate import EvalSpec, columns, evaluate_batch, point_label, point_model
from stewart_sim.sweep.grid import GridSpec
from stewart_sim.sweep.table import chunk_rows, merge, open_sweep, write_chunk

CONNECT_TIMEOUT = 30.0   # s to reach a scheduler or start the local cluster


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
              timeout: float | None = None) -> SweepSummary:
    """Run (or resume) the sweep into `out` and merge its table; see the module doc."""
    spec = eval_spec(scene, grid)
    points = grid.points()
    check_first_point(spec, points[0][1], grid)
    cols = columns(grid.evaluation, grid.keys)
    open_sweep(out, fingerprint(spec, grid), cols, len(points))
    done = set(chunk_rows(out, cols))
    todo = [p for p in points if p[0] not in done]
    batches = [todo[i:i + grid.batch] for i in range(0, len(todo), grid.batch)]
    computed, start, n_workers = 0, time.monotonic(), 0
    try:
        if batches:
            with ExitStack() as stack:
                client = stack.enter_context(_client(scheduler, workers))
                n_workers = len(client.scheduler_info()["workers"])
                start = time.monotonic()
                computed = _run_batches(client, spec, batches, out, cols, len(done),
                                        len(points), progress, timeout)
    finally:
        wall = time.monotonic() - start
        rows = merge(out, cols)
    table = out / "sweep.csv"
    failed = sum(1 for r in chunk_rows(out, cols).values() if r[cols.index("status")] != "ok")
    if rows != len(points):
        raise SweepError(None, f"{table}: {rows} rows for {len(points)} points")
    return SweepSummary(table, len(points), len(done), computed, failed, n_workers, wall)


def _client(scheduler: str | None, workers: int | None):
    """A dask.distributed Client on the scheduler, or on a new local cluster of processes."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise SweepError(None, f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=":0", silence_logs=logging.ERROR)
    return _OwnedClient(Client(cluster, timeout=CONNECT_TIMEOUT), cluster)


class _OwnedClient:
    """A client that closes its local cluster with it (context manager)."""

    def __init__(self, client, cluster):
        self.client, self.cluster = client, cluster

    def __enter__(self):
        return self.client

    def __exit__(self, *exc) -> None:
        self.client.close()
        self.cluster.close()


def _run_batches(client, spec: EvalSpec, batches: Sequence[list], out: Path,
                 cols: Sequence[str], resumed: int, total: int, progress: Progress | None,
                 timeout: float | None) -> int:
    """Submit every batch, write each task's rows as it completes; returns the points done."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    futures = [client.submit(evaluate_batch, spec, b, pure=False) for b in batches]
    pending, done = set(futures), resumed
    try:
        for fut in as_completed(futures, timeout=timeout):
            rows = fut.result()
            write_chunk(out, cols, rows)
            pending.discard(fut)
            done += len(rows)
            if progress is not None:
                progress.update("sweep", done, total, unit="points")
    except (KilledWorker, FutureCancelledError) as exc:
        raise SweepError(None, f"a task was lost on the cluster: {exc}") from None
    except TimeoutError:
        raise SweepError(None, f"the sweep took longer than {timeout} s") from None
    finally:
        for fut in [f for f in pending if f.status == "finished"]:  # finished meanwhile: keep
            write_chunk(out, cols, fut.result())
        client.cancel(list(pending))
    return done - resumed

