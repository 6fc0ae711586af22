"""Points batched per task: the batch sizer's arithmetic on given costs, the same rows however
the points are grouped into tasks (and equal to the inverse dynamics computed point by point),
the points made on demand equal to the list, the merge of chunks whose points interleave, and a
sized sweep resumed after losing some of its chunks equal to the uninterrupted one."""
from __future__ import annotations

import math
import os
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import SweepError
from stewart_sim.cli import main
from stewart_sim.shell.progress import rate_text
from stewart_sim.studies.sweep.batching import (MIN_SECONDS, PROBE, TARGET_SECONDS, BatchSizer,
                                                TaskCosts)
from stewart_sim.studies.sweep.chunks import (check_task_text, checked_cells, chunk_rules,
                                              chunk_text, merge_chunks, resume_ledger, write_chunk)
from stewart_sim.studies.sweep.cluster import LOCAL_CLUSTER, dask_client, dask_environment
from stewart_sim.studies.sweep.dask_run import (TaskContext, eval_spec, evaluate_task, fingerprint,
                                                run_sweep)
from stewart_sim.studies.sweep.evaluate import (LEGS, columns, evaluate_batch, has_drive,
                                                point_model, point_trajectory, trajectory)
from stewart_sim.studies.sweep.grid import MAX_BATCH, grid_from_dict, load_grid
from stewart_sim.studies.sweep.result_table import CHUNKS, csv_text, open_sweep

distributed = pytest.importorskip("distributed")

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
WAIT = 120.0  # s: the bound on every wait for a cluster
# Two strokes (two trajectories, two regressors), Coulomb friction, a point the scene rejects.
INVERSE = """
evaluation = "inverse"
[trajectory]
duration = 0.3
[axes]
"geometry.leg_max" = [0.18, 0.19]
"platform.mass" = [0.5, 2.0, -1.0]
"friction.coulomb" = [0.0, 0.7]
"drive.gear_ratio" = [10.0, 30.0]
"""
ENVELOPE = """
evaluation = "envelope"
[envelope]
x = [-0.02, 0.02]
points = 3
[axes]
"platform.mass" = [0.5, 1.0, 1.5]
"""


def _grid(text: str):
    return grid_from_dict(tomllib.loads(text))


# --- the sizer's arithmetic --------------------------------------------------------------------

def test_tasks_are_sized_to_the_target_duration_from_the_cost_of_a_point():
    s = BatchSizer(MAX_BATCH)
    assert s.size(None, 1_000_000, 2) == PROBE                  # no cost measured yet
    assert s.size(0.001, 1_000_000, 2) == math.floor(TARGET_SECONDS / 0.001) == 300
    assert s.size(0.15, 1_000_000, 2) == 2                      # a closed-loop point
    assert s.size(1.0, 1_000_000, 2) == 1                       # a point longer than a task
    assert s.size(1e-7, 1_000_000, 2) == MAX_BATCH              # the chunk file's bound
    assert s.size(0.0, 1_000_000, 2) == MAX_BATCH
    assert s.size(0.001, 0, 2) == 0


def test_the_last_tasks_shrink_so_that_workers_finish_together():
    s = BatchSizer(MAX_BATCH)
    # no more than a quarter of the remaining points per worker ...
    assert s.size(0.001, 800, 2) == math.ceil(800 / (2 * 4)) == 100
    # ... unless that is less than a task of MIN_SECONDS
    assert s.size(0.001, 40, 2) == math.ceil(MIN_SECONDS / 0.001) == 20
    assert s.size(0.001, 7, 2) == 7                              # never more than remain
    assert s.size(0.001, 800, 1) == 300                          # one worker: nothing to balance
    # a sweep planned at a constant cost: every point once, the sizes never growing at the end
    sizes, left = [], 10_000
    while left:
        sizes.append(s.size(0.001, left, 4))
        left -= sizes[-1]
    assert sum(sizes) == 10_000 and sizes[0] == 300 and sizes[-1] <= 20
    assert all(a >= b for a, b in zip(sizes[20:], sizes[21:]))


