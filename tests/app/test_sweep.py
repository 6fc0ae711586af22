"""Design sweeps: grid and Latin-hypercube points, GRID.toml errors naming the key, and the sweep
on Dask (local cluster, loopback distributed cluster) against a direct serial evaluation of the
same points; interruption and resume, a worker killed mid-sweep, the command's files."""
from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu.errors import SceneError, SweepError
from stewart_sim.cli import main
from stewart_sim.studies.sweep.dask_run import eval_spec, run_sweep
from stewart_sim.studies.sweep.evaluate import columns, evaluate_batch
from stewart_sim.studies.sweep.grid import grid_from_dict, load_grid
from stewart_sim.studies.sweep.result_table import CHUNKS, csv_text, read_table

distributed = pytest.importorskip("distributed")

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
WAIT = 120.0  # s: the bound on every wait for a cluster, a thread or a process

INVERSE = """
evaluation = "inverse"
batch = 4
[trajectory]
duration = 0.3
[axes]
"platform.mass" = [0.5, 2.0, -1.0]          # -1: a point the scene rejects (a row, not a crash)
"drive.gear_ratio" = {min = 5.0, max = 40.0, points = 3, log = true}
legs.upper_mass = [0.05, 0.1]
"""
CLOSED_LOOP = """
evaluation = "closed_loop"
batch = 1
[trajectory]
kind = "run"
duration = 0.3
[axes]
"drive.gear_ratio" = [10.0, 20.0]
"controller.feedforward" = ["none", "kane"]
"""
ENVELOPE = """
evaluation = "envelope"
batch = 2
[envelope]
x = [-0.03, 0.03]
z = [-0.04, 0.04]
points = 7
accelerations = [[0, 0, 0, 0, 0, 0], [10, 0, 0, 0, 0, 0]]
[axes]
"platform.mass" = [0.5, 1.0]
"geometry.leg_max" = [0.15, 0.19]
"""
# Long enough to interrupt: the leg stroke changes the demonstration move at every point.
SLOW = """
evaluation = "inverse"
batch = 4
[trajectory]
duration = 1.0
[axes]
"geometry.leg_max" = {min = 0.17, max = 0.20, points = 120}
"""


