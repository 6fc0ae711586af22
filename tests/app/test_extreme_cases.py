"""Extreme scenes (scenes/extreme) and scales: each ends in its defined outcome, a correct
result with its condition number or a typed error at the first bad sample; never NaNs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import forward_dynamics, inverse_dynamics, inverse_kinematics, load_scene
from stewart_fmu.kinematics import COND_LIMIT
from stewart_sim.scene.case_config import case_of
from stewart_sim.scene.load import scene_of
from stewart_sim.studies.cases.outcome import case_trajectory, run_case
from stewart_sim.studies.cases.study import hour_drift
from tests.helpers import level_model

EXTREME = Path(__file__).resolve().parents[2] / "scenes" / "extreme"



def _case(model):
    """The model with its [case] and [controller] tables as run_case takes them."""
    scene = scene_of(model)
    return model, scene.case, scene.controller


def _round_trip_error(model, traj, forces) -> float:
    """max |forward(inverse) - qdd| relative to max |qdd|."""
    qdd = forward_dynamics(model, traj.q, traj.qd, forces)
    return float(np.max(np.abs(qdd - traj.qdd)) / np.max(np.abs(traj.qdd)))


@pytest.mark.parametrize("scene", sorted(p.name for p in EXTREME.glob("*.toml")))
def test_every_extreme_scene_has_its_defined_outcome(scene):
    """The outcome is the one the scene's [case] declares (simulated holds cut to 0.2 s); a
    failure names the sample and its time; results are finite."""
    model = load_scene(EXTREME / scene)
    case = case_of(model)
    result = run_case(*_case(model),
                      duration=min(case.duration, 0.2) if case.motion == "hold" else None)
    assert result.outcome == case.expect, result.error
    if case.expect != "ok":
        assert result.index is not None and result.time == pytest.approx(result.index * case.step)
        assert f"sample {result.index}" in str(result.error)
    for arr in (result.forces, result.states):
        assert arr is None or np.all(np.isfinite(arr))


def test_near_singular_pose_gives_correct_forces_with_their_condition_number():
    """1e-4 rad from Fichter's singularity cond(J) >= 1e4 is reported, and the forces are
    still the inverse of the forward dynamics to cond x 1e-13."""
    model = load_scene(EXTREME / "near_singular.toml")
    cond = inverse_kinematics(model, model.home).cond
    assert 1e4 <= cond < COND_LIMIT
    q = np.tile(model.home, (3, 1))
    qd = np.zeros((3, 6))
    qdd = np.array([[10.0, 0, 0, 0, 0, 0], [0, 0, 10.0, 0, 0, 0], [0, 0, 0, 0, 0, 8.0]])
    forces = inverse_dynamics(model, q, qd, qdd)
    back = forward_dynamics(model, q, qd, forces)
    assert np.max(np.abs(back - qdd)) <= cond * 1e-13 * np.max(np.abs(qdd))
    assert run_case(*_case(model), duration=0.02).cond_max >= 1e4


def test_singular_move_stops_at_the_first_sample_past_the_threshold():
    """The yaw move onto the singularity stops at the first sample whose cond(J) exceeds the
    threshold (found here independently), naming its index and time."""
    model = load_scene(EXTREME / "singular_move.toml")
    traj = case_trajectory(model, case_of(model))
    first = int(np.argmax(inverse_kinematics(model, traj.q).cond > COND_LIMIT))
    result = run_case(*_case(model))
    assert result.outcome == "SingularityError"
    assert (result.index, result.time) == (first, float(traj.t[first]))


def test_stroke_crossing_stops_at_the_first_sample_past_leg_max():
    """The heave stops at the first sample with a leg past leg_max (found independently)."""
    model = load_scene(EXTREME / "stroke_crossing.toml")
    traj = case_trajectory(model, case_of(model))
    first = int(np.argmax(np.any(inverse_kinematics(model, traj.q).lengths > model.leg_max,
                                 axis=1)))
    result = run_case(*_case(model))
    assert result.outcome == "StrokeLimitError"
    assert (result.index, result.time) == (first, float(traj.t[first]))


@pytest.mark.parametrize("axis, paper", [(0, 10.0), (3, 8.0)])
def test_hundred_times_the_paper_acceleration(axis, paper):
    """From rest the forces are affine in the acceleration: at t = 0, sigma(100 a) - sigma(0)
    = 100 (sigma(a) - sigma(0)) (1e-12 rel); the move then ends at the stroke with its time."""
    model = load_scene(EXTREME / "high_acceleration.toml")
    rest = np.zeros(6)
    a = np.zeros(6)
    a[axis] = paper
    s0 = inverse_dynamics(model, model.home, rest, rest)
    s1 = inverse_dynamics(model, model.home, rest, a)
    s100 = inverse_dynamics(model, model.home, rest, 100 * a)
    assert np.max(np.abs((s100 - s0) - 100 * (s1 - s0))) <= 1e-12 * np.max(np.abs(s100 - s0))
    result = run_case(*_case(model))
    assert result.outcome == case_of(model).expect == "StrokeLimitError"
    assert 0 < result.time < 0.1


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_micro_and_full_scale_paper_moves(name):
    """The paper's x move on the micro-manipulator and the full-size simulator: forces and
    their cond, the forward dynamics inverting them to 1e-9."""
    model = level_model(name, "full")
    t = np.arange(101) * 1e-3
    a = np.array([10.0, 0, 0, 0, 0, 0])
    q = model.home + 0.5 * np.outer(t**2, a)
    qd, qdd = np.outer(t, a), np.tile(a, (len(t), 1))
    forces = inverse_dynamics(model, q, qd, qdd)
    back = forward_dynamics(model, q, qd, forces)
    assert np.all(np.isfinite(forces))
    assert np.max(np.abs(back - qdd)) <= 1e-9 * np.max(np.abs(qdd))
    assert np.max(inverse_kinematics(model, q).cond) < 10.0


def test_massless_legs_are_the_platform_plus_drive_and_friction():
    """No [legs]: the forces are the platform-only forces plus m_d lddot plus viscous ldot,
    composed here from the platform-only model and the leg kinematics (1e-12 rel)."""
    model = load_scene(EXTREME / "massless_legs.toml")
    traj = case_trajectory(model, case_of(model))
    kin = inverse_kinematics(model, traj.q, traj.qd, traj.qdd)
    platform = inverse_dynamics(level_model("micro", "platform_only"), traj.q, traj.qd, traj.qdd)
    expect = (platform + model.drive.reflected_mass * kin.accelerations
              + model.friction.viscous * kin.rates)
    forces = run_case(*_case(model)).forces
    assert np.max(np.abs(forces - expect)) <= 1e-12 * np.max(np.abs(forces))


def test_long_run_drift_short_horizon():
    """The ceiling-mounted conservative hold over 20 s with RK4 at 1 ms: E - F . l drifts by
    less than 1e-9 of the peak kinetic energy, orientation by less than 1e-9 rad."""
    model = load_scene(EXTREME / "hour.toml")
    drift = hour_drift(model, case_of(model), duration=20.0)
    assert drift.energy_drift < 1e-9 and drift.orientation_drift < 1e-9
