"""Per-leg friction end to end: a scene whose six legs have six different viscous frictions gives,
through `inverse` (the CLI), `simulate`, the exported FMU (fmpy) and `run`, forces that differ leg
by leg exactly as the model says. Checked against scenes where only one leg has friction: by
linearity, the all-legs scene's forces minus the frictionless scene's equal the sum of the
single-leg scenes' differences, each of which lies on its own leg only and equals
viscous_i * ldot_i there (the micro scene has no Coulomb friction)."""
from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.io import FORCE_COLUMNS, POSE, named_array, trajectory_table, write_csv
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.plant import Plant
from stewart_sim import cli
from tests.helpers import host_binary_only

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
VISCOUS = (1.0, 2.5, 4.0, 5.5, 7.0, 8.5)   # N s/m, legs 1..6
REL = 1e-12


def _scene(folder: Path, name: str, viscous) -> Path:
    """The micro scene with another [friction] viscous (a number, or six)."""
    text = MICRO.read_text()
    value = repr(float(viscous)) if np.ndim(viscous) == 0 else "[" + ", ".join(map(repr, viscous)) + "]"
    text, n = re.subn(r"(?m)^viscous = .*$", f"viscous = {value}", text)
    assert n == 1
    path = folder / f"{name}.toml"
    path.write_text(text.replace('name = "', f'name = "{name}-', 1))
    return path


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> dict[str, Path]:
    """all: six frictions; none: no viscous friction; leg<i>: only leg i's."""
    folder = tmp_path_factory.mktemp("per_leg")
    out = {"all": _scene(folder, "all", VISCOUS), "none": _scene(folder, "none", 0.0)}
    for i in range(6):
        out[f"leg{i + 1}"] = _scene(folder, f"leg{i + 1}", [v if k == i else 0.0 for k, v in enumerate(VISCOUS)])
    return out


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    data = np.array([[float(c) for c in row] for row in rows[1:]])
    return {name: data[:, k] for k, name in enumerate(rows[0])}


