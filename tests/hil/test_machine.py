"""The emulated device as the machine: a hidden true scene behind its plant (hil.truth) and the
sensors of its reports (hil.sensors), driven in process in lockstep (hil.client's direct loop,
bit for bit the loop over the link). Fixed seeds; no wall clock."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from controller.config import controller_config  # noqa: E402
from controller.trajectory import Trajectory  # noqa: E402
from hil.client import link_reference, run_lockstep_direct  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.sensors import SensorConfig, sensor_config  # noqa: E402
from hil.truth import check_truth  # noqa: E402
from stewart_fmu.dynamics import inverse_dynamics  # noqa: E402
from stewart_fmu.errors import SceneError, SceneKeyError  # noqa: E402
from stewart_fmu.kinematics import forward_kinematics, inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene, scene_from_dict  # noqa: E402
from tests.helpers import scene_dict  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
DURATION = 1.0   # s of device time per run: 1000 lockstep ticks
AMPLITUDE = np.array([0.01, 0.01, 0.008, 0.08, 0.08, 0.1])   # m, rad: inside the stroke
FREQUENCY = np.array([1.3, 1.7, 2.1, 1.1, 1.9, 2.3])         # Hz


def truth_dict(sensors: dict | None = None) -> dict:
    """The micro-manipulator with every inertial and friction parameter 15-30 % off."""
    d = scene_dict("micro")
    d["name"] = "micro-manipulator (truth)"
    d["platform"].update(mass=0.62, inertia=[7.2e-4, 5.6e-4, 1.2e-3])
    d["legs"].update(lower_mass=0.08, upper_mass=0.05, lower_com=0.045)
    d["drive"]["rotor_inertia"] = 1.25e-6
    d["friction"]["viscous"] = 6.5
    if sensors is not None:
        d["sensors"] = sensors
    return d


def excitation(model, rate: float, duration: float = DURATION) -> Trajectory:
    """q = home + a (1 - cos w t): at rest at home at t = 0, as the device starts."""
    t = np.arange(int(round(duration * rate)) + 1) / rate
    w = 2 * np.pi * FREQUENCY
    arg = w * t[:, None]
    return Trajectory(t, model.home + AMPLITUDE * (1 - np.cos(arg)), AMPLITUDE * w * np.sin(arg),
                      AMPLITUDE * w**2 * np.cos(arg))


@pytest.fixture(scope="module")
def setting():
    model = load_scene(SCENE)
    config = controller_config(model)
    return model, config, link_reference(model, config, excitation(model, config.rate))


def record(setting, truth=None, sensors: SensorConfig | None = None):
    """(LinkRun with currents, the device after the run)."""
    model, config, ref = setting
    dev = Device(model, config, lockstep=True, truth=truth, sensors=sensors)
    return run_lockstep_direct(dev, ref, currents=True), dev


def columns(table: np.ndarray, name: str) -> np.ndarray:
    return np.column_stack([table[f"{name}{i}"] for i in range(1, 7)])


def mid_step_forces(model, run, models):
    """Inverse dynamics of each model on the recorded motion, at the middle of each step.

    Row k holds the state after step k (time t_(k+1)) and the rack force held over that step
    (the zero-order hold of the mean motor torque). The pose comes from the recorded lengths
    (forward kinematics), the pose rates from the recorded leg rates (ldot = (dl/dq) qd, dl/dq
    column by column from inverse_kinematics); over one step of constant force the mean
    acceleration is (qd_(k+1) - qd_k) / dt, and the state at mid-step is the mean of its ends to
    O(dt^2)."""
    table = run.table
    lengths = np.vstack([inverse_kinematics(model, model.home).lengths, columns(table, "l")])
    rates = np.vstack([np.zeros(6), columns(table, "ldot")])
    q = [model.home.copy()]
    for l in lengths[1:]:
        q.append(forward_kinematics(model, l, guess=q[-1]))
    q = np.array(q)
    qd = np.empty_like(q)
    for j in range(len(q)):
        dl_dq = np.column_stack([inverse_kinematics(model, q[j], qd=e, with_cond=False).rates
                                 for e in np.eye(6)])
        qd[j] = np.linalg.solve(dl_dq, rates[j])
    dt = float(np.diff(table["time"])[0])
    mid = ((q[1:] + q[:-1]) / 2, (qd[1:] + qd[:-1]) / 2, np.diff(qd, axis=0) / dt)
    return [inverse_dynamics(m, *mid) for m in models]


# --- the truth scene behind the plant ---------------------------------------------------------

def test_the_plant_is_the_truth_scenes(setting) -> None:
    """The recorded rack forces are the truth's inverse dynamics on the recorded motion, not the
    believed scene's. Tolerance 1e-5 of the peak: the mid-step evaluation errs by O(dt^2) of the
    forces' second derivative (measured 5e-7 at these frequencies); the scene's forces differ by
    about 20 % of the peak with parameters 15-30 % off. Without a truth the same evaluation
    matches the scene to the same tolerance (the method, checked on its own)."""
    model = setting[0]
    truth = scene_from_dict(truth_dict(), source="truth.toml")
    run, _ = record(setting, truth)
    sigma = columns(run.table, "force")
    peak = float(np.max(np.abs(sigma)))
    by_truth, by_scene = mid_step_forces(model, run, (truth, model))
    assert np.max(np.abs(sigma - by_truth)) <= 1e-5 * peak
    assert np.max(np.abs(sigma - by_scene)) >= 0.1 * peak

    plain, _ = record(setting)
    sigma = columns(plain.table, "force")
    (by_scene,) = mid_step_forces(model, plain, (model,))
    assert np.max(np.abs(sigma - by_scene)) <= 1e-5 * float(np.max(np.abs(sigma)))


def test_truth_geometry_must_be_the_scenes() -> None:
    """Gravity, joints, home, stroke, the drive's ratio and the presence of [drive] are refused
    when they differ, naming the truth's key; friction present in the truth only is the
    machine's business."""
    model = load_scene(SCENE)
    cases = {"gravity": ("gravity", [0.0, 0.0, -9.8]),
             "geometry.base_joints": ("geometry", "base_joints"),
             "geometry.platform_joints": ("geometry", "platform_joints"),
             "geometry.home": ("geometry", "home"),
             "geometry.leg_min": ("geometry", "leg_min"),
             "geometry.leg_max": ("geometry", "leg_max"),
             "drive.gear_ratio": ("drive", "gear_ratio"),
             "drive.pinion_radius": ("drive", "pinion_radius")}
    for key, (table, what) in cases.items():
        d = truth_dict()
        if table == "gravity":
            d["gravity"] = what
        elif what in ("base_joints", "platform_joints"):
            d[table][what] = copy.deepcopy(d[table][what])
            d[table][what][2][0] += 1e-6
        elif what == "home":
            d[table][what] = [0.0, 0.0, 0.121, 0.0, 0.0, 0.0]
        else:
            d[table][what] *= 1.001
        with pytest.raises(SceneError) as err:
            check_truth(model, scene_from_dict(d, source="truth.toml"))
        assert err.value.key == key and str(err.value).startswith("truth.toml: ")
    d = truth_dict()
    del d["drive"]
    with pytest.raises(SceneError) as err:
        check_truth(model, scene_from_dict(d, source="truth.toml"))
    assert err.value.key == "drive"
    d = truth_dict()
    d["friction"]["coulomb"] = 0.3
    check_truth(model, scene_from_dict(d))                  # allowed: a parameter
    check_truth(model, model)                               # the scene is its own truth


