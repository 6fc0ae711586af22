"""`stewart-sim design` (stewart_sim.studies.design): the joints' layout against the shipped
scenes, a candidate's margins against the engine, the modes and the stiffness called directly,
the report of a requirement no geometry meets, bad input, the shipped example at a reduced size
(its best.toml re-checked here), and one seed giving one search on 1 and 2 workers and BLAS
threads."""
from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from stewart_fmu import load_scene
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.reach import Engine
from stewart_fmu.scene import read_scene_dict
from stewart_fmu.stiffness import modes, modes_map, stiffness
from stewart_sim.studies.design import candidate as C
from stewart_sim.studies.design import spec as S
from stewart_sim.studies.design.layout import joints

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "scenes" / "design" / "positioning_hexapod.toml"
REDUCED = ("--population", "20", "--generations", "8")   # the example's CI size
ROUNDING = 5e-7   # the shipped scenes' joints are written to 1e-6 m


def cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "stewart_sim", *map(str, args)],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, **(env or {})})


def design_file(tmp_path: Path, **tables) -> Path:
    """The example's design.toml with tables' keys replaced, its base scene by absolute path."""
    doc = tomlkit.parse(EXAMPLE.read_text())
    doc["design"]["base_scene"] = str((EXAMPLE.parent / doc["design"]["base_scene"]).resolve())
    for table, keys in tables.items():
        for k, v in keys.items():
            doc[table][k] = v
    path = tmp_path / "design.toml"
    path.write_text(tomlkit.dumps(doc))
    return path


@pytest.mark.parametrize("scene,base,platform", [
    ("micro_manipulator.toml", (0.10, 10.0), (0.06, 50.0, -0.01)),
    ("motion_simulator.toml", (2.2, 12.0), (1.4, 48.0, -0.35)),
])
def test_layout_gives_the_shipped_scenes_joints(scene, base, platform):
    g = read_scene_dict(ROOT / "scenes" / scene)["geometry"]
    a = joints(base[0], np.radians(base[1]))
    p = joints(platform[0], np.radians(platform[1]), platform[2])
    assert np.abs(a - g["base_joints"]).max() <= ROUNDING
    assert np.abs(p - g["platform_joints"]).max() <= ROUNDING


def test_a_candidates_margins_are_the_engines_and_the_modes():
    spec = S.load(EXAMPLE)
    names = C.requirement_names(spec)
    x = np.array([0.1, 0.06, np.radians(10), np.radians(50), 0.12, 0.09, 0.05, 1e7])
    c = C.evaluate(spec, x, names)
    got = {m.name: m for m in c.margins}
    values = spec.values(x)
    model = C.candidate_model(spec, values)
    Q = C.workspace_poses(spec.workspace, model.home, spec.workspace.search_points)
    # the axes' ends, then the four tilts at home and at the translations' ends
    assert c.poses == len(Q) == 1 + 6 * 2 + 4 * (1 + 3 * 2)
    kin = inverse_kinematics(model, Q)
    L = np.asarray(kin.lengths)
    assert got["stroke_min"].absolute == pytest.approx(L.min() - values["leg_min"], abs=1e-12)
    assert got["stroke_max"].absolute == pytest.approx(
        values["leg_min"] + values["stroke"] - L.max(), abs=1e-12)
    assert got["stroke_max"].relative == pytest.approx(
        got["stroke_max"].absolute / values["stroke"], rel=1e-12)
    cond = np.asarray(kin.cond).ravel()
    assert got["cond"].absolute == pytest.approx(20.0 - cond.max(), rel=1e-9)
    # the first mode over the poses every limit passes (home included), pose by pose
    ok = Engine(model, None, 20.0).check(Q)["feasible"]
    assert 0 < ok.sum() < len(Q)      # this candidate misses part of the workspace
    poses = np.vstack([model.home, Q[ok]])
    first = np.array([modes(model, q).frequency_hz[0] for q in poses])
    assert c.first_hz == pytest.approx(first.min(), rel=1e-9)
    assert got["first_resonance"].relative == pytest.approx(first.min() / 100.0 - 1, rel=1e-9)
    worst = poses[np.argmin(first)]
    k = np.minimum(stiffness(model, model.home).axis_stiffness,
                   stiffness(model, worst).axis_stiffness)
    for j, axis in enumerate("xyz"):
        need = spec.requirements.stiffness[j]
        assert got[f"stiffness_{axis}"].absolute == pytest.approx(k[j] - need, rel=1e-9)


