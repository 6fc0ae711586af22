"""Stiff scenes (scenes/stiff): the default integrator copes; explicit RK4 past its stability
limit is caught with time, method, step and advice; short horizons."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.design import UnstableLoopError
from stewart_fmu import load_scene
from stewart_fmu.errors import IntegrationError
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.stability import stable_step
from stewart_sim.scene.case_config import case_of
from stewart_sim.scene.load import scene_of
from stewart_sim.studies.cases.outcome import run_case

STIFF = Path(__file__).resolve().parents[2] / "scenes" / "stiff"
REFERENCE = IntegratorOptions("Radau", rtol=1e-10, atol=1e-13)


def _case(model):
    """The model with its [case] and [controller] tables as run_case takes them."""
    scene = scene_of(model)
    return model, scene.case, scene.controller


@pytest.mark.parametrize("scene", ["viscous.toml", "compliant.toml"])
def test_default_integrator_copes_and_agrees_with_radau(scene):
    """The default (RK4 at h rho <= 0.5) runs 0.05 s without a caught instability and matches a
    tight Radau run within 1e-4 of the motion."""
    model = load_scene(STIFF / scene)
    assert case_of(model).expect == "ok"
    result = run_case(*_case(model), duration=0.05)
    ref = run_case(*_case(model), REFERENCE, duration=0.05)
    assert result.outcome == "ok" and ref.outcome == "ok"
    motion = np.max(np.abs(ref.states[:, :6] - model.home))
    assert np.max(np.abs(result.states[:, :6] - ref.states[:, :6])) <= 1e-4 * motion


@pytest.mark.parametrize("scene", ["viscous.toml", "compliant.toml"])
def test_explicit_rk4_past_its_stability_limit_is_caught(scene):
    """RK4 at 1 ms (beyond 2.78 / rho) is stopped by the power-balance check in the first step,
    not left to produce garbage: IntegrationError names the time, method, step and advice."""
    model = load_scene(STIFF / scene)
    limit = stable_step(model)
    assert limit < 1e-3
    result = run_case(*_case(model), IntegratorOptions("rk4", max_step=1e-3),
                      duration=0.05)
    assert result.outcome == "unstable"
    exc = result.error
    assert isinstance(exc, IntegrationError)
    assert exc.time == 0.0 and exc.method == "rk4" and exc.step == 1e-3
    assert exc.stable_step == pytest.approx(limit, rel=1e-6)
    assert "t = 0.0 s" in str(exc) and "Radau" in str(exc) and "max_step below" in str(exc)
    assert np.all(np.isfinite(result.states))


def test_rk4_below_its_stability_limit_is_accepted():
    """RK4 at 0.9 of the stability limit on the viscous scene runs without being flagged."""
    model = load_scene(STIFF / "viscous.toml")
    h = 0.9 * stable_step(model)
    rk4 = IntegratorOptions("rk4", max_step=h)
    assert run_case(*_case(model), rk4, duration=0.02).outcome == "ok"


def test_high_gain_loop_runs_and_integrators_agree():
    """The 100 Hz loop at 5 kHz tracks; the plant under RK4 and under Radau gives the same leg
    lengths (1e-9 m): the stiffness of a sampled high-gain loop is decided by the sampled-loop
    analysis, not by the plant integrator."""
    model = load_scene(STIFF / "high_gain.toml")
    a = run_case(*_case(model), duration=0.06)
    b = run_case(*_case(model), REFERENCE, duration=0.06)
    assert a.outcome == b.outcome == "ok"
    assert np.max(np.abs(a.states - b.states)) < 1e-9


def test_gain_beyond_the_sample_rate_is_refused_before_running():
    """A 400 Hz crossover sampled at 500 Hz is refused by the sampled-loop analysis (spectral
    radius above one) before anything runs."""
    model = load_scene(STIFF / "high_gain.toml", {"controller.bandwidth": 400.0,
                                                  "controller.rate": 500.0})
    with pytest.raises(UnstableLoopError, match="spectral radius"):
        run_case(*_case(model), duration=0.2)
