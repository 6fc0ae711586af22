"""`sweep --adaptive N`: the points added cluster at boundaries computed independently (the
stroke limits from inverse kinematics along the trajectory; a peak-force threshold crossing of
the payload, root-found on the dynamics directly) and bracket them closer than the grid by the
factor the rounds promise; --adaptive 0 is the plain sweep byte for byte; a sweep interrupted
mid-refinement resumes to the same table; bad N, targets and grids: exit 2, one line."""
from __future__ import annotations

import functools
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from controller.moves import demo_trajectory
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.io import trajectory_table, write_csv
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.scene import apply_overrides, load_scene, read_scene_dict, scene_from_dict
from stewart_sim.cli import main
from stewart_sim.studies.sweep.adaptive import REFINEMENT, ROUNDS, check_adaptive
from stewart_sim.studies.sweep.adaptive_plots import RESULT_UNITS, refinement_figure
from stewart_sim.studies.sweep.dask_run import eval_spec, run_sweep
from stewart_sim.studies.sweep.evaluate import RESULTS
from stewart_sim.studies.sweep.evaluate import columns, evaluate_batch
from stewart_sim.studies.sweep.grid import grid_from_dict, load_grid
from stewart_sim.studies.sweep.plots import results_figure
from stewart_sim.studies.sweep.result_table import CHUNKS, MANIFEST, csv_text, read_table
from tests.app.test_plot_labels import check_figure

distributed = pytest.importorskip("distributed")

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
WAIT = 120.0  # s: the bound on every wait for the cluster
H = 0.01      # m: the stroke grid's spacing in leg_min and in leg_max
# Feasible where leg_min <= the shortest leg length along the move and leg_max >= the longest:
# a corner, crossed by the 4 leg_max lines at leg_min <= 0.12 and the 2 leg_min lines at
# leg_max >= 0.16, 6 grid edges straddle it; 24 points are 4 rounds of 6 bisections.
STROKE = """
evaluation = "inverse"
batch = 2
[trajectory]
kind = "file"
file = "traj.csv"
[axes]
"geometry.leg_min" = {min = 0.09, max = 0.13, points = 5}
"geometry.leg_max" = {min = 0.13, max = 0.17, points = 5}
"""
ADDED, ROUNDS_RUN = 24, 4
MASS_STAR = 2.1   # kg: the payload whose peak force is the threshold
MASS = """
evaluation = "inverse"
batch = 2
[trajectory]
kind = "file"
file = "traj.csv"
[adaptive]
target = "sigma_max"
threshold = {threshold!r}
[axes]
"platform.mass" = {{min = 0.25, max = 4.0, points = 6}}
"""


@functools.lru_cache(maxsize=None)
def move() -> tuple[np.ndarray, ...]:
    """The trajectory every point follows: the base scene's demonstration move, 0.3 s at
    200 Hz."""
    return demo_trajectory(load_scene(SCENE), 0.3, 200.0)


def sweep_dir(tmp_path: Path, text: str) -> Path:
    """A directory with the grid file and its trajectory."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    write_csv(tmp_path / "traj.csv", trajectory_table(*move()))
    (tmp_path / "grid.toml").write_text(text)
    return tmp_path / "grid.toml"


def stroke_limits() -> tuple[float, float]:
    """The shortest and the longest leg along the move and at home (inverse kinematics)."""
    model = load_scene(SCENE)
    lengths = inverse_kinematics(model, np.vstack([model.home, move()[1]])).lengths
    return float(lengths.min()), float(lengths.max())


def peak_force(mass: float) -> float:
    """max |sigma_i| along the move at this payload: the dynamics called directly."""
    model = scene_from_dict(apply_overrides(read_scene_dict(SCENE), {"platform.mass": mass}))
    _, q, qd, qdd = move()
    return float(np.max(np.abs(inverse_dynamics(model, q, qd, qdd))))


def brackets(table, axis: str, line: str, outcome: np.ndarray) -> dict[float, tuple[float, float]]:
    """For each value of `line`, the neighbours along `axis` whose outcomes differ: the
    boundary's bracket on that grid line (one per line here)."""
    out = {}
    for v in np.unique(table[line]):
        on = table[line] == v
        x, o = table[axis][on], outcome[on]
        k = np.argsort(x)
        x, o = x[k], o[k]
        flips = np.flatnonzero(o[1:] != o[:-1])
        if flips.size:
            assert flips.size == 1, (line, v, x, o)
            out[v] = (float(x[flips[0]]), float(x[flips[0] + 1]))
    return out


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as c:
        yield c


