"""A scene read once (stewart_sim/scene/load.py): every table parsed at load, any key no command
reads refused with one line naming the dotted key (exit 2) by every command; [solver] is the
in-process plant's integrator for `run` and `simulate`."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controller.config import controller_config
from stewart_fmu import SceneError, load_scene, scene_from_dict
from stewart_fmu.stability import default_options
from stewart_sim import cli
from stewart_sim.scene.cueing_config import cueing_config, optimal_options
from stewart_sim.scene.load import load, scene_of
from tests.helpers import scene_dict

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
SHIPPED = sorted(p for d in ("scenes", "examples") for p in (ROOT / d).rglob("*.toml")
                 if "[geometry]" in p.read_text())


def _scene(tmp_path: Path, tail: str) -> Path:
    scene = tmp_path / "scene.toml"
    scene.write_text(MICRO.read_text() + "\n" + tail)
    return scene


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("command", ["scene-info", "run", "simulate", "inverse"])
def test_a_typo_in_solver_is_one_line_naming_the_key(tmp_path, capsys, command) -> None:
    scene = _scene(tmp_path, "[solver]\nrtoll = 1e-9\n")
    extra = {"run": ["--out", str(tmp_path / "o")],
             "simulate": ["--forces", str(tmp_path / "f.csv"), "--out", str(tmp_path / "o")],
             "inverse": ["--trajectory", str(tmp_path / "t.csv"), "--out", str(tmp_path / "f.csv")],
             }.get(command, [])
    assert cli.main([command, str(scene), *extra]) == 2
    assert "scene key 'solver.rtoll': unknown key" in _one_line(capsys)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("table", ["link", "device", "trajectory"])
def test_tables_no_command_reads_are_refused(tmp_path, capsys, table) -> None:
    scene = _scene(tmp_path, f"[{table}]\nrate = 1.0\n")
    assert cli.main(["scene-info", str(scene)]) == 2
    assert f"scene key '{table}': unknown key" in _one_line(capsys)


def test_every_table_is_parsed_once_at_load() -> None:
    """The typed objects are those each table's reader builds; [solver] absent: the plant's
    default integrator."""
    scene = load(MICRO)
    model = scene.model
    assert scene.controller == controller_config(model)
    assert scene.cueing == cueing_config(model) and scene.optimal == optimal_options(model)
    assert scene.case is None and not scene.has_solver
    assert scene.solver == default_options(model)


def test_solver_table_sets_the_in_process_integrator(tmp_path, capsys) -> None:
    scene = _scene(tmp_path, '[solver]\nmethod = "dopri5"\nrtol = 1e-9\nmax_step = 5e-4\n')
    s = load(scene)
    assert s.has_solver
    assert s.solver == replace(default_options(s.model), method="dopri5", rtol=1e-9,
                               max_step=5e-4)
    assert cli.main(["scene-info", str(scene)]) == 0
    assert "solver: dopri5, rtol 1e-09" in capsys.readouterr().out


@pytest.mark.parametrize("bad, key", [('method = "Radau"', "solver.method"),
                                      ("atol = -1.0", "solver.atol"),
                                      ("max_step = true", "solver.max_step")])
def test_solver_values_are_checked(tmp_path, capsys, bad, key) -> None:
    assert cli.main(["scene-info", str(_scene(tmp_path, f"[solver]\n{bad}\n"))]) == 2
    assert f"scene key '{key}'" in _one_line(capsys)


def test_run_uses_the_solver_table(tmp_path) -> None:
    """`run` in-process integrates with [solver]: euler with a larger step gives another run
    than the default rk4; --fmu refuses a scene with [solver] (the FMU has its own)."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.main(["run", str(MICRO), "--out", str(a), "--duration", "0.2", "--no-view"]) == 0
    scene = _scene(tmp_path, '[solver]\nmethod = "euler"\n')
    assert cli.main(["run", str(scene), "--out", str(b), "--duration", "0.2", "--no-view"]) == 0
    ra = np.loadtxt(a / "run.csv", delimiter=",", skiprows=1)
    rb = np.loadtxt(b / "run.csv", delimiter=",", skiprows=1)
    assert ra.shape == rb.shape and not np.array_equal(ra, rb)
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "c"), "--fmu", "x.fmu"]) == 2


def test_shipped_scenes_load() -> None:
    assert SHIPPED
    for path in SHIPPED:
        assert load(path).model.name == load_scene(path).name


GOOD_CASE = {"kind": "stiff", "description": "", "motion": "hold", "duration": 1.0,
             "expect": "ok"}


@pytest.mark.parametrize("mutate, key", [
    (lambda d: d.update(case={"kind": "stiff"}), "case.description"),
    (lambda d: d.update(case={"kind": "odd", "description": "", "motion": "hold",
                              "duration": 1.0, "expect": "ok"}), "case.kind"),
    (lambda d: d.update(case={"kind": "stiff", "description": "", "motion": "ramp",
                              "duration": 1.0, "expect": "ok"}), "case.target"),
    (lambda d: d.update(case={**GOOD_CASE, "durations": 1.0}), "case.durations"),
    (lambda d: d.update(case={**GOOD_CASE, "duration": 0.0}), "case.duration"),
    (lambda d: d.update(case={**GOOD_CASE, "step": True}), "case.step"),
    (lambda d: d.update(case={**GOOD_CASE, "force_scale": float("inf")}), "case.force_scale"),
    (lambda d: d.update(case={**GOOD_CASE, "start_rates": [0.0] * 5}), "case.start_rates"),
    (lambda d: (d.pop("controller"), d.update(case={**GOOD_CASE, "motion": "closed_loop"})),
     "case.motion"),
])
def test_scene_rejects_bad_case_tables(mutate, key):
    """A bad [case] table is refused at load (stewart_sim.scene.case_config.case_of) naming the
    key."""
    d = scene_dict("micro")
    d["transmission"] = {"stiffness": 1e6, "damping": 1.0}
    mutate(d)
    with pytest.raises(SceneError) as exc:
        scene_of(scene_from_dict(d))
    assert exc.value.key == key


def test_a_good_case_table_loads_with_its_defaults():
    d = scene_dict("micro")
    d["case"] = {**GOOD_CASE, "start_rates": [0.0, 0.0, 0.0, 0.0, 0.0, 0.01]}
    case = scene_of(scene_from_dict(d)).case
    assert (case.kind, case.motion, case.duration, case.expect) == ("stiff", "hold", 1.0, "ok")
    assert case.step == 1e-3 and case.force_scale == 1.0 and case.start_rates[5] == 0.01
