"""`stewart-sim cue` (stewart_sim/commands/cue.py, cueing/study.py, report.py): every shipped
vehicle motion on the shipped motion simulator, the files and their agreement with the rest of the
tool (the written trajectory through `inverse` gives the written forces), a motion made too
strong reported with its first sample and leg, the closed loop tracking the cue, bad input."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import io, load_scene
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim import cli
from stewart_sim.cueing.motion import VehicleMotion, read_motion
from stewart_sim.cueing.report import write_cue_report
from stewart_sim.cueing.study import cue_study, make_cue, resample
from stewart_sim.scene.cueing_config import cueing_config
from stewart_sim.scene.load import scene_of

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"
MOTIONS = sorted((ROOT / "scenes" / "motions").glob("*.csv"))
G = 9.81
# Cues of one motion at 100 Hz and at the controller's 1 kHz: the filters are exact for the
# linearly interpolated input; the tilt-rate limiter and Heun's Euler-angle step work per sample
# (measured on the shipped motions: 2.6e-4 m, 4.9e-4 rad).
RATE_AGREEMENT = 1e-3


@pytest.fixture(scope="module")
def model():
    return load_scene(SIM)


def test_three_motions_are_shipped():
    assert {p.stem for p in MOTIONS} >= {"braking_car", "lane_change", "takeoff"}


@pytest.mark.parametrize("path", MOTIONS, ids=lambda p: p.stem)
def test_shipped_motion_is_flown_inside_every_limit(model, path, tmp_path):
    study = cue_study(scene_of(model), read_motion(path))
    run = study.runs[0]
    assert run.feasibility.violations == ()
    lengths = inverse_kinematics(model, run.cue.q).lengths   # independently of feasibility
    assert model.leg_min < lengths.min() and lengths.max() < model.leg_max
    names = {p.name for p in write_cue_report(study, tmp_path / "out", "t")}
    assert {"trajectory.csv", "forces.csv", "perception.csv", "summary.md",
            "cue_specific_force.png", "cue_angular_velocity.png", "cue_legs.png",
            "cue_forces.png"} <= names
    assert names == {p.name for p in (tmp_path / "out").iterdir()} - {".stewart-sim-set"}
    summary = (tmp_path / "out" / "summary.md").read_text()
    for part in ("Perceived-motion error", "False cues", "Workspace used", "Limits",
                 "Violations (classical): none"):
        assert part in summary


def test_written_trajectory_gives_the_written_forces_through_inverse(model, tmp_path):
    """trajectory.csv is the `inverse` command's input: its forces are forces.csv's."""
    study = cue_study(scene_of(model), read_motion(ROOT / "scenes" / "motions" / "lane_change.csv"))
    out = tmp_path / "out"
    write_cue_report(study, out, "t")
    t, q, qd, qdd = io.read_trajectory(out / "trajectory.csv")
    np.testing.assert_array_equal(q, study.runs[0].cue.q)        # repr-exact round trip
    forces = np.genfromtxt(out / "forces.csv", delimiter=",", names=True)
    sigma = np.column_stack([forces[f"sigma{i}"] for i in range(1, 7)])
    np.testing.assert_allclose(sigma, inverse_dynamics(model, q, qd, qdd), rtol=0, atol=1e-9)


def _braking(scale: float, n: int = 801, h: float = 0.01) -> VehicleMotion:
    t = np.arange(n) * h
    f = np.tile([0.0, 0.0, G], (n, 1))
    f[(t >= 1.0) & (t < 4.0), 0] = -scale
    return VehicleMotion(t, f, np.zeros((n, 3)))


def test_too_strong_a_motion_is_reported_at_its_first_sample_and_leg(model):
    """Scale a braking pulse with a stiffer washout until the stroke breaks: the first
    violation is the first sample where an independently computed leg length leaves it."""
    strong = replace(model, extra={**model.extra, "cueing": {
        "translational_gain": [1.0, 1.0, 1.0], "translational_limit": [40.0, 40.0, 40.0],
        "translational_frequency": [0.5, 0.5, 0.5], "translational_first_order": [0.1, 0.1, 0.1]}})
    found = None
    for scale in (2.0, 5.0, 10.0, 20.0, 40.0):
        study = cue_study(scene_of(strong), _braking(scale))
        stroke = [v for v in study.runs[0].feasibility.violations
                  if v.quantity.startswith("stroke")]
        if stroke:
            found = study, stroke
            break
    assert found is not None, "no scale up to 40 m/s^2 left the stroke"
    study, stroke = found
    lengths = inverse_kinematics(model, study.runs[0].cue.q).lengths
    outside = (lengths < model.leg_min) | (lengths > model.leg_max)
    first = int(np.argmax(outside.any(axis=1)))
    assert stroke[0].sample == first
    assert outside[first, stroke[0].leg - 1]
    assert stroke[0].t == study.runs[0].cue.t[first]


def test_tracking_runs_the_closed_loop_on_the_cue(model):
    motion = read_motion(ROOT / "scenes" / "motions" / "braking_car.csv")
    study = cue_study(scene_of(model), motion, track=True)
    tr = study.tracking
    assert tr is not None and study.tracking_note is None
    assert tr.table["time"][1] - tr.table["time"][0] == pytest.approx(1e-3)
    # the loop follows the cue: pose error far below the cue's own excursion (0.35 m, 9.6 deg)
    assert np.max(tr.summary.pose_max[:3]) < 5e-3
    assert np.max(tr.summary.pose_max[3:]) < np.radians(0.1)
    assert tr.summary.saturated_time == 0.0


def test_the_cue_at_the_controller_rate_agrees_with_the_sampled_one(model):
    config = cueing_config(model)
    for path in MOTIONS:
        motion = read_motion(path)
        coarse, _ = make_cue("classical", scene_of(model), config, motion)
        fine, _ = make_cue("classical", scene_of(model), config, resample(motion, 1000.0))
        k = np.round((coarse.t - coarse.t[0]) * 1000.0).astype(int)
        np.testing.assert_allclose(fine.t[k], coarse.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fine.q[k], coarse.q, rtol=0, atol=RATE_AGREEMENT)


# long: --compare on the shipped lane change with the default MPC (its summary's 240 MPC
# steps are asserted): ~15 s of CPU
@pytest.mark.long
@pytest.mark.numerics
def test_compare_writes_both_cues_and_both_fly_inside_the_limits(model, tmp_path):
    """--compare: the optimal cue beside the classical one; both inside every limit, the
    optimal one's QP record in the summary, its trajectory in the inverse format."""
    study = cue_study(scene_of(model), read_motion(ROOT / "scenes" / "motions" / "lane_change.csv"),
                      ("classical", "optimal"))
    classical, optimal = study.runs
    assert optimal.solver is not None and set(optimal.solver.status) == {"solved"}
    for run in study.runs:
        assert run.feasibility.violations == (), run.mode
    out = tmp_path / "out"
    write_cue_report(study, out, "t")
    t, q, _, _ = io.read_trajectory(out / "trajectory_optimal.csv")
    np.testing.assert_array_equal(q, optimal.cue.q)
    summary = (out / "summary.md").read_text()
    assert "Optimal cueing: 240 MPC steps" in summary
    assert "| optimal |" in summary and "Violations (optimal): none" in summary
    # the mode that optimises perception perceives the lane change's main axis better
    assert optimal.perception.rms_f[1] < classical.perception.rms_f[1]