def legs(table: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.column_stack([table[f"{prefix}{i}"] for i in range(1, 7)])


def check_leg_by_leg(forces: dict[str, np.ndarray], ldot: np.ndarray | None = None) -> None:
    """forces[scene] (N, 6): the single-leg differences lie on their leg (equal to
    viscous_i * ldot_i there when ldot is given) and sum to the all-legs difference."""
    base = forces["none"]
    scale = np.max(np.abs(forces["all"]))
    total = np.zeros_like(base)
    for i in range(6):
        d = forces[f"leg{i + 1}"] - base
        assert np.all(np.delete(d, i, axis=1) == 0.0), f"leg {i + 1}'s friction reached another leg"
        assert np.max(np.abs(d[:, i])) > 1e-6 * scale, f"leg {i + 1}: no friction"
        if ldot is not None:
            np.testing.assert_allclose(d[:, i], VISCOUS[i] * ldot[:, i], rtol=0, atol=REL * scale)
        total += d
    np.testing.assert_allclose(forces["all"] - base, total, rtol=0, atol=REL * scale)
    assert not np.allclose(forces["all"][:, 0] - base[:, 0], forces["all"][:, 1] - base[:, 1])


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory) -> tuple[Path, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A smooth 0.5 s move from rest at home, at 20 kHz (fine: simulate holds each sample's
    forces), cosines on every pose coordinate."""
    model = load_scene(MICRO)
    t = np.linspace(0.0, 0.5, 10001)
    amp = np.array([2e-3, 1.5e-3, 1e-3, 0.02, 0.015, 0.03])
    w = 2 * np.pi * np.array([2.0, 3.0, 2.5, 1.5, 2.0, 3.5])
    c = 1.0 - np.cos(w * t[:, None])          # from rest at home, as simulate starts
    q = model.home + amp * c
    qd = amp * w * np.sin(w * t[:, None])
    qdd = amp * w**2 * (1.0 - c)
    path = tmp_path_factory.mktemp("traj") / "move.csv"
    write_csv(path, trajectory_table(t, q, qd, qdd))
    return path, t, q, qd, qdd


@pytest.fixture(scope="module")
def inverse_tables(scenes, trajectory, tmp_path_factory) -> dict[str, dict[str, np.ndarray]]:
    folder = tmp_path_factory.mktemp("inverse")
    out = {}
    for name, scene in scenes.items():
        path = folder / f"{name}.csv"
        assert cli.main(["inverse", str(scene), "--trajectory", str(trajectory[0]), "--out",
                         str(path), "--parts", "--no-view"]) == 0
        out[name] = read_csv(path)
    return out


def test_scene_declares_six_values(scenes):
    model = load_scene(scenes["all"])
    assert model.friction.viscous == VISCOUS
    np.testing.assert_array_equal(model.friction.viscous_legs, VISCOUS)
    assert load_scene(scenes["none"]).friction.viscous == 0.0


def test_inverse_cli_forces_differ_leg_by_leg(inverse_tables, trajectory):
    _, _, q, qd, _ = trajectory
    ldot = inverse_kinematics(load_scene(MICRO), q, qd).rates
    check_leg_by_leg({k: legs(v, "sigma") for k, v in inverse_tables.items()}, ldot)
    # the friction part of the breakdown is viscous_i * ldot_i, leg by leg
    np.testing.assert_allclose(legs(inverse_tables["all"], "friction"), np.asarray(VISCOUS) * ldot,
                               rtol=0, atol=REL * np.max(np.abs(legs(inverse_tables["all"], "sigma"))))


def test_simulate_applies_each_legs_own_friction(scenes, inverse_tables, trajectory, tmp_path):
    """simulate(scene, inverse(scene)) moves the six-friction plant as the frictionless plant
    moves under its own inverse forces (their hold errors alike), while the six-friction plant
    under the frictionless forces does not: the plant applies each leg's own friction, the
    one inverse computed."""
    pose = {}
    for scene, forces in (("all", "all"), ("none", "none"), ("all", "none")):
        out = tmp_path / f"{scene}-{forces}"
        force_file = tmp_path / f"{forces}.csv"
        write_csv(force_file, named_array({c: inverse_tables[forces][c] for c in FORCE_COLUMNS}))
        assert cli.main(["simulate", str(scenes[scene]), "--forces", str(force_file), "--out", str(out)]) == 0
        motion = read_csv(out / "motion.csv")
        pose[scene, forces] = np.column_stack([motion[c] for c in POSE])
    same = np.max(np.abs(pose["all", "all"] - pose["none", "none"]))
    unbalanced = np.max(np.abs(pose["all", "none"] - pose["none", "none"]))
    assert same < 0.02 * unbalanced


@pytest.fixture(scope="module")
def fmus(scenes, tmp_path_factory) -> dict[str, Path]:
    """The exported FMUs (FMI 2.0) of the six-friction scene and of the frictionless one."""
    folder = tmp_path_factory.mktemp("fmu")
    with host_binary_only():   # imported here (fmpy, run --fmu): the Windows DLL is not used
        return {name: export_fmu(scenes[name], folder / f"{name}.fmu") for name in ("all", "none")}


def test_fmu_friction_outputs_leg_by_leg(scenes, fmus):
    """The exported FMU of the six-friction scene declares friction.viscous[1..6] and its
    force.friction[i] is viscous_i * ldot[i], bit for bit the Plant's; a one-number scene keeps
    the scalar parameter friction.viscous. The single-leg scenes are that FMU with its six
    parameters set to theirs (one export: each export compiles the C core), against the Plant
    of each single-leg scene file."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    outputs = {}
    cases = [("all", None), ("none", None)]
    cases += [(f"leg{i + 1}", [v if k == i else 0.0 for k, v in enumerate(VISCOUS)])
              for i in range(6)]
    unzipped = {name: extract(str(path)) for name, path in fmus.items()}
    for name, viscous_set in cases:
        source = "none" if name == "none" else "all"
        md = read_model_description(str(fmus[source]))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        start = {v.name: v.start for v in md.modelVariables}
        if name == "all":
            assert [float(start[f"friction.viscous[{i}]"]) for i in range(1, 7)] == list(VISCOUS)
            assert "friction.viscous" not in vr
        if name == "none":
            assert "friction.viscous" in vr and "friction.viscous[1]" not in vr
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped[source],
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        model = load_scene(scenes[name])
        plant = Plant(model)
        fmu.instantiate()
        if viscous_set is not None:
            fmu.setReal([vr[f"friction.viscous[{i}]"] for i in range(1, 7)], viscous_set)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        plant.setup_experiment(0.0)
        plant.enter_initialization_mode()
        plant.exit_initialization_mode()
        sigma_vr = [vr[f"sigma[{i}]"] for i in range(1, 7)]
        hold = np.array(fmu.getReal(sigma_vr))
        names = [f"ldot[{i}]" for i in range(1, 7)] + [f"force.friction[{i}]" for i in range(1, 7)]
        rows, h = [], 1e-3
        for k in range(40):
            sigma = hold * (1.0 + 0.05 * np.sin(0.3 * k + np.arange(6)))
            fmu.setReal(sigma_vr, list(sigma))
            fmu.doStep(k * h, h)
            plant.set_force(sigma)
            plant.do_step(k * h, h)
            got = np.array(fmu.getReal([vr[n] for n in names]))
            assert np.array_equal(got[6:], plant.outputs.parts["friction"]), name
            rows.append(got)
        fmu.terminate()
        fmu.freeInstance()
        rows = np.array(rows)
        ldot, friction = rows[:, :6], rows[:, 6:]
        viscous = model.friction.viscous_legs
        np.testing.assert_allclose(friction, viscous * ldot, rtol=0, atol=REL * np.max(np.abs(friction)) + 1e-300)
        outputs[name] = friction
    # the same inputs, different motions: the friction of leg i is only ever viscous_i * ldot_i
    assert np.max(np.abs(outputs["all"])) > 0 and np.all(outputs["none"] == 0.0)


def test_run_feedforward_forces_differ_leg_by_leg(scenes, fmus, tmp_path):
    """`run` with the Kane feedforward: its feedforward voltages carry each leg's own friction
    force (linear in it), and the FMU plant runs the six-friction scene as the in-process one.
    The eight scenes' loops run as `run` runs them (controller.cosim.run_closed_loop on the
    scene's controller with --feedforward kane, the demonstration reference and the scene's
    [solver], as stewart_sim.closed_loop.run_files.run_closed_loop_files calls it) without the three
    plots each; the command itself runs the six-friction scene, and its run.csv is that loop's
    table."""
    from dataclasses import replace

    from controller.cosim import run_closed_loop
    from controller.moves import run_reference
    from stewart_sim.scene.load import load

    v_ff = {}
    for name, scene in scenes.items():
        loaded = load(scene)
        config = replace(loaded.require_controller(), feedforward="kane")
        traj = run_reference(loaded.model, config, 1.0)
        result = run_closed_loop(loaded.model, config, traj, options=loaded.solver)
        v_ff[name] = legs(result.table, "v_ff")
    check_leg_by_leg(v_ff)
    assert cli.main(["run", str(scenes["all"]), "--out", str(tmp_path / "all"), "--duration", "1.0",
                     "--feedforward", "kane", "--no-view"]) == 0
    assert np.array_equal(legs(read_csv(tmp_path / "all" / "run.csv"), "v_ff"), v_ff["all"])
    fmu = fmus["all"]
    assert cli.main(["run", str(scenes["all"]), "--out", str(tmp_path / "fmu"), "--duration", "1.0",
                     "--feedforward", "kane", "--no-view", "--fmu", str(fmu)]) == 0
    loc, via_fmu = read_csv(tmp_path / "all" / "run.csv"), read_csv(tmp_path / "fmu" / "run.csv")
    assert np.max(np.abs(legs(via_fmu, "l") - legs(loc, "l"))) <= 1e-9


def test_scene_info_paper_and_compare_accept_a_per_leg_scene(scenes, tmp_path, capsys):
    """scene-info lists the six values; the paper and compare studies run on the scene (compare
    sweeps the gear ratio: all six legs' m_d scale alike) and their reports show the six."""
    assert cli.main(["scene-info", str(scenes["all"])]) == 0
    out = capsys.readouterr().out
    assert "viscous [1, 2.5, 4, 5.5, 7, 8.5] (legs 1..6) N s/m" in out
    assert cli.main(["paper", str(scenes["all"]), "--out", str(tmp_path / "paper"), "--no-view"]) == 0
    assert "viscous [1, 2.5, 4, 5.5, 7, 8.5] (legs 1..6)" in (tmp_path / "paper" / "report.md").read_text()
    assert cli.main(["compare", str(scenes["all"]), "--out", str(tmp_path / "compare"), "--points", "2"]) == 0
    assert (tmp_path / "compare" / "report.md").exists()


@pytest.mark.parametrize("value, words", [([1.0] * 5, "one number, or six (one per leg), got 5"),
                                          ([1.0, 2.0, -0.5, 1.0, 1.0, 1.0], "must be >= 0"),
                                          ([1.0, 2.0, "x", 1.0, 1.0, 1.0], "must be numbers")])
def test_bad_per_leg_values_name_the_key(value, words):
    from stewart_fmu.errors import SceneError
    from stewart_fmu.scene import read_scene_dict, scene_from_dict

    data = read_scene_dict(MICRO)
    data["friction"]["viscous"] = value
    with pytest.raises(SceneError, match="friction.viscous") as info:
        scene_from_dict(data)
    assert words in str(info.value)