def test_a_requirement_no_geometry_meets_is_named_with_its_shortfall(tmp_path):
    path = design_file(tmp_path, requirements={"first_resonance": 5000.0})
    out = tmp_path / "out"
    r = cli("design", path, "--out", out, "--workers", "1", "--population", "8",
            "--generations", "2")
    assert r.returncode == 3, r.stderr
    assert "Traceback" not in r.stderr
    with open(out / "candidates.csv") as fh:
        best = max(float(row["margin_first_resonance"]) for row in csv.DictReader(fh))
    assert best < 0
    line = r.stdout.strip().splitlines()[-1]
    assert "first_resonance" in line and f"short by {-best:.1%}" in line
    summary = (out / "summary.md").read_text()
    assert "No design found" in summary and "first_resonance" in summary
    assert not (out / "best.toml").exists() and (out / "margins.png").is_file()


@pytest.mark.parametrize("tables,key", [
    ({"workspace": {"x": [0.01, -0.01]}}, "workspace.x"),
    ({"parameters": {"stroke": [0.06, 0.02]}}, "parameters.stroke"),
    ({"requirements": {"first_resonance": -1.0}}, "requirements.first_resonance"),
    ({"search": {"seed": -3}}, "search.seed"),
    ({"payload": {"mass": -5.0}}, "payload.mass"),
    ({"parameters": {"base_half_angle": [0.0, 0.5]}}, "parameters.base_half_angle"),
])
def test_bad_input_is_one_line_naming_the_key(tmp_path, tables, key):
    out = tmp_path / "out"
    r = cli("design", design_file(tmp_path, **tables), "--out", out)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and key in r.stderr, r.stderr
    assert not out.exists()


def test_the_example_at_a_reduced_size_finds_a_design_that_holds(tmp_path):
    out = tmp_path / "out"
    r = cli("design", EXAMPLE, "--out", out, "--workers", "2", *REDUCED)
    assert r.returncode == 0, r.stderr
    for name in ("pareto.csv", "candidates.csv", "best.toml", "front.png", "margins.png",
                 "parameters.png", "summary.md"):
        assert (out / name).is_file(), name
    # best.toml re-checked here on the dense grid, every requirement of the example
    spec = S.load(EXAMPLE)
    model = load_scene(out / "best.toml")
    Q = C.workspace_poses(spec.workspace, model.home, spec.workspace.check_points)
    assert len(Q) == 1 + 6 * 8 + 4 * (1 + 3 * 8)
    assert Engine(model, None, spec.requirements.cond_limit).check(Q)["feasible"].all()
    assert modes_map(model, Q).lowest_hz.min() >= spec.requirements.first_resonance
    k = stiffness(model, model.home).axis_stiffness
    assert np.all(k[:3] >= np.array(spec.requirements.stiffness[:3]))


@pytest.mark.parametrize("example", [EXAMPLE, EXAMPLE.parent / "motion_simulator.toml"],
                         ids=["positioning", "motion-simulator"])
def test_a_seed_gives_one_search_on_any_workers_and_blas_threads(tmp_path, example):
    runs, fronts = [], []
    for n in (1, 2):
        out = tmp_path / f"out{n}"
        r = cli("design", example, "--out", out, "--workers", str(n), "--population", "12",
                "--generations", "3", env={"OPENBLAS_NUM_THREADS": str(n)})
        assert r.returncode in (0, 3), r.stderr
        with open(out / "candidates.csv") as fh:
            rows = list(csv.DictReader(fh))
        runs.append(np.array([[float(v) for v in row.values()] for row in rows]))
        with open(out / "pareto.csv") as fh:
            fronts.append([row["candidate"] for row in csv.DictReader(fh)])
    a, b = runs
    assert a.shape == b.shape == (36, a.shape[1])
    # the same candidates (pymoo's draws from the seed, the same selections); the margins are
    # C calls and LAPACK's eigenvalues, equal to rounding (1e-9 of a relative margin)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    assert fronts[0] == fronts[1]


def test_the_workspace_grids_box_axes_and_orientations():
    ws = S.Workspace({"x": (-0.01, 0.02), "thz": (-0.1, 0.1)}, "box", 3, 5, ((0.05, 0.0, 0.0),))
    home = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
    Q = C.workspace_poses(ws, home, 3)
    # 3 x 3 combinations, then the orientation at each of the 3 positions (x's values)
    assert len(Q) == 9 + 3
    box = Q[:9] - home
    assert {tuple(r) for r in box[:, [0, 5]].round(12)} == {
        (x, t) for x in (-0.01, 0.005, 0.02) for t in (-0.1, 0.0, 0.1)}
    assert np.all(box[:, [1, 2, 3, 4]] == 0.0)
    tilt = Q[9:] - home
    assert np.allclose(tilt[:, 3:], [0.05, 0.0, 0.0])
    assert np.allclose(sorted(tilt[:, 0]), [-0.01, 0.005, 0.02], rtol=0, atol=1e-15)
    axes = C.workspace_poses(S.Workspace(ws.ranges, "axes", 3, 5, ()), home, 5)
    # home, then each axis's values other than home: x's five (none is 0), thz's four
    assert len(axes) == 1 + 5 + 4