def test_a_grid_that_gives_batch_gets_tasks_of_that_size():
    s = BatchSizer(4, fixed=True)
    assert [s.size(c, left, 2) for c, left in ((None, 10), (0.5, 6), (1e-6, 3))] == [4, 4, 3]
    assert _grid(INVERSE).sized and _grid(INVERSE).batch == MAX_BATCH
    given = _grid('batch = 4\n' + INVERSE)
    assert given.batch == 4 and not given.sized


def test_the_cost_of_a_point_leaves_out_each_workers_first_task():
    costs = TaskCosts()
    assert costs.per_point is None
    costs.add(2, 0.8, first=True)                     # a worker's first task: trajectories
    assert costs.per_point == pytest.approx(0.4)      # the only measure yet
    costs.add(100, 0.1)
    costs.add(300, 0.3)
    assert costs.per_point == pytest.approx(0.001)    # the first task left out
    costs.add(1, 0.2)                                 # a small last task, preempted
    assert costs.per_point == pytest.approx(0.6 / 401)


def test_the_progress_line_gives_a_rate_and_the_time_left():
    assert rate_text(100, 2.0, 300, "points") == ", 50 points/s, about 6 s left"
    assert rate_text(100, 2.0, 30_000, "points") == ", 50 points/s, about 10 min left"
    assert rate_text(100, 2.0, None, "points") == ", 50 points/s"
    assert rate_text(0, 2.0, 300, "points") == ""


# --- the same rows, however the points are grouped ---------------------------------------------

@pytest.mark.parametrize("text", [INVERSE, ENVELOPE], ids=["inverse", "envelope"])
def test_batching_does_not_change_the_rows(text):
    grid = _grid(text)
    spec, points = eval_spec(SCENE, grid), grid.points()
    cols = columns(grid.evaluation, grid.keys)
    whole = csv_text(cols, evaluate_batch(spec, points))
    rng = np.random.default_rng(3)
    for _ in range(3):   # random cuts into tasks, points of one trajectory split among them
        cuts = sorted(rng.choice(np.arange(1, len(points)), size=min(5, len(points) - 1),
                                 replace=False))
        rows = [r for a, b in zip([0, *cuts], [*cuts, len(points)])
                for r in evaluate_batch(spec, points[a:b])]
        assert csv_text(cols, rows) == whole
    alone = [r for p in points for r in evaluate_batch(spec, [p])]
    assert csv_text(cols, alone) == whole


def test_a_batch_of_points_equals_the_inverse_dynamics_point_by_point():
    """sigma = Y pi with the regressor shared by the points of one trajectory: the peaks are
    those of stewart_fmu.dynamics.inverse_dynamics at each point's own model, to rounding."""
    grid = _grid(INVERSE)
    spec = eval_spec(SCENE, grid)
    rows = evaluate_batch(spec, grid.points())
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == 16 and len(rows) == 24
    for row in ok:
        values = {k: row[k] for k in grid.keys}
        model = point_model(spec, values)
        traj = trajectory(spec, model, point_trajectory(spec, values), 1000.0)
        peak = np.max(np.abs(inverse_dynamics(model, traj.q, traj.qd, traj.qdd)), axis=0)
        got = np.array([row[k] for k in LEGS])
        assert np.allclose(got, peak, rtol=1e-12, atol=0), (values, got - peak)
        assert row["torque_max"] == pytest.approx(
            peak.max() * model.drive.pinion_radius / model.drive.gear_ratio, rel=1e-12)


def test_points_made_on_demand_are_the_list():
    for text in (INVERSE, """evaluation = "inverse"
method = "lhs"
samples = 40
seed = 5
[axes]
"platform.mass" = {min = 0.5, max = 4.0}
"drive.gear_ratio" = {min = 5.0, max = 50.0, log = true}
"friction.viscous" = [0.0, 5.0]
"""):
        grid = _grid(text)
        seq = grid.point_sequence()
        assert len(seq) == grid.size() and [seq[i] for i in range(len(seq))] == grid.points()
        with pytest.raises(IndexError):
            seq[len(seq)]