@pytest.fixture(scope="module")
def stroke(tmp_path_factory, cluster):
    """The stroke sweep with --adaptive 24, run once: its grid file and directory."""
    grid = sweep_dir(tmp_path_factory.mktemp("stroke"), STROKE)
    out = grid.parent / "out"
    s = run_sweep(SCENE, load_grid(grid), out, scheduler=cluster.scheduler_address,
                  timeout=WAIT, adaptive=ADDED)
    assert (s.points, s.added, s.computed, s.resumed) == (25 + ADDED, ADDED, 25 + ADDED, 0)
    return {"grid": grid, "out": out, "table": (out / "sweep.csv").read_text()}


def test_added_points_bracket_the_stroke_limits_16_times_closer_than_the_grid(stroke):
    lo, hi = stroke_limits()
    assert 0.12 < lo < 0.13 and 0.15 < hi < 0.16   # inside the grid, between grid values
    t = read_table(stroke["out"] / "sweep.csv")
    feasible = t["status"] == "ok"
    # the physics, point by point: feasible exactly within the stroke limits
    assert np.array_equal(feasible, (t["geometry.leg_min"] <= lo) & (t["geometry.leg_max"] >= hi))
    rounds = t[REFINEMENT]
    assert list(rounds[:25]) == [0] * 25
    assert sorted(rounds[25:]) == [k for k in range(1, ROUNDS_RUN + 1) for _ in range(6)]
    # every added point lies on a grid line, within half a grid step of the limit it brackets
    added = rounds > 0
    gap = np.minimum(np.abs(t["geometry.leg_min"] - lo), np.abs(t["geometry.leg_max"] - hi))
    assert np.all(gap[added] <= H / 2)
    check_refinement_plots(t, load_grid(stroke["grid"]), ADDED)
    step = H / 2 ** ROUNDS_RUN
    along_max = brackets(t, "geometry.leg_max", "geometry.leg_min", feasible)
    along_min = brackets(t, "geometry.leg_min", "geometry.leg_max", feasible)
    assert sorted(along_max) == pytest.approx([0.09, 0.10, 0.11, 0.12])
    assert sorted(along_min) == pytest.approx([0.16, 0.17])
    for a, b in along_max.values():
        assert a < hi <= b and b - a == pytest.approx(step, rel=1e-9)
    for a, b in along_min.values():
        assert a <= lo < b and b - a == pytest.approx(step, rel=1e-9)
    # the grid alone brackets each limit within H: 16 times wider
    grid = rounds == 0
    for a, b in brackets({k: v[grid] for k, v in t.items()}, "geometry.leg_max",
                         "geometry.leg_min", feasible[grid]).values():
        assert b - a == pytest.approx(H)


def test_added_points_bracket_a_peak_force_threshold(tmp_path, cluster):
    """Peak force rises with the payload; 5 points bisect the one straddling grid step 5
    times around the crossing root-found on the dynamics."""
    masses = np.linspace(0.25, 4.0, 40)
    assert np.all(np.diff([peak_force(m) for m in masses]) > 0)   # monotone: one crossing
    threshold = peak_force(MASS_STAR)
    root = brentq(lambda m: peak_force(m) - threshold, 0.25, 4.0, xtol=1e-12)
    assert root == pytest.approx(MASS_STAR, abs=1e-9)
    grid = sweep_dir(tmp_path, MASS.format(threshold=threshold))
    s = run_sweep(SCENE, load_grid(grid), tmp_path / "out", scheduler=cluster.scheduler_address,
                  timeout=WAIT, adaptive=5)
    assert s.added == 5 and s.failed == 0
    t = read_table(tmp_path / "out" / "sweep.csv")
    assert list(t[REFINEMENT]) == [0] * 6 + [1, 2, 3, 4, 5]
    (a, b), = brackets(t, "platform.mass", "status", t["sigma_max"] >= threshold).values()
    assert a < root < b and b - a == pytest.approx(0.75 / 2 ** 5, rel=1e-9)
    assert np.all(np.abs(t["platform.mass"][6:] - root) <= 0.75 / 2)
    check_refinement_plots(t, load_grid(grid), 5)


