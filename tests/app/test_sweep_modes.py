"""The sweep's modes evaluation (stewart_sim/studies/sweep/evaluate.py) and its joint-layout
axes (joint_layout.py): the columns lowest_hz and weakest_n_per_um against stewart_fmu.stiffness
on a scene whose joints the test lays out itself; the shipped example grid; bad values a row's
error."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu import stiffness as S
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from stewart_sim import cli
from stewart_sim.studies.sweep.evaluate import EvalSpec, columns, evaluate_point
from stewart_sim.studies.sweep.grid import load_grid

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"
GRID = ROOT / "scenes" / "sweeps" / "modes_joints.toml"
SAME = 1e-12     # the same computation on joints rounded differently, relative


def _laid_out(data: dict, side: str, radius: float, angle: float) -> dict:
    """The scene dict with one side's joints put by hand: joint i at 120 deg (i // 2) -+ angle."""
    out = {**data, "geometry": dict(data["geometry"])}
    joints = []
    for i, old in enumerate(data["geometry"][f"{side}_joints"]):
        a = math.radians(120.0 * (i // 2) + (angle if i % 2 else -angle))
        joints.append([radius * math.cos(a), radius * math.sin(a), old[2]])
    out["geometry"][f"{side}_joints"] = joints
    return out


@pytest.mark.parametrize("values", [
    {"pairs.base_half_angle": 20.0},
    {"pairs.platform_radius": 1.0, "pairs.platform_half_angle": 56.0},
    {"pairs.base_radius": 2.0, "pairs.base_half_angle": 8.0, "pairs.platform_half_angle": 40.0},
])
def test_the_columns_are_stewart_fmus_at_home(values):
    data = read_scene_dict(SIM)
    row = evaluate_point(EvalSpec("modes", data), 0, values)
    assert row["status"] == "ok", row["error"]
    assert set(columns("modes", list(values))) == set(row)
    expect = data
    for side in ("base", "platform"):
        r, a = values.get(f"pairs.{side}_radius"), values.get(f"pairs.{side}_half_angle")
        if r is None and a is None:
            continue
        first = np.array(data["geometry"][f"{side}_joints"][1])
        r = float(np.hypot(*first[:2])) if r is None else r
        a = math.degrees(math.atan2(first[1], first[0])) if a is None else a
        expect = _laid_out(expect, side, r, a)
    model = scene_from_dict(expect)
    home = np.asarray(model.home, dtype=float)
    assert row["lowest_hz"] == pytest.approx(S.modes(model, home).frequency_hz[0], rel=SAME)
    c = S.stiffness(model, home).compliance[:3, :3]
    weakest = 1.0 / np.linalg.eigvalsh(c)[-1]        # N/m: the force direction that moves most
    assert row["weakest_n_per_um"] == pytest.approx(weakest * 1e-6, rel=1e-9)


def test_the_scenes_own_layout_gives_its_modes():
    """The shipped layout's values (12 deg, 48 deg): the scene's joints to their 6 digits."""
    row = evaluate_point(EvalSpec("modes", read_scene_dict(SIM)), 0,
                         {"pairs.base_half_angle": 12.0, "pairs.platform_half_angle": 48.0})
    model = load_scene(SIM)
    assert row["lowest_hz"] == pytest.approx(S.modes(model, model.home).frequency_hz[0], rel=1e-6)


@pytest.mark.parametrize("values,words", [
    ({"pairs.platform_radius": 0.0}, "pairs.platform_radius"),
    ({"pairs.base_half_angle": 60.0}, "pairs.base_half_angle"),
])
def test_a_bad_layout_is_the_points_error(values, words):
    row = evaluate_point(EvalSpec("modes", read_scene_dict(SIM)), 3, values)
    assert row["status"] == "error" and words in row["error"] and math.isnan(row["lowest_hz"])


def test_joints_not_on_circles_cannot_take_the_axes():
    data = read_scene_dict(SIM)
    data = {**data, "geometry": {**data["geometry"]}}
    joints = [list(j) for j in data["geometry"]["base_joints"]]
    joints[3][0] += 0.01
    data["geometry"]["base_joints"] = joints
    row = evaluate_point(EvalSpec("modes", data), 0, {"pairs.base_half_angle": 10.0})
    assert row["status"] == "error" and "geometry.base_joints" in row["error"]


def test_the_shipped_grid_and_a_scene_without_stiffness(tmp_path, capsys):
    grid = load_grid(GRID)
    assert grid.evaluation == "modes" and len(list(grid.points())) == 108
    scene = tmp_path / "s.toml"
    scene.write_text(SIM.read_text().replace("[stiffness]\nleg = 5.0e7", ""))
    assert cli.main(["sweep", str(scene), "--grid", str(GRID), "--out", str(tmp_path / "o"),
                     "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'stiffness'" in err


def test_the_shipped_grid_finds_what_the_guide_says():
    """scenes/sweeps/modes_joints.toml evaluated serially: the guide's best (30.8 Hz, 64.8 N/um
    at 8 deg, 56 deg, 1.0 m), worst (9.5 Hz, 9.2 N/um at 24 deg, 36 deg, 1.0 m) and shipped
    layout (26.8 Hz, 47.9 N/um), every point ok."""
    from stewart_sim.studies.sweep.evaluate import evaluate_batch

    grid = load_grid(GRID)
    rows = evaluate_batch(EvalSpec("modes", read_scene_dict(SIM)), list(grid.points()))
    assert all(r["status"] == "ok" for r in rows)

    def stated(r):
        return (r["pairs.base_half_angle"], r["pairs.platform_half_angle"],
                r["pairs.platform_radius"], round(r["lowest_hz"], 1), round(r["weakest_n_per_um"], 1))

    by_f = sorted(rows, key=lambda r: r["lowest_hz"])
    assert stated(by_f[-1]) == (8.0, 56.0, 1.0, 30.8, 64.8)
    assert stated(by_f[0]) == (24.0, 36.0, 1.0, 9.5, 9.2)
    (own,) = [r for r in rows if stated(r)[:3] == (12.0, 48.0, 1.4)]
    assert stated(own)[3:] == (26.8, 47.9)
