"""The identification model sigma = Y(q, qd, qdd) pi (native/src/regressor.c) against the
inverse dynamics on every shipped scene, and its platform columns against an independent
Newton-Euler computation of a point mass carried off the platform's centre."""
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.dynamics import regressor
from stewart_fmu.errors import StrokeLimitError
from stewart_fmu.rotations import euler_motion
from stewart_fmu.standard import N_STANDARD, NAMES, STANDARD, present, span, standard_parameters

from tests.helpers import shipped_scenes

ROOT = Path(__file__).resolve().parents[2]
# every plant scene we ship (scenes/sweeps holds sweep definitions, not scenes)
SCENES = shipped_scenes()


def samples(model, n=300, seed=0):
    """Random poses near home with random rates and accelerations (inside the stroke)."""
    rng = np.random.default_rng(seed)
    c = model.characteristic_length
    q = np.array(model.home) + rng.uniform(-1, 1, (n, 6)) * np.array([0.02 * c] * 3 + [0.03] * 3)
    qd = rng.normal(0, 1, (n, 6)) * np.array([c] * 3 + [1.0] * 3)
    qdd = rng.normal(0, 1, (n, 6)) * np.array([10 * c] * 3 + [10.0] * 3)
    return q, qd, qdd


def test_table_names_every_column_once():
    assert len(NAMES) == N_STANDARD == sum(s.count for s in STANDARD)
    assert len(set(NAMES)) == N_STANDARD
    assert [s.column for s in STANDARD] == list(np.cumsum([0] + [s.count for s in STANDARD])[:-1])


@pytest.mark.parametrize("path", SCENES, ids=lambda p: str(p.relative_to(ROOT / "scenes")))
def test_y_pi_is_the_inverse_dynamics(path):
    """Y pi == inverse_dynamics to 1e-12 of the peak force, every effect the scene declares."""
    model = load_scene(path)
    q, qd, qdd = samples(model)
    sigma = inverse_dynamics(model, q, qd, qdd)
    Y = regressor(model, q, qd, qdd)
    assert Y.shape == (len(q), 6, N_STANDARD)
    err = np.max(np.abs(Y @ standard_parameters(model) - sigma))
    assert err <= 1e-12 * np.max(np.abs(sigma)), (path.name, err)
    # the columns of an absent effect multiply zeros of pi
    assert np.all(standard_parameters(model)[~present(model)] == 0.0)


def test_columns_the_equations_do_not_hold_are_zero(micro_model):
    Y = regressor(micro_model, *samples(micro_model, 50))
    for name in ("LOWER_MASS", "LOWER_AXIAL", "UPPER_AXIAL"):
        assert np.all(Y[:, :, span(name)] == 0.0), name


def test_platform_columns_by_newton_euler(micro_model):
    """A point mass mu at c (platform frame) is the standard parameters mu, mu c and
    mu (|c|^2 1 - c c^T): Y's platform columns times them must equal the rack forces that carry
    its weight and inertia, -J^-T [mu (g - a_P); R c x mu (g - a_P)], with J's rows
    [u_i, r_i x u_i] and a_P = a + alpha x R c + omega x (omega x R c), all in numpy."""
    model = micro_model
    q, qd, qdd = samples(model, 100, seed=3)
    mu, c = 0.3, np.array([0.012, -0.007, 0.02])
    pi = np.zeros(N_STANDARD)
    pi[span("PLATFORM_MASS")] = mu
    pi[span("PLATFORM_MOMENT")] = mu * c
    I = mu * (c @ c * np.eye(3) - np.outer(c, c))
    pi[span("PLATFORM_INERTIA")] = I[[0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    n = len(q)
    R, om, al = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    euler_motion(q, qd, qdd, R, om, al)
    g = np.asarray(model.gravity)
    for k in range(n):
        rc = R[k] @ c
        a_p = qdd[k, :3] + np.cross(al[k], rc) + np.cross(om[k], np.cross(om[k], rc))
        F = mu * (g - a_p)
        wrench = np.concatenate([F, np.cross(rc, F)])
        r = model.platform_joints @ R[k].T
        L = q[k, :3] + r - model.base_joints
        u = L / np.linalg.norm(L, axis=1)[:, None]
        J = np.hstack([u, np.cross(r, u)])
        expected = -np.linalg.solve(J.T, wrench)
        got = regressor(model, q[k], qd[k], qdd[k])[0] @ pi
        assert np.allclose(got, expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))


def test_a_bad_sample_is_named(micro_model):
    q, qd, qdd = samples(micro_model, 10)
    q[7, 2] = 1.0   # far above the stroke
    with pytest.raises(StrokeLimitError) as err:
        regressor(micro_model, q, qd, qdd)
    assert err.value.index == 7