def grid_file(tmp_path: Path, text: str, name: str = "grid.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def serial_table(path: Path) -> str:
    """The table a sweep must write: every point evaluated directly, in one process."""
    return _serial_table(path.read_text(), str(path))


@functools.lru_cache(maxsize=None)
def _serial_table(text: str, path: str) -> str:
    grid = load_grid(path)
    rows = evaluate_batch(eval_spec(SCENE, grid), grid.points())
    return csv_text(columns(grid.evaluation, grid.keys), rows)


@pytest.fixture(scope="module")
def cluster():
    """A real dask.distributed scheduler and two worker processes on loopback."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as c:
        yield c


# --- points ----------------------------------------------------------------------------------

def test_grid_points_cover_every_combination_in_order():
    g = grid_from_dict(tomllib.loads(INVERSE))
    pts = g.points()
    assert g.size() == len(pts) == 3 * 3 * 2
    assert [p for p, _ in pts] == list(range(18))
    assert pts[0][1] == {"platform.mass": 0.5, "drive.gear_ratio": 5.0, "legs.upper_mass": 0.05}
    assert pts[1][1]["legs.upper_mass"] == 0.1  # the last axis runs fastest
    assert np.allclose(sorted({v["drive.gear_ratio"] for _, v in pts}), [5, np.sqrt(200), 40])


def test_latin_hypercube_is_stratified_bounded_and_reproducible():
    text = """evaluation = "inverse"
method = "lhs"
samples = 50
seed = 7
[axes]
"platform.mass" = {min = 0.5, max = 4.0}
"drive.gear_ratio" = {min = 5.0, max = 50.0, log = true}
"friction.viscous" = [0.0, 5.0]
"""
    g = grid_from_dict(tomllib.loads(text))
    pts = [v for _, v in g.points()]
    assert len(pts) == 50
    mass = np.array([p["platform.mass"] for p in pts])
    zeta = np.array([p["drive.gear_ratio"] for p in pts])
    assert np.all((mass >= 0.5) & (mass < 4.0)) and np.all((zeta >= 5) & (zeta < 50))
    # one sample in each of the 50 strata of every axis (log-uniform for the log axis)
    assert sorted(((mass - 0.5) / 3.5 * 50).astype(int)) == list(range(50))
    assert sorted((np.log(zeta / 5) / np.log(10) * 50).astype(int)) == list(range(50))
    assert sorted(p["friction.viscous"] for p in pts) == [0.0] * 25 + [5.0] * 25
    assert [v for _, v in g.points()] == pts
    other = grid_from_dict(tomllib.loads(text.replace("seed = 7", "seed = 8")))
    assert [v for _, v in other.points()] != pts


@pytest.mark.parametrize("text, key", [
    ('evaluation = "inverse"\n[axes]\n"platform.mas" = [1.0]', "axes.platform.mas"),
    ('evaluation = "inverse"\n[axes]\n"platform.mass" = []', "axes.platform.mass"),
    ('evaluation = "inverse"\n[axes]\n"platform.mass" = ["heavy"]', "axes.platform.mass"),
    ('evaluation = "inverse"\n[axes]\n"platform.mass" = {min = 2.0, max = 1.0, points = 3}',
     "axes.platform.mass"),
    ('evaluation = "inverse"\n[axes]\n"platform.mass" = {min = 1.0, max = 2.0}',
     "axes.platform.mass.points"),
    ('evaluation = "inverse"\n[axes]\n"drive.gear_ratio" = {min = 0.0, max = 2.0, points = 2, log = true}',
     "axes.drive.gear_ratio.min"),
    ('evaluation = "inverse"\n[axes]\n"controller.bandwidth" = [10.0]', "axes.controller.bandwidth"),
    ('evaluation = "closed_loop"\n[axes]\n"controller.feedforward" = ["kane", "magic"]',
     "axes.controller.feedforward"),
    ('evaluation = "bending"\n[axes]\n"platform.mass" = [1.0]', "evaluation"),
    ('[axes]\n"platform.mass" = [1.0]', "evaluation"),
    ('evaluation = "inverse"', "axes"),
    ('evaluation = "inverse"\nmethod = "lhs"\n[axes]\n"platform.mass" = {min = 1.0, max = 2.0}',
     "samples"),
    ('evaluation = "inverse"\nbatch = 0\n[axes]\n"platform.mass" = [1.0]', "batch"),
    ('evaluation = "inverse"\ncolour = 1\n[axes]\n"platform.mass" = [1.0]', "colour"),
    ('evaluation = "inverse"\n[trajectory]\nkind = "file"\n[axes]\n"platform.mass" = [1.0]',
     "trajectory.file"),
    ('evaluation = "envelope"\n[envelope]\nx = [0.1]\n[axes]\n"platform.mass" = [1.0]', "envelope.x"),
    ('evaluation = "envelope"\n[envelope]\nx = [0, 0.1]\naccelerations = [[1, 2]]\n[axes]\n'
     '"platform.mass" = [1.0]', "envelope.accelerations"),
])
def test_bad_grids_are_refused_naming_the_key(text, key):
    with pytest.raises(SweepError) as info:
        grid_from_dict(tomllib.loads(text), "grid.toml")
    assert info.value.key == key and f"grid key '{key}'" in str(info.value)


def test_a_key_the_scene_cannot_take_is_refused_before_anything_runs(tmp_path):
    """A negative viscous friction at the first point: the scene refuses it, naming the key,
    before any cluster starts or any directory is made."""
    text = ('evaluation = "closed_loop"\n[axes]\n"controller.motor.resistance" = [1.0]\n'
            '"friction.viscous" = [-1.0, 1.0]\n')
    with pytest.raises(SceneError) as info:
        run_sweep(SCENE, grid_from_dict(tomllib.loads(text)), tmp_path / "out")
    assert info.value.key == "friction.viscous"
    assert not (tmp_path / "out").exists()


# --- the sweep on Dask -----------------------------------------------------------------------

def test_command_on_the_local_cluster_equals_the_serial_evaluation(tmp_path, cluster, capsys):
    """`stewart-sim sweep` (local cluster, 2 workers) writes the serial table, byte for byte,
    a failed point as a row with its error, and the plots; the loopback cluster gives the same
    table."""
    grid = grid_file(tmp_path, INVERSE)
    out = tmp_path / "local"
    assert main(["sweep", str(SCENE), "--grid", str(grid), "--out", str(out),
                 "--workers", "2"]) == 0
    text = (out / "sweep.csv").read_text()
    assert text == serial_table(grid)
    table = read_table(out / "sweep.csv")
    failed = table["status"] != "ok"
    assert np.all(table["platform.mass"][failed] == -1.0) and failed.sum() == 6
    assert all("SceneError" in e and "platform.mass" in e for e in table["error"][failed])
    assert np.all(table["sigma_max"][~failed] > 0)
    for name in ("peak_force.png", "force_envelope.png", "singularity_map.png"):
        assert (out / name).stat().st_size > 10_000
    assert "18 points, 0 already done, 18 computed on 2 workers" in capsys.readouterr().out

    summary = run_sweep(SCENE, load_grid(grid), tmp_path / "dist", scheduler=cluster.scheduler_address,
                        timeout=WAIT)
    assert summary.workers == 2 and summary.computed == 18 and summary.failed == 6
    assert (tmp_path / "dist" / "sweep.csv").read_text() == text

    with pytest.raises(SweepError, match="another sweep"):  # the directory holds this sweep only
        run_sweep(SCENE, grid_from_dict(tomllib.loads(ENVELOPE)), out)


@pytest.mark.parametrize("text", [CLOSED_LOOP, ENVELOPE], ids=["closed_loop", "envelope"])
def test_distributed_sweep_equals_the_serial_evaluation(tmp_path, cluster, text):
    grid = grid_file(tmp_path, text)
    summary = run_sweep(SCENE, load_grid(grid), tmp_path / "out",
                        scheduler=cluster.scheduler_address, timeout=WAIT)
    assert summary.failed == 0 and summary.computed == 4
    assert (tmp_path / "out" / "sweep.csv").read_text() == serial_table(grid)


def test_envelope_rows_are_the_physics(tmp_path):
    """A heavier platform raises the static envelope; a shorter stroke leaves fewer poses."""
    grid = load_grid(grid_file(tmp_path, ENVELOPE))
    rows = evaluate_batch(eval_spec(SCENE, grid), grid.points())
    by = {(r["platform.mass"], r["geometry.leg_max"]): r for r in rows}
    assert by[(1.0, 0.19)]["sigma_max"] > by[(0.5, 0.19)]["sigma_max"]
    assert by[(0.5, 0.15)]["reachable"] < by[(0.5, 0.19)]["reachable"] <= 1.0


@pytest.mark.parametrize("group", [False, True], ids=["process", "process-group"])
def test_interrupted_sweep_keeps_its_rows_and_resumes(tmp_path, cluster, group):
    """Ctrl-C (SIGINT) mid-sweep: exit 130, the finished rows are in the table; the rerun
    computes only the rest, and the final table is the serial one: nothing lost, nothing twice.
    Sent to the whole process group, as a terminal does, it reaches the local cluster's workers
    too: still one line, no worker's traceback (cluster.WORKER_PRELOAD)."""
    grid = grid_file(tmp_path, SLOW)
    out = tmp_path / "out"
    exe = Path(sys.executable).parent / "stewart-sim"
    proc = subprocess.Popen([str(exe), "sweep", str(SCENE), "--grid", str(grid), "--out", str(out),
                             "--workers", "1", "--no-plots"], start_new_session=group,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + WAIT
        while len(list((out / CHUNKS).glob("part-*.csv"))) < 3:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no rows appeared"
            time.sleep(0.05)
        if group:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=WAIT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=WAIT)
    assert proc.returncode == 130, err
    assert err.rstrip().endswith("stewart-sim: error: interrupted")
    assert "Traceback" not in err, err
    partial = read_table(out / "sweep.csv")["point"]
    assert 12 <= len(partial) < 120 and len(set(partial)) == len(partial)

    summary = run_sweep(SCENE, load_grid(grid), out, scheduler=cluster.scheduler_address,
                        timeout=WAIT)
    assert summary.resumed == len(partial) and summary.computed == 120 - len(partial)
    assert (out / "sweep.csv").read_text() == serial_table(grid)


def test_a_worker_killed_mid_sweep_loses_no_point(tmp_path, cluster):
    """SIGKILL one of two worker processes once rows arrive: the scheduler reruns its tasks
    (its nanny restarts it), and the table still has every point once, equal to the serial one.
    The module's cluster: the nanny's restart leaves it whole again (waited for at the end)."""
    grid = grid_file(tmp_path, SLOW)
    out = tmp_path / "out"
    c = cluster
    with distributed.Client(c, timeout=WAIT) as client:
        client.wait_for_workers(2, timeout=WAIT)  # workers up
        pids = client.run(os.getpid)
        result: dict = {}
        worker = threading.Thread(target=lambda: result.update(summary=run_sweep(
            SCENE, load_grid(grid), out, scheduler=c.scheduler_address, timeout=WAIT)))
        worker.start()
        deadline = time.monotonic() + WAIT
        while not (out / CHUNKS).is_dir() or not list((out / CHUNKS).glob("part-*.csv")):
            assert worker.is_alive() and time.monotonic() < deadline
            time.sleep(0.02)
        victim = sorted(pids.values())[0]
        os.kill(victim, signal.SIGKILL)
        worker.join(WAIT)
        assert not worker.is_alive()
        assert victim not in client.run(os.getpid).values()  # it really died (and was replaced)
        client.wait_for_workers(2, timeout=WAIT)
        assert victim not in client.run(os.getpid).values()
    s = result["summary"]
    assert s.computed == 120 and s.failed == 0
    assert (out / "sweep.csv").read_text() == serial_table(grid)