def check_refinement_plots(table, grid, added: int) -> None:
    """The map marks the added points apart (triangles), the main figure circles them; axes
    with units."""
    fig = refinement_figure(table, grid, "sweep")
    check_figure(fig)
    ax = fig.axes[0]
    marked = sum(len(c.get_offsets()) for c in ax.collections if "added" in c.get_label())
    assert marked == added and f"{added} points added" in ax.get_title()
    main_fig = results_figure(table, grid, "sweep")
    check_figure(main_fig)
    labels = [c.get_label() for c in main_fig.axes[0].collections]
    ok_added = int(np.sum((table[REFINEMENT] > 0) & (table["status"] == "ok")))
    assert f"{ok_added} added by refinement" in labels


def test_every_result_has_a_unit_for_the_map():
    assert {r for rs in RESULTS.values() for r in rs} == set(RESULT_UNITS)


def test_adaptive_0_is_the_plain_sweep_and_the_grid_rows_are_kept(tmp_path, cluster, stroke):
    """--adaptive 0: the serial table byte for byte, no refinement column, no rounds; with
    --adaptive N the grid's rows are those same rows."""
    grid = sweep_dir(tmp_path, STROKE)
    g = load_grid(grid)
    serial = csv_text(columns(g.evaluation, g.keys), evaluate_batch(eval_spec(SCENE, g), g.points()))
    run_sweep(SCENE, g, tmp_path / "out", scheduler=cluster.scheduler_address, timeout=WAIT,
              adaptive=0)
    assert (tmp_path / "out" / "sweep.csv").read_text() == serial
    assert not (tmp_path / "out" / ROUNDS).exists()
    assert (tmp_path / "out" / MANIFEST).read_text() == (stroke["out"] / MANIFEST).read_text()
    lines = stroke["table"].splitlines()
    assert lines[0] == serial.splitlines()[0] + f",{REFINEMENT}"
    assert [line.rsplit(",", 1)[0] for line in lines[:26]] == serial.splitlines()


class _StopInRound:
    """A progress display that presses Ctrl-C once round `k` has a chunk file."""

    def __init__(self, out: Path, k: int):
        self.where = out / ROUNDS / f"round-{k:03d}" / CHUNKS

    def update(self, *args, **kwargs) -> None:
        if self.where.is_dir() and any(self.where.glob("part-*.csv")):
            raise KeyboardInterrupt


def test_a_sweep_interrupted_mid_refinement_resumes_to_the_same_table(tmp_path, cluster, stroke):
    out = tmp_path / "out"
    g = load_grid(stroke["grid"])
    with pytest.raises(KeyboardInterrupt):
        run_sweep(SCENE, g, out, scheduler=cluster.scheduler_address, timeout=WAIT,
                  adaptive=ADDED, progress=_StopInRound(out, 2))
    partial = read_table(out / "sweep.csv")
    assert 25 + 6 < len(partial["point"]) < 25 + ADDED
    assert set(partial[REFINEMENT]) == {0, 1, 2}
    # a chunk of the grid put among round 3's: refused there (another fingerprint)
    third = out / ROUNDS / "round-003" / CHUNKS
    third.mkdir(parents=True)
    shutil.copy(out / CHUNKS / "part-000000000.csv", third / "part-000000000.csv")
    notices: list[str] = []
    s = run_sweep(SCENE, g, out, scheduler=cluster.scheduler_address, timeout=WAIT,
                  adaptive=ADDED, notice=notices.append)
    assert s.resumed == len(partial["point"]) and s.computed == 25 + ADDED - s.resumed
    assert s.refused == 1 and len(notices) == 1 and "written for another sweep" in notices[0]
    assert (out / "sweep.csv").read_text() == stroke["table"]
    again = run_sweep(SCENE, g, out, scheduler=cluster.scheduler_address, timeout=WAIT,
                      adaptive=ADDED)
    assert again.computed == 0 and (out / "sweep.csv").read_text() == stroke["table"]


