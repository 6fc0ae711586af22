"""The paper's body-by-body Kane terms against the compiled twist-space kernel."""
from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import forward_dynamics, inverse_dynamics, inverse_kinematics, scene_from_dict
from stewart_fmu import kane_terms as K

SCENES = Path(__file__).resolve().parents[2] / "scenes"
LEVELS = {"full": (), "no drive": ("drive",), "no drive, no friction": ("drive", "friction"),
          "platform only": ("legs", "drive", "friction")}


def _model(scene: str, drop: tuple[str, ...]):
    data = tomllib.loads((SCENES / scene).read_text())
    return scene_from_dict({k: v for k, v in data.items() if k not in drop})


def _states(model, n: int, seed: int = 7):
    """Random poses near home (roll/pitch/yaw up to ~0.3 rad), velocities, accelerations."""
    rng = np.random.default_rng(seed)
    size = float(np.mean(inverse_kinematics(model, model.home).lengths))
    for _ in range(n):
        dq = rng.uniform(-1, 1, 6) * np.r_[[0.08 * size] * 3, [0.3] * 3]
        yield model.home + dq, rng.normal(size=6) * np.r_[[size] * 3, [1.0] * 3], rng.normal(size=6) * 5


@pytest.mark.parametrize("scene", ["micro_manipulator.toml", "motion_simulator.toml"])
@pytest.mark.parametrize("level", list(LEVELS))
def test_paper_terms_equal_compiled_kernel(scene, level):
    """sigma = [a]^-1(([m]+[m_d]) lddot + b - g - f) equals inverse_dynamics to 1e-10 relative."""
    model = _model(scene, LEVELS[level])
    for q, qd, qdd in _states(model, 10):
        ref = inverse_dynamics(model, q, qd, qdd)
        got = K.actuator_forces(model, q, qd, qdd)
        assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("level", list(LEVELS))
def test_actuator_matrix_is_identity_and_mass_matrix_spd(level):
    """[a] = I to 1e-12 (leg rates are the speeds); [m] symmetric to 1e-12 and positive definite."""
    model = _model("micro_manipulator.toml", LEVELS[level])
    for q, _, _ in _states(model, 5):
        assert np.allclose(K.actuator_matrix(model, q), np.eye(6), rtol=0, atol=1e-12)
        M = K.mass_matrix(model, q)
        assert np.max(np.abs(M - M.T)) <= 1e-12 * np.max(np.abs(M))
        assert np.linalg.eigvalsh(M).min() > 0


def test_kane_equation_holds_with_forward_dynamics():
    """K* + K = 0 at the accelerations forward_dynamics returns (residual < 1e-10 of |sigma|)."""
    model = _model("micro_manipulator.toml", ())
    md = K.drive_inertia(model)
    for q, qd, _ in _states(model, 5, seed=3):
        sigma = np.random.default_rng(1).normal(size=6) * 10
        qdd = forward_dynamics(model, q, qd, sigma)
        lddot = inverse_kinematics(model, q, qd, qdd).accelerations
        Kstar = K.generalized_inertia_forces(model, q, qd, qdd) - md @ lddot
        Kact = K.gravity_terms(model, q) + K.actuator_matrix(model, q) @ sigma + K.friction_terms(model, q, qd)
        assert np.max(np.abs(Kstar + Kact)) <= 1e-10 * np.max(np.abs(sigma))


def test_mass_matrix_is_the_acceleration_coefficient():
    """[m] lddot + b = -K* for random accelerations (1e-10): b carries no acceleration."""
    model = _model("motion_simulator.toml", ("drive",))
    for q, qd, qdd in _states(model, 5, seed=11):
        lddot = inverse_kinematics(model, q, qd, qdd).accelerations
        lhs = K.mass_matrix(model, q) @ lddot + K.velocity_terms(model, q, qd)
        rhs = -K.generalized_inertia_forces(model, q, qd, qdd)
        assert np.max(np.abs(lhs - rhs)) <= 1e-10 * np.max(np.abs(rhs))


def test_axial_leg_inertia_has_no_effect():
    """Legs do not spin about their axes, so the axial moment changes nothing (1e-12)."""
    model = _model("micro_manipulator.toml", ("drive",))
    lg = model.legs
    heavy = dataclasses.replace(model, legs=dataclasses.replace(
        lg, lower_inertia=(lg.lower_inertia[0], 2 * lg.lower_inertia[0]),
        upper_inertia=(lg.upper_inertia[0], 0.0)))
    for q, qd, qdd in _states(model, 5):
        a, b = inverse_dynamics(model, q, qd, qdd), inverse_dynamics(heavy, q, qd, qdd)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a))
        ka, kb = K.actuator_forces(model, q, qd, qdd), K.actuator_forces(heavy, q, qd, qdd)
        assert np.max(np.abs(ka - kb)) <= 1e-12 * np.max(np.abs(ka))


def test_partial_velocities_reproduce_body_velocities():
    """sum_j V_j ldot_j equals each body's velocity from kinematics (Eqs. 1-2), to 1e-12."""
    model = _model("micro_manipulator.toml", ())
    for q, qd, qdd in _states(model, 5):
        ldot = inverse_kinematics(model, q, qd).rates
        pv = K.partial_velocities(model, q)
        mot = K.body_motion(model, q, qd, qdd)
        pairs = [(pv.platform_linear.T @ ldot, mot.platform[0]),
                 (pv.platform_angular.T @ ldot, mot.platform[2]),
                 (np.einsum("ijk,j->ik", pv.lower_linear, ldot), mot.lower[0]),
                 (np.einsum("ijk,j->ik", pv.upper_linear, ldot), mot.upper[0]),
                 (np.einsum("ijk,j->ik", pv.leg_angular, ldot), mot.leg[0])]
        for got, want in pairs:
            assert np.allclose(got, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()))


def test_drive_inertia_is_zeta_squared_I_over_r_squared():
    """[m_d] = zeta^2 I / r^2 on the diagonal (20^2 * 1e-6 / 0.005^2 = 16 kg)."""
    model = _model("micro_manipulator.toml", ())
    assert np.allclose(K.drive_inertia(model), 16.0 * np.eye(6), rtol=1e-12)
    assert np.all(K.drive_inertia(_model("micro_manipulator.toml", ("drive",))) == 0)
