"""Work-precision study (stewart_sim.studies.accuracy.study): fixed-step methods converge with their
theoretical order, the reference agrees with its second method, the command writes its files.

Open-loop case: the default scene (micro-manipulator: smooth right-hand side, no Coulomb
friction) driven by its demonstration forces plus a perturbation
(stewart_sim.studies.accuracy.study)."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu.integrators import FIXED_STEP
from stewart_sim.cli import main
from stewart_sim.studies.accuracy.study import (
    REFERENCE_TOLERANCE,
    convergence_orders,
    open_loop_case,
    open_loop_sweep,
    reference_solution,
    settings_for,
)

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
HORIZON = 0.5   # s: shorter than the command's default, same physics


@pytest.fixture(scope="module")
def study():
    """The case, its reference and the fixed-step sweeps (no adaptive methods: fast)."""
    model = load_scene(SCENE)
    case = open_loop_case(model, HORIZON)
    ref = reference_solution(case)
    sweep = {"rk4": (1, 2, 4, 8, 16), "euler": (1, 4, 16, 64, 256), "rtol": ()}
    settings = [o for o in settings_for(sweep, case.comm_step) if o.method in FIXED_STEP]
    return case, ref, open_loop_sweep(case, ref, settings, repeats=1)


def test_motion_is_nontrivial_and_inside_the_stroke(study):
    """The reference moves by millimetres and tenths of a radian and stays in the stroke
    (Plant.do_step would refuse a step past it), so the errors are relative to a real motion."""
    case, ref, _ = study
    assert ref.ranges[0] > 5e-3 and ref.ranges[1] > 0.05, ref.ranges


def test_reference_agrees_with_its_second_method(study):
    """DOP853 at rtol 1e-13 and Radau at rtol 1e-12 agree within REFERENCE_TOLERANCE (1e-11)
    in pose and in force (relative, the max over the run)."""
    _, ref, _ = study
    pose, force = ref.agreement
    assert pose <= REFERENCE_TOLERANCE and force <= REFERENCE_TOLERANCE, ref.agreement


def test_fixed_step_methods_show_their_theoretical_order(study):
    """Slope of log(pose error) against log(h): rk4 4, semi-implicit Euler 1, within 0.2, fitted
    on errors well above the reference's tolerance."""
    _, _, rows = study
    orders = convergence_orders(rows, REFERENCE_TOLERANCE)
    assert {o.method for o in orders} == set(FIXED_STEP)
    for o in orders:
        assert len(o.steps) >= 3, o
        assert abs(o.measured - o.theory) <= 0.2, o


def test_force_errors_converge_with_the_same_order(study):
    """The force breakdown's error follows the state's: the same fit on the force errors gives
    the same theoretical orders within 0.2."""
    _, _, rows = study
    for o in convergence_orders(rows, REFERENCE_TOLERANCE, "force_error"):
        assert len(o.steps) >= 3, o
        assert abs(o.measured - o.theory) <= 0.2, o


def test_accuracy_command_writes_its_report(tmp_path, capsys):
    """`stewart-sim accuracy` on a short horizon writes the tables, the plot and the summary."""
    out = tmp_path / "acc"
    status = main(["accuracy", str(SCENE), "--out", str(out), "--horizon", "0.2",
                   "--repeats", "1", "--closed-loop-duration", "0.2"])
    assert status == 0, capsys.readouterr().err
    for name in ("open_loop.csv", "closed_loop.csv", "work_precision.png", "summary.md"):
        assert (out / name).stat().st_size > 0, name
    with (out / "open_loop.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {r["method"] for r in rows} == {"rk4", "euler", "dopri5", "RK45", "DOP853", "Radau",
                                           "BDF", "LSODA"}
    assert all(np.isfinite(float(r["pose_error"])) for r in rows)
    text = (out / "summary.md").read_text()
    assert "Measured convergence order" in text and "Closed loop" in text


def test_accuracy_command_rejects_a_bad_horizon(tmp_path, capsys):
    """A horizon shorter than two communication steps is a usage error (status 2)."""
    assert main(["accuracy", str(SCENE), "--out", str(tmp_path), "--horizon", "0.01"]) == 2
    assert "horizon" in capsys.readouterr().err
