"""The compliant transmission: power balance, the rigid limit, its natural frequencies, scenes."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_fmu import SceneError, scene_from_dict
from stewart_fmu.dynamics import leg_state
from stewart_fmu.energy import energy_terms, total_energy
from stewart_fmu.integrators import IntegratorOptions, derivative
from stewart_fmu.plant import Plant
from stewart_fmu.stability import hold_state
from stewart_fmu.transmission import natural_frequencies
from tests.helpers import random_states, scene_dict


def _compliant(stiffness: float, damping: float = 20.0, drop: tuple[str, ...] = ()):
    d = scene_dict("micro")
    d["transmission"] = {"stiffness": stiffness, "damping": damping}
    for table in drop:
        d.pop(table)
    return scene_from_dict(d)


def test_power_balance_with_spring_energy_and_damper_dissipation():
    """dE/dt = F . sd - mu . ld - c |sd - ld|^2 (E with the spring energy), by central
    differences of E along the flow at random states (1e-7 rel)."""
    model = _compliant(1e6, 30.0)
    q, qd, _ = random_states("micro", 8, seed=3)
    rng = np.random.default_rng(4)
    for k in range(8):
        y0 = np.r_[q[k], qd[k]]
        l, ld, _ = leg_state(model, q[k], qd[k])
        s = l + rng.uniform(-1e-5, 1e-5, 6)
        y = np.r_[y0, s, rng.uniform(-0.05, 0.05, 6)]
        F = rng.uniform(-5.0, 5.0, 6)
        dy, status = derivative(model.params, y, F)
        assert status == 0
        eps = 1e-6
        rate = (total_energy(energy_terms(model, y + eps * dy))
                - total_energy(energy_terms(model, y - eps * dy))) / (2 * eps)
        mu = 5.0 * ld
        power = F @ y[18:] - mu @ ld - 30.0 * np.sum((y[18:] - ld) ** 2)
        scale = np.abs(F @ y[18:]) + np.abs(mu @ ld) + 30.0 * np.sum((y[18:] - ld) ** 2)
        assert abs(rate - power) <= 1e-7 * scale, (rate, power)


def _final_q(model, duration: float = 0.1) -> np.ndarray:
    plant = Plant(model, IntegratorOptions("dopri5", rtol=1e-11, atol=1e-13))
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    _, F = hold_state(model)
    plant.set_force(1.05 * F)
    plant.exit_initialization_mode()
    for _ in range(int(round(duration / 1e-3))):
        plant.do_step(plant.time, 1e-3)
    return plant.outputs.q


def test_stiff_limit_approaches_the_rigid_drive():
    """The pose error vs the rigid drive after 0.1 s is first order in 1/k: k x error is the
    same constant (within 2%) for k = 1e6, 1e7, 1e8 N/m, so it vanishes as k -> inf."""
    rigid = scene_from_dict(scene_dict("micro"))
    ref = _final_q(rigid)
    errors = [np.max(np.abs(_final_q(_compliant(k)) - ref)) for k in (1e6, 1e7, 1e8)]
    scaled = np.array(errors) * np.array([1e6, 1e7, 1e8])
    assert np.all(np.abs(scaled / scaled[-1] - 1.0) < 0.02), (errors, scaled)


def test_natural_frequency_matches_the_linearised_estimate():
    """Without damping the largest |eigenvalue| of the plant's Jacobian at the hold is the
    highest transmission mode sqrt(eig(k (I / m_d + [m]^-1))) (1e-3 rel)."""
    model = _compliant(1e7, 0.0, drop=("friction",))
    y, F = hold_state(model)
    cols = []
    for j in range(24):
        e = np.zeros(24)
        e[j] = 1e-7 * max(abs(y[j]), 0.06)
        cols.append((derivative(model.params, y + e, F)[0]
                     - derivative(model.params, y - e, F)[0]) / (2 * e[j]))
    lam = np.linalg.eigvals(np.column_stack(cols))
    estimate = natural_frequencies(model, model.home)
    assert abs(np.max(np.abs(lam)) - estimate[-1]) <= 1e-3 * estimate[-1]
    assert abs(np.max(np.abs(lam.real))) < 1e-3 * estimate[-1]  # undamped: imaginary pairs


def test_preloaded_start_holds_and_parts_sum_to_the_rack_force():
    """A plant started with the hold force has the spring carrying it, and the rack-force
    breakdown (leg-side parts + m_d sdd) sums to the rack force."""
    model = _compliant(1e7)
    plant = Plant(model)
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    _, F = hold_state(model)
    plant.set_force(F)
    plant.exit_initialization_mode()
    assert np.allclose(plant.outputs.spring_force, F, rtol=1e-12)
    for _ in range(10):
        plant.do_step(plant.time, 1e-3)
    total = sum(plant.outputs.parts.values())
    assert np.allclose(total, F, rtol=1e-9, atol=1e-9 * np.max(np.abs(F)))


@pytest.mark.parametrize("mutate, key", [
    (lambda d: d.pop("drive"), "transmission"),
    (lambda d: d["transmission"].update(stiffness=-1.0), "transmission.stiffness"),
    (lambda d: d["transmission"].update(damping=float("nan")), "transmission.damping"),
    (lambda d: d["transmission"].update(spring=1.0), "transmission.spring"),
])
def test_scene_rejects_bad_transmission_tables(mutate, key):
    """Bad [transmission] tables are refused naming the key ([case]: tests/app/test_scene_load.py)."""
    d = scene_dict("micro")
    d["transmission"] = {"stiffness": 1e6, "damping": 1.0}
    mutate(d)
    with pytest.raises(SceneError) as exc:
        scene_from_dict(d)
    assert exc.value.key == key
