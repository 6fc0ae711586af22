"""Output-error refinement (identify --refine): a force signal measured 2 ms late and with a
bias on each leg, which the least-squares estimate cannot see, is found by fitting the forward
model's leg lengths to the measured ones."""
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.dynamics import regressor
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.studies.identify.refine import refine
from stewart_sim.studies.identify.runs import read_run
from stewart_sim.studies.identify.study import identify

sys.path.insert(0, str(Path(__file__).parent))
from test_identify import SCENE, TRUTH, fourier_motion  # noqa: E402

DELAY = 0.002
BIAS = np.array([0.05, -0.08, 0.1, 0.0, -0.05, 0.07])


@pytest.fixture(scope="module")
def late_run(tmp_path_factory):
    truth = load_scene(SCENE, overrides=TRUTH)
    t, q, qd, qdd = fourier_motion(truth, 5, period=4.0)
    # the force measured at t is the one applied at t - DELAY, plus the bias
    shift = int(round(DELAY * 1000))
    sigma = inverse_dynamics(truth, q, qd, qdd)
    measured = np.roll(sigma, shift, axis=0) + BIAS   # periodic record: a roll is a delay
    lengths = inverse_kinematics(truth, q).lengths
    path = tmp_path_factory.mktemp("late") / "late.csv"
    rows = np.column_stack([t, lengths, measured])
    header = "t," + ",".join(f"l{i}" for i in range(1, 7)) + "," + ",".join(
        f"sigma{i}" for i in range(1, 7))
    path.write_text(header + "\n" + "\n".join(",".join(repr(float(x)) for x in r)
                                              for r in rows) + "\n")
    return truth, path


# Known, open: under another OpenBLAS kernel the trust region stops elsewhere in the valley
# where delay, biases and parameters trade against each other (OPENBLAS_CORETYPE=Haswell with
# one thread: delay 1.60 ms, 0.26 um, against 2.11 ms, 0.163 um here); the same with 1 or 2
# threads of the machine's own kernel.
@pytest.mark.xfail(bool(os.environ.get("OPENBLAS_CORETYPE")), strict=False,
                   reason="--refine stops at another point under a forced OpenBLAS kernel")
@pytest.mark.numerics
def test_delay_and_bias_are_found(late_run):
    truth, path = late_run
    prior = load_scene(SCENE)
    run = read_run(path, prior)
    ident = identify(prior, [run])
    r = refine(ident, [run], every=0.5)
    # measured on this run: 7.8 um -> 0.163 um, delay 2.114 ms; the biases' differences between
    # legs within 0.0032 N; the forces the refined model gives with its biases within 0.021 N of
    # the true ones (the least-squares estimate: 0.139 N)
    assert r.rms_after < 0.1 * r.rms_before
    assert abs(r.delay - DELAY) < 0.2e-3
    # a bias common to all six legs is close to a change of the platform's weight at these poses:
    # the run fixes the biases' differences and the sum of that common part and the weight, not
    # each alone (the converged fit moves the common part by 0.063 N, the parameters with it)
    between = (r.bias - r.bias.mean()) - (BIAS - BIAS.mean())
    assert np.max(np.abs(between)) < 0.01
    t, q, qd, qdd = fourier_motion(truth, 5, period=4.0)
    refined = regressor(ident.model, q, qd, qdd) @ r.pi + r.bias
    assert np.max(np.abs(refined - (inverse_dynamics(truth, q, qd, qdd) + BIAS))) < 0.05
    assert np.all(np.isfinite(r.std)) and np.all(r.std > 0) and r.delay_std > 0
