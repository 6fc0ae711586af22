"""The view's geometry: every drawn part ends at the joints stewart_fmu.kinematics computes,
the parts keep their lengths, the plates pass through their joints."""
from __future__ import annotations

import numpy as np
import pytest

from hil.params import COND_MAX
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.scene.load import scene_of
from stewart_sim.view.geometry import (
    COND_WARN,
    at_stroke_limit,
    axis_to,
    object_transforms,
    part_ends,
    rotation,
    view_geometry,
)
from tests.helpers import random_states


def poses(name: str, n: int = 40) -> np.ndarray:
    """Random poses inside the stroke (tests.helpers.random_states)."""
    return random_states(name, n, seed=3)[0]


@pytest.mark.parametrize("fixture", ["micro_model", "sim_model"])
def test_leg_parts_end_at_the_joints(fixture, request):
    model = request.getfixturevalue(fixture)
    g = view_geometry(model, controller=scene_of(model).controller)
    name = "micro" if fixture == "micro_model" else "sim"
    for q in poses(name):
        kin = inverse_kinematics(model, q, with_cond=False)
        T = object_transforms(g, q)
        tops = q[:3] + kin.lever_arms            # platform joints x + R p_i (kinematics)
        for i in range(6):
            a = model.base_joints[i]
            lo, hi = part_ends(T[f"legs/{i + 1}/cylinder"], g.cylinder_length)
            np.testing.assert_allclose(lo, a, atol=1e-12)
            np.testing.assert_allclose(hi, a + kin.unit_vectors[i] * g.cylinder_length, atol=1e-12)
            lo, hi = part_ends(T[f"legs/{i + 1}/piston"], g.piston_length)
            np.testing.assert_allclose(hi, tops[i], atol=1e-12)
            np.testing.assert_allclose(lo, tops[i] - kin.unit_vectors[i] * g.piston_length,
                                       atol=1e-12)
            # the two parts span the leg: their far ends are l_i apart along u_i
            np.testing.assert_allclose(np.linalg.norm(tops[i] - a), kin.lengths[i], rtol=1e-12)
            np.testing.assert_allclose(T[f"joints/platform/{i + 1}"][:3, 3], tops[i], atol=1e-12)
            np.testing.assert_allclose(T[f"joints/base/{i + 1}"][:3, 3], a, atol=1e-15)


def test_transforms_are_rigid_and_plates_hold_the_joints(micro_model):
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    for q in poses("micro", 10):
        T = object_transforms(g, q)
        for M in T.values():
            np.testing.assert_allclose(M[:3, :3] @ M[:3, :3].T, np.eye(3), atol=1e-12)
            assert np.linalg.det(M[:3, :3]) == pytest.approx(1.0)
            np.testing.assert_array_equal(M[3], [0, 0, 0, 1])
        # the platform plate's axis (its local y) is the platform's z axis, and its lower face
        # (half its thickness below its centre) holds every platform joint
        P = T["platform"]
        R = rotation(q)
        np.testing.assert_allclose(P[:3, 1], R[:, 2], atol=1e-12)
        for i in range(6):
            joint = T[f"joints/platform/{i + 1}"][:3, 3]
            assert np.dot(joint - P[:3, 3], P[:3, 1]) == pytest.approx(-g.plate_thickness / 2,
                                                                       abs=1e-12)
    B = object_transforms(g, micro_model.home)["base"]
    for a in micro_model.base_joints:      # the base plate's top face holds the base joints
        assert np.dot(a - B[:3, 3], B[:3, 1]) == pytest.approx(g.plate_thickness / 2, abs=1e-15)


def test_parts_meet_at_full_extension(micro_model):
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    assert g.cylinder_length == micro_model.leg_min
    assert g.cylinder_length + g.piston_length == pytest.approx(micro_model.leg_max)


@pytest.mark.parametrize("u", [[0, 1, 0], [0, -1, 0], [1, 0, 0], [0.3, -0.2, 0.9]])
def test_axis_to_takes_y_onto_u(u):
    u = np.asarray(u, float) / np.linalg.norm(u)
    R = axis_to(u)
    np.testing.assert_allclose(R @ [0, 1, 0], u, atol=1e-14)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)


def test_stroke_limit_band(micro_model):
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    band = g.stroke_margin * (g.leg_max - g.leg_min)
    l = np.array([g.leg_min, g.leg_min + 2 * band, g.leg_max - band / 2, 0.12, g.leg_max, 0.13])
    np.testing.assert_array_equal(at_stroke_limit(g, l), [True, False, True, False, True, False])


def test_cond_threshold_is_the_devices():
    assert COND_WARN == COND_MAX


def test_drive_peak_force_is_kt_zeta_over_r_times_current_limit(micro_model):
    # 0.02 N m/A x 2 A x (20 / 0.005 m) = 160 N: the device's "drive peak 160 N"
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    assert g.force_scale == pytest.approx(160.0)
