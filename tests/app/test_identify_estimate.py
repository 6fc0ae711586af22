"""The estimation of identify on regressor rows the model generated (no files, no filter):
recovery of known base parameters, honest standard deviations, physical consistency, and the
refusal of data that cannot determine the scene's base parameters."""
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu.dynamics import regressor
from stewart_fmu.standard import N_STANDARD, present, span, standard_parameters
from stewart_sim.studies.identify.base import (base_parameters, random_motion, stacked,
                                               structural_base)
from stewart_sim.studies.identify.estimate import estimate, scales
from stewart_sim.studies.identify.synthetic import perturbed_model

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"


@pytest.fixture(scope="module")
def micro():
    return load_scene(SCENE)


def rows(model, n, rng):
    q, qd, qdd = random_motion(model, n, rng)
    W = stacked(regressor(model, q, qd, qdd))
    return W, np.tile(np.arange(6), n)


def run_estimate(model, truth, W, legs, noise, rng):
    s = W @ truth
    s = s + noise * np.max(np.abs(s)) * rng.normal(size=s.shape)
    base = base_parameters(W, np.flatnonzero(present(model)))
    prior = standard_parameters(model)
    sc = scales(model, prior)
    return base, estimate(W, s, legs, base, prior, sc, model.characteristic_length), sc


@pytest.mark.numerics
def test_noise_free_rows_give_the_base_parameters_to_1e_8(micro):
    rng = np.random.default_rng(0)
    truth = standard_parameters(perturbed_model(micro, rng))
    W, legs = rows(micro, 2000, rng)
    base, est, sc = run_estimate(micro, truth, W, legs, 0.0, rng)
    assert base.rank == structural_base(micro).rank == 31
    err = np.abs(est.beta - base.beta(truth)) / (np.abs(base.combination) @ sc)
    assert err.max() < 1e-8, err.max()
    assert not est.constrained
    # forces of other samples predicted to 1e-8 of their peak
    W2, _ = rows(micro, 500, np.random.default_rng(99))
    s2 = W2 @ truth
    assert np.max(np.abs(W2 @ est.pi - s2)) < 1e-8 * np.max(np.abs(s2))


@pytest.mark.numerics
def test_the_truth_is_inside_three_sigma(micro):
    """Force noise 1 % of the peak: over 20 seeds, at least 95 % of the base parameters hold
    the truth inside the reported 3-sigma interval; the estimated noise level of each leg is the
    true one within 4 standard errors of a standard deviation from 600 samples (4 / sqrt(1200))."""
    inside, total = 0, 0
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        truth = standard_parameters(perturbed_model(micro, rng))
        W, legs = rows(micro, 600, rng)
        base, est, _ = run_estimate(micro, truth, W, legs, 0.01, rng)
        z = np.abs(est.beta - base.beta(truth)) / est.std
        inside += int(np.sum(z <= 3.0))
        total += z.size
        peak = np.max(np.abs(W @ truth))
        assert np.allclose(est.noise, 0.01 * peak, rtol=4 / np.sqrt(2 * 600))
    assert inside / total >= 0.95, inside / total


def pseudo_inertia(pi):
    m, h = pi[span("PLATFORM_MASS")][0], pi[span("PLATFORM_MOMENT")]
    xx, xy, xz, yy, yz, zz = pi[span("PLATFORM_INERTIA")]
    I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    J = np.zeros((4, 4))
    J[:3, :3] = np.trace(I) / 2 * np.eye(3) - I
    J[:3, 3] = J[3, :3] = h
    J[3, 3] = m
    return J


@pytest.mark.numerics
def test_the_estimate_is_physically_consistent(micro):
    """With noise large enough to make the WLS estimate unphysical, pi is physical (pseudo-
    inertias >= 0, frictions and drive masses >= 0) and reproduces the reported beta."""
    rng = np.random.default_rng(7)
    truth = standard_parameters(perturbed_model(micro, rng))
    W, legs = rows(micro, 300, rng)
    base, est, sc = run_estimate(micro, truth, W, legs, 0.05, rng)
    pi = est.pi
    L = micro.characteristic_length
    D = np.diag([1 / L, 1 / L, 1 / L, 1.0])
    assert np.linalg.eigvalsh(D @ pseudo_inertia(pi) @ D).min() > -1e-7 * pi[0]
    for part in ("LOWER", "UPPER"):
        m, mc = pi[span(f"{part}_MASS")][0], pi[span(f"{part}_MOMENT")][0]
        jt, ja = pi[span(f"{part}_INERTIA")][0], pi[span(f"{part}_AXIAL")][0]
        Q = np.array([[(jt - ja / 2) / L**2, mc / L], [mc / L, m]])
        assert np.linalg.eigvalsh(Q).min() > -1e-7 * m and ja >= -1e-12
    for name in ("DRIVE_MASS", "VISCOUS", "COULOMB"):
        assert np.all(pi[span(name)] >= -1e-9 * sc[span(name)])
    assert np.allclose(base.beta(pi), est.beta, rtol=0, atol=1e-6 * (np.abs(base.combination) @ sc).max())


@pytest.mark.numerics
def test_rows_without_rotation_determine_less_than_the_structure(micro):
    """Translation only: the platform's inertia drops out of what the rows determine."""
    rng = np.random.default_rng(3)
    q, qd, qdd = random_motion(micro, 400, rng)
    q[:, 3:] = qd[:, 3:] = qdd[:, 3:] = 0.0
    q[:, 3:] = micro.home[3:]
    W = stacked(regressor(micro, q, qd, qdd))
    base = base_parameters(W, np.flatnonzero(present(micro)))
    assert base.rank < structural_base(micro).rank
    got = set(base.alone) | set(base.combined)
    assert "platform.inertia_tensor.xx" not in got