def _cli(capsys, *args: str) -> tuple[int, str, str]:
    """`stewart-sim ARGS` in this process (cli.main, which the console script and
    `python -m stewart_sim` call): the exit status, stdout and stderr."""
    capsys.readouterr()
    status = cli.main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_writes_the_set_and_says_the_verdict(tmp_path, capsys):
    out = tmp_path / "cue"
    status, stdout, stderr = _cli(capsys, "cue", str(SIM), "--motion", str(MOTIONS[0]),
                                  "--out", str(out))
    assert status == 0, stderr
    # the braking car stays inside the mechanism's limits, not inside the live envelope's
    # (the device's setpoint stroke less the envelope's margin): cue-live limits it on a
    # simulated clock, and `cue` says so (live.preflight)
    line = next(x for x in stdout.splitlines() if x.startswith("classical: "))
    assert line.startswith("classical: inside the mechanism's limits, not the live margins: "
                           "cue-live's envelope: ") and "of 12501 samples limited (stroke " in line, line
    for name in ("trajectory.csv", "summary.md", "view.html"):
        assert (out / name).exists(), name
    assert "view.html: " in stdout and " frames at 30 frames/s from 1201 samples" in stdout


def test_cli_bad_motion_file_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,fx,fy,fz,wx,wy,wz\n0,0,0,9.81,0,0,0\n0.01,0,zero,9.81,0,0,0\n")
    out = tmp_path / "cue"
    status, _, stderr = _cli(capsys, "cue", str(SIM), "--motion", str(bad), "--out", str(out))
    assert status == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.csv" in lines[0] and "Traceback" not in stderr
    assert not out.exists()