# --- chunks whose points interleave, and a resumed sized sweep ---------------------------------

def test_chunks_whose_points_interleave_merge_in_point_order(tmp_path):
    """Tasks of a resumed sweep hold the points left between earlier chunks: the merge reads
    each file once, in point order, and writes the serial table."""
    grid = _grid(INVERSE)
    spec, points = eval_spec(SCENE, grid), grid.points()
    cols = columns(grid.evaluation, grid.keys)
    rows = evaluate_batch(spec, points)
    fp = fingerprint(spec, grid)
    open_sweep(tmp_path, fp, cols, len(points))
    rules = chunk_rules(fp, cols, grid.point_sequence(), 24, has_drive(spec.scene))
    groups = [[0, 5, 23], [1, 2, 3, 4], [6, 12, 18], [7, 8, 9, 10, 11], [13, 14], [15, 16, 17],
              [19, 20, 21, 22]]
    for g in groups:
        write_chunk(tmp_path, rules, [rows[i] for i in g])
    ledger = resume_ledger(tmp_path, rules, pytest.fail)
    assert ledger.count == 24 and sum(ledger.done) == 24
    assert merge_chunks(tmp_path, rules, ledger) == (24, 8)
    assert (tmp_path / "sweep.csv").read_text() == csv_text(cols, rows)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as c:
        yield c