@pytest.mark.parametrize("extra, grid_text, words", [
    (["--adaptive", "-1"], STROKE, "argument --adaptive: must be an integer from 0 to 1000000"),
    (["--adaptive", "many"], STROKE, "argument --adaptive: not an integer: 'many'"),
    (["--adaptive", "4"], STROKE + '[adaptive]\ntarget = "peak"\nthreshold = 1.0\n',
     "grid key 'adaptive.target': must be \"feasible\" or a result of evaluation 'inverse'"),
    (["--adaptive", "0"], STROKE + '[adaptive]\ntarget = "leg_err_rms"\nthreshold = 1.0\n',
     "grid key 'adaptive.target'"),
    (["--adaptive", "4"], STROKE + '[adaptive]\ntarget = "sigma_max"\n',
     "grid key 'adaptive.threshold': required key is missing"),
    (["--adaptive", "4"], STROKE + '[adaptive]\nthreshold = 3.0\n',
     "grid key 'adaptive.threshold': only for a result column"),
    (["--adaptive", "4"], STROKE + '[adaptive]\ntarget = "sigma_max"\nthreshold = "high"\n',
     "grid key 'adaptive.threshold': must be a finite number"),
    (["--adaptive", "4"], STROKE + '[adaptive]\ncolour = 1\n', "grid key 'adaptive.colour'"),
    (["--adaptive", "4"], STROKE.replace('"geometry.leg_min" = {min = 0.09, max = 0.13, points = 5}\n'
                                         '"geometry.leg_max" = {min = 0.13, max = 0.17, points = 5}',
                                         '"platform.mass" = [1.0]'),
     "--adaptive 4: no numeric axis with two values or more"),
    (["--adaptive", "4"], 'evaluation = "inverse"\nmethod = "lhs"\nsamples = 4\n[axes]\n'
                          '"platform.mass" = {min = 0.5, max = 1.0}\n',
     "--adaptive 4: refinement bisects the edges of a full grid; method = \"lhs\""),
])
def test_bad_adaptive_inputs_exit_2_in_one_line(tmp_path, capsys, extra, grid_text, words):
    grid = sweep_dir(tmp_path, grid_text)
    out = tmp_path / "out"
    assert main(["sweep", str(SCENE), "--grid", str(grid), "--out", str(out), "--workers", "1",
                 "--no-plots", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert words in err[-1] and err[-1].startswith("stewart-sim")
    assert err[-1].startswith("stewart-sim sweep: error: argument") or len(err) == 1
    assert not out.exists()


def test_the_command_adds_the_points_and_writes_the_map(tmp_path, cluster, capsys):
    grid = sweep_dir(tmp_path, MASS.format(threshold=peak_force(MASS_STAR)))
    out = tmp_path / "out"
    assert main(["sweep", str(SCENE), "--grid", str(grid), "--out", str(out), "--scheduler",
                 cluster.scheduler_address, "--adaptive", "3"]) == 0
    printed = capsys.readouterr().out
    assert "sweep: 9 points (3 added by refinement), 0 already done, 9 computed" in printed
    for name in ("sweep.csv", "refinement.png", "peak_force.png"):
        assert f"wrote {out / name}" in printed
    assert (out / "refinement.png").stat().st_size > 10_000
    assert list(read_table(out / "sweep.csv")[REFINEMENT]) == [0] * 6 + [1, 2, 3]


def test_the_shipped_grids_pass_the_adaptive_checks():
    for path in sorted((SCENE.parent / "sweeps").glob("*.toml")):
        check_adaptive(load_grid(path), 0, drive=True)   # micro_manipulator.toml has a [drive]
    g = load_grid(SCENE.parent / "sweeps" / "torque_adaptive.toml")
    check_adaptive(g, 56, drive=True)
    assert (g.adaptive.target, g.adaptive.threshold) == ("torque_max", 0.008)


def test_the_adaptive_table_is_part_of_the_grid_format():
    g = grid_from_dict(tomllib.loads(MASS.format(threshold=12.5)))
    assert (g.adaptive.target, g.adaptive.threshold) == ("sigma_max", 12.5)
    assert grid_from_dict(tomllib.loads(STROKE)).adaptive.target == "feasible"