# --- the sensors of the reports ---------------------------------------------------------------

def test_sensors_quantise_and_add_noise_to_the_reports_only(setting) -> None:
    """Encoder steps of 1 um and Gaussian noise on forces and currents change what the device
    reports, not its plant or control (the plant ends bit for bit where the ideal one does).
    Noise std within 3 % of the configured one over 6000 samples (the relative spread of a
    sample std is 1 / sqrt(2 N) = 0.9 %), mean within 4 sigma / sqrt(N)."""
    truth = scene_from_dict(truth_dict(), source="truth.toml")
    res, f_noise, i_noise = 1e-6, 0.5, 1e-3
    ideal, dev0 = record(setting, truth)
    real, dev1 = record(setting, truth, SensorConfig(res, f_noise, i_noise, 0.0, seed=11))
    assert np.array_equal(dev0.plant.outputs.q, dev1.plant.outputs.q)
    assert np.array_equal(dev0.plant.rack_force, dev1.plant.rack_force)

    l0, l1 = columns(ideal.table, "l"), columns(real.table, "l")
    steps = l1 / res
    assert np.max(np.abs(steps - np.round(steps))) < 1e-6          # whole encoder steps
    assert np.max(np.abs(l1 - l0)) <= res / 2 * (1 + 1e-9)
    assert len(np.unique(l1)) < len(np.unique(l0))                 # the grid is visible
    assert np.array_equal(columns(real.table, "ldot"), columns(ideal.table, "ldot"))

    for noise, std in ((columns(real.table, "force") - columns(ideal.table, "force"), f_noise),
                       (real.currents - ideal.currents, i_noise)):
        n = noise.size
        assert abs(np.std(noise) / std - 1) < 0.03
        assert abs(np.mean(noise)) < 4 * std / np.sqrt(n)
    # float32 currents on DRIVE_STATUS: the ideal ones are the motor's to 1e-7 relative
    assert np.all(np.isfinite(ideal.currents))

    again, _ = record(setting, truth, SensorConfig(res, f_noise, i_noise, 0.0, seed=11))
    assert np.array_equal(columns(again.table, "force"), columns(real.table, "force"))
    other, _ = record(setting, truth, SensorConfig(res, f_noise, i_noise, 0.0, seed=12))
    assert not np.array_equal(columns(other.table, "force"), columns(real.table, "force"))


