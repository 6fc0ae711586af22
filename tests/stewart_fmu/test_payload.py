"""[payload] in the plant's dynamics (kane.c, energy.c): a body fixed to the platform, off its
centre of mass, with products of inertia."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_fmu import forward_dynamics, inverse_dynamics, scene_from_dict
from stewart_fmu.dynamics import regressor
from stewart_fmu.energy import energy_terms, total_energy
from stewart_fmu.integrators import derivative
from stewart_fmu.native import core
from stewart_fmu.standard import standard_parameters
from tests.helpers import random_states, record, scene_dict

PAYLOAD = {"micro": {"mass": 0.8, "com": [0.012, -0.02, 0.035],
                     "inertia": [1e-3, 2e-3, 2.5e-3, 1e-4, -2e-4, 3e-4]},
           "sim": {"mass": 500.0, "com": [0.39, -0.26, 0.65],
                   "inertia": [100.0, 120.0, 150.0, 10.0, -5.0, 3.0]}}


def _loaded(name: str, payload: dict | None = None, **changes):
    d = scene_dict(name)
    d["payload"] = payload or PAYLOAD[name]
    d.update(changes)
    return scene_from_dict(d)


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_a_payload_at_the_centre_of_mass_is_a_heavier_platform(name):
    """A payload at C's origin with principal moments along C's axes: the inverse and forward
    dynamics of the platform with its mass and moments added (1e-12 relative)."""
    inertia = [0.3, 0.4, 0.5] if name == "micro" else [300.0, 400.0, 500.0]
    m = 0.7 if name == "micro" else 700.0
    loaded = _loaded(name, {"mass": m, "com": [0.0, 0.0, 0.0], "inertia": [i * 1e-3 if name == "micro" else i
                                                                          for i in inertia]})
    d = scene_dict(name)
    d["platform"]["mass"] += m
    d["platform"]["inertia"] = [a + (b * 1e-3 if name == "micro" else b)
                                for a, b in zip(d["platform"]["inertia"], inertia)]
    heavier = scene_from_dict(d)
    q, qd, qdd = random_states(name, 20, seed=5)
    s1, s2 = inverse_dynamics(loaded, q, qd, qdd), inverse_dynamics(heavier, q, qd, qdd)
    err = np.max(np.abs(s1 - s2)) / np.max(np.abs(s2))
    record("payload at C vs heavier platform (rel)", err, 1e-12)
    assert err <= 1e-12
    a1, a2 = forward_dynamics(loaded, q, qd, s2), forward_dynamics(heavier, q, qd, s2)
    assert np.max(np.abs(a1 - a2)) <= 1e-10 * np.max(np.abs(a2))


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_inverse_dynamics_with_a_payload_is_the_regressor_with_its_standard_parameters(name):
    """Off C, with products of inertia: sigma = Y(q, qd, qdd) pi, the regressor's columns for
    the platform's first moment and full inertia tensor (regressor.c) with pi holding the
    payload (standard.py), an independent route (1e-10 relative); the forward dynamics inverts
    it."""
    model = _loaded(name)
    q, qd, qdd = random_states(name, 20, seed=6)
    sigma = inverse_dynamics(model, q, qd, qdd)
    Y = regressor(model, q, qd, qdd)
    ref = Y @ standard_parameters(model)
    err = np.max(np.abs(sigma - ref)) / np.max(np.abs(ref))
    record("payload: inverse dynamics vs regressor (rel)", err, 1e-10)
    assert err <= 1e-10
    back = forward_dynamics(model, q, qd, sigma)
    assert np.max(np.abs(back - qdd)) <= 1e-8 * np.max(np.abs(qdd))


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_energy_with_a_payload_balances_the_power(name):
    """dE/dt = F . ldot - mu . ldot along the flow (E with the payload's kinetic and potential
    energy), by central differences at random states (1e-7 relative)."""
    model = _loaded(name)
    q, qd, _ = random_states(name, 6, seed=7)
    rng = np.random.default_rng(8)
    for k in range(6):
        y = np.r_[q[k], qd[k]]
        F = rng.uniform(-1, 1, 6) * (5.0 if name == "micro" else 5e3)
        dy, st = derivative(model.params, y, F)
        assert st == core.OK
        eps = 1e-6
        rate = (total_energy(energy_terms(model, y + eps * dy))
                - total_energy(energy_terms(model, y - eps * dy))) / (2 * eps)
        l, ld, _, _ = core.leg_state(model.native, q[k], qd[k])
        mu = model.friction.viscous_legs * ld + model.friction.coulomb_legs * np.sign(ld)
        power = F @ ld - mu @ ld
        scale = np.abs(F @ ld) + np.abs(mu @ ld)
        assert abs(rate - power) <= 1e-7 * scale, (rate, power)


def test_the_fmu_export_refuses_a_payload(tmp_path):
    """No FMU variable holds [payload]: export refuses the scene naming the table, writes nothing."""
    from stewart_fmu.errors import SceneError
    from stewart_fmu.fmu.export import export_model

    with pytest.raises(SceneError) as err:
        export_model(_loaded("micro"), b"", tmp_path / "x.fmu")
    assert err.value.key == "payload" and not (tmp_path / "x.fmu").exists()


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_the_c_core_is_the_papers_kane_terms_with_a_payload(name):
    """kane_terms, body by body (the payload a body with its own partial velocities, Eqs. 1-8),
    against the C core's reduction to the twist: the actuator forces (1e-10 relative) and the
    twist mass matrix J^T ([m] + [m_d]) J (1e-12)."""
    from stewart_fmu.kane_terms import actuator_forces, drive_inertia, mass_matrix
    from stewart_fmu.kinematics import inverse_kinematics

    model = _loaded(name)
    q, qd, qdd = random_states(name, 8, seed=9)
    for k in range(8):
        ref = actuator_forces(model, q[k], qd[k], qdd[k])
        got = inverse_dynamics(model, q[k], qd[k], qdd[k])
        err = np.max(np.abs(got - ref)) / np.max(np.abs(ref))
        record("payload: C core vs kane_terms (rel)", err, 1e-10)
        assert err <= 1e-10
    J = inverse_kinematics(model, q[0], with_cond=False).jacobian
    M = J.T @ (mass_matrix(model, q[0]) + drive_inertia(model)) @ J
    Mc, st = core.mass_matrix(model.native, q[0])
    assert st == core.OK
    assert np.linalg.norm(Mc - M) <= 1e-12 * np.linalg.norm(M)