def test_a_resumed_sized_sweep_equals_the_uninterrupted_one(tmp_path, cluster, capsys):
    """A sweep with tasks sized to their cost (no `batch`), then the same sweep with half of its
    chunk files lost (a run stopped before writing them): the rerun computes only their points,
    and both tables are the serial one."""
    path = tmp_path / "grid.toml"
    path.write_text(INVERSE)
    grid = load_grid(path)
    spec = eval_spec(SCENE, grid)
    serial = csv_text(columns(grid.evaluation, grid.keys), evaluate_batch(spec, grid.points()))
    full = tmp_path / "full"
    assert main(["sweep", str(SCENE), "--grid", str(path), "--out", str(full), "--scheduler",
                 cluster.scheduler_address, "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "sweep: Dask dashboard at http://" in out and "/status" in out
    assert (full / "sweep.csv").read_text() == serial
    chunks = sorted((full / CHUNKS).glob("part-*.csv"))
    assert len(chunks) > 1          # the first tasks probe the cost with PROBE points
    lost = chunks[::2]
    lost_points = sum(len(p.read_text().splitlines()) - 2 for p in lost)
    for p in lost:
        p.unlink()
    (full / "sweep.csv").unlink()
    s = run_sweep(SCENE, grid, full, scheduler=cluster.scheduler_address, timeout=WAIT)
    assert s.computed == lost_points and s.resumed == 24 - lost_points and s.failed == 8
    assert (full / "sweep.csv").read_text() == serial


def test_a_task_is_the_ids_of_its_points():
    """A worker gets the points, settings and rules once (a TaskContext, pickled as Dask sends
    it) and a task's ids: its points are the grid's, values and types, and it returns the
    chunk text of their rows as the serial evaluation gives it, with the ids."""
    for text in (INVERSE, 'evaluation = "closed_loop"\n[axes]\n"controller.feedforward" = '
                          '["none", "kane"]\n"drive.gear_ratio" = [10.0, 20.0]\n'):
        grid = _grid(text)
        spec, points = eval_spec(SCENE, grid), grid.point_sequence()
        cols = columns(grid.evaluation, grid.keys)
        fp = fingerprint(spec, grid)
        rules = chunk_rules(fp, cols, points, 24, has_drive(spec.scene))
        context = pickle.loads(pickle.dumps(TaskContext(spec, points, rules)))
        assert [context.points[i] for i in range(len(points))] == grid.points()
        assert all(type(v) is type(w) for i in range(len(points))
                   for v, w in zip(context.points[i][1].values(), points[i][1].values()))
        ids = np.array([1, 2, len(points) - 1], dtype=np.int64)
        got, body, seconds, first = evaluate_task(context, ids, fp)
        assert got == ids.tolist() and seconds > 0 and first
        rows = evaluate_batch(spec, [points[i] for i in ids.tolist()])
        assert body == chunk_text(rules, checked_cells(rules, rows))
        assert body.decode() == csv_text(cols, rows)


def _worker_settings() -> tuple[dict, dict]:
    import os

    import dask

    return ({k: dask.config.get(k) for k in LOCAL_CLUSTER},
            {k: os.environ.get(k) for k in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS")})


def test_the_local_clusters_workers_run_with_its_settings():
    """The sweep's own local cluster: its workers' Dask settings are LOCAL_CLUSTER's (no
    profiler, slower monitors and ticks), whatever this process's are, and their environment
    has one BLAS thread and no MALLOC_TRIM_THRESHOLD_ (unless this process has one: a worker
    inherits it)."""
    with dask_client(None, 1) as client:
        got = client.run(_worker_settings)
    assert len(got) == 1
    settings, environ = list(got.values())[0]
    assert settings == LOCAL_CLUSTER
    assert LOCAL_CLUSTER["distributed.worker.profile.enabled"] is False
    assert environ["OMP_NUM_THREADS"] == "1"
    assert environ["MALLOC_TRIM_THRESHOLD_"] == os.environ.get("MALLOC_TRIM_THRESHOLD_")


def test_the_settings_as_environment_variables_are_the_local_clusters():
    """dask_environment gives a hand-started scheduler and workers LOCAL_CLUSTER's settings:
    Dask reads them back as they are (infinity as "inf", which its scheduler takes)."""
    import dask

    got = dask.config.collect(paths=[], env=dict(dask_environment()))
    for key, value in LOCAL_CLUSTER.items():
        read = dask.config.get(key, config=got)
        assert read == value or (value == math.inf and read == "inf"), key


def test_the_settings_print_as_shell_exports():
    """`python -m stewart_sim.studies.sweep.cluster` prints dask_environment as `export` lines a
    shell
    takes back as they are."""
    import shlex
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "stewart_sim.studies.sweep.cluster"], check=True,
                         capture_output=True, text=True).stdout
    got = {}
    for line in out.splitlines():
        word, assignment = shlex.split(line)
        assert word == "export"
        name, _, value = assignment.partition("=")
        got[name] = value
    assert got == dask_environment()


def test_the_client_checks_the_form_of_a_tasks_text():
    """check_task_text takes a worker's chunk text for the points sent (an error text over two
    lines included) and refuses, naming the fault, the rows of other points, another column
    set, a row missing and bytes that are not UTF-8."""
    grid = _grid(INVERSE)
    spec, points = eval_spec(SCENE, grid), grid.point_sequence()
    cols = columns(grid.evaluation, grid.keys)
    rules = chunk_rules(fingerprint(spec, grid), cols, points, 24, has_drive(spec.scene))
    ids = [6, 7, 8, 9]
    rows = evaluate_batch(spec, [points[i] for i in ids])
    assert {r["status"] for r in rows} == {"ok", "error"}
    rows = [{**r, "error": "first line\nsecond line"} if r["status"] == "error" else r
            for r in rows]
    cells = checked_cells(rules, rows)
    body = chunk_text(rules, cells)
    check_task_text(rules, ids, ids, body)
    lines = body.decode().split("\n")
    bad = {
        "the rows of other points": (ids[:3] + [10], body),
        "rows with other columns than the sweep's": (ids, body.replace(b"status", b"state", 1)),
        "3 rows that are not those of its 4 points": (ids, chunk_text(rules, {
            k: v for k, v in cells.items() if k != 7})),
        "text that is not UTF-8 CSV": (ids, body + b"\xff\n"),
    }
    assert len(lines) > len(ids) + 2     # the error text's line break is in the text
    for reason, (got, text) in bad.items():
        with pytest.raises(SweepError, match="do the workers run this version") as exc:
            check_task_text(rules, ids, got, text)
        assert reason in str(exc.value)