def test_latency_delays_the_reports_by_whole_ticks(setting) -> None:
    """latency = 3 ticks: row k reports what the ideal sensors reported at row k - 3; the first
    rows repeat the state the device started in (at rest at home)."""
    model, config, _ = setting
    n = 3
    ideal, _ = record(setting)
    late, _ = record(setting, sensors=SensorConfig(latency=n / config.rate))
    for name in ("l", "ldot", "force"):
        a, b = columns(ideal.table, name), columns(late.table, name)
        assert np.array_equal(b[n:], a[:-n])
    assert np.array_equal(late.currents[n:], ideal.currents[:-n])
    first = columns(late.table, "l")[:n]
    assert np.allclose(first, inverse_kinematics(model, model.home).lengths, rtol=0, atol=1e-15)
    assert np.all(columns(late.table, "ldot")[:n] == 0)
    assert np.array_equal(late.table["time"], ideal.table["time"])   # stamped when sent


def test_latency_must_be_whole_ticks() -> None:
    model = load_scene(SCENE)
    with pytest.raises(SceneKeyError) as err:
        Device(model, lockstep=True, sensors=SensorConfig(latency=0.0015))
    assert err.value.key == "sensors.latency" and "whole number" in str(err.value)


@pytest.mark.parametrize("key, value", [
    ("encoder_resolution", -1e-6), ("encoder_resolution", 0.01), ("force_noise", float("nan")),
    ("force_noise", True), ("current_noise", -0.1), ("latency", 2.0), ("latency", "1 ms"),
    ("seed", 1.5), ("seed", -1), ("colour", 1)])
def test_sensor_table_refusals_name_the_key(key, value) -> None:
    d = scene_dict("micro")
    d["sensors"] = {key: value}
    with pytest.raises(SceneKeyError) as err:
        sensor_config(scene_from_dict(d, source="s.toml"))
    assert err.value.key == f"sensors.{key}"
    d["sensors"] = 3
    with pytest.raises(SceneKeyError) as err:
        sensor_config(scene_from_dict(d, source="s.toml"))
    assert err.value.key == "sensors"


def test_sensor_table_defaults_are_ideal() -> None:
    d = scene_dict("micro")
    assert sensor_config(scene_from_dict(d)).ideal
    d["sensors"] = {"seed": 5}
    assert sensor_config(scene_from_dict(d)) == SensorConfig(seed=5)
    d["sensors"] = {"encoder_resolution": 1e-6, "force_noise": 0.1, "current_noise": 0.0,
                    "latency": 0.002, "seed": 3}
    assert sensor_config(scene_from_dict(d)) == SensorConfig(1e-6, 0.1, 0.0, 0.002, 3)


def test_the_shipped_machine_is_a_truth_of_the_micro_manipulator() -> None:
    """scenes/machines/micro_manipulator_truth.toml: the scene's geometry and drive ratio, every
    inertial and friction parameter 10-30 % off (Coulomb friction the scene leaves out), real
    sensors."""
    model = load_scene(SCENE)
    truth = load_scene(ROOT / "scenes" / "machines" / "micro_manipulator_truth.toml")
    check_truth(model, truth)
    pairs = [(model.platform_mass, truth.platform_mass),
             (model.platform_inertia, truth.platform_inertia),
             (model.drive.reflected_masses, truth.drive.reflected_masses),
             (model.friction.viscous_legs, truth.friction.viscous_legs)]
    pairs += [(getattr(model.legs, k), getattr(truth.legs, k)) for k in
              ("lower_mass", "lower_com", "lower_inertia", "upper_mass", "upper_com",
               "upper_inertia")]
    for mine, theirs in pairs:
        off = np.abs(np.asarray(theirs) / np.asarray(mine) - 1)
        assert np.all((off >= 0.1 - 1e-12) & (off <= 0.3 + 1e-12)), (mine, theirs)
    assert np.all(model.friction.coulomb_legs == 0) and np.all(truth.friction.coulomb_legs > 0)
    s = sensor_config(truth)
    assert s.encoder_resolution == 1e-6 and s.force_noise > 0 and not s.ideal
