"""Feasibility of a platform trajectory: each limit crossing is reported at its first sample
with its leg, checked against lengths, cond(J), forces and drive figures computed here."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stewart_fmu import scene_from_dict
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import SceneError
from stewart_sim.cueing.feasibility import COND_LIMIT, feasibility
from stewart_sim.scene.load import scene_of
from tests.helpers import agrees_at_limit, level_model, near_peak, runs_mask, scene_dict

DT = 0.01


def _model():
    return level_model("sim", "full")


def _rot(thx, thy, thz):
    cx, sx, cy, sy, cz, sz = np.cos(thx), np.sin(thx), np.cos(thy), np.sin(thy), np.cos(thz), np.sin(thz)
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


def _lengths(model, q):
    """Leg lengths |x + R p_i - a_i| straight from numpy."""
    out = np.empty((len(q), 6))
    for k, pose in enumerate(q):
        legs = pose[:3] + model.platform_joints @ _rot(*pose[3:]).T - model.base_joints
        out[k] = np.linalg.norm(legs, axis=1)
    return out


def _cond(model, q):
    """Scaled cond(J), J rows [u_i, (R p_i) x u_i], rotational columns / mean joint radius."""
    scale = np.r_[np.ones(3), np.full(3, 1 / np.mean(np.linalg.norm(model.platform_joints, axis=1)))]
    out = np.empty(len(q))
    for k, pose in enumerate(q):
        r = model.platform_joints @ _rot(*pose[3:]).T
        legs = pose[:3] + r - model.base_joints
        u = legs / np.linalg.norm(legs, axis=1)[:, None]
        s = np.linalg.svd(np.hstack([u, np.cross(r, u)]) * scale, compute_uv=False)
        out[k] = s[0] / s[-1]
    return out


def _sine(model, axis, amplitude, freq, duration=4.0, phase=0.0):
    """home + amplitude sin(2 pi freq t + phase) on one pose coordinate, with its exact
    derivatives."""
    t = np.arange(0, duration + DT / 2, DT)
    w = 2 * np.pi * freq
    q = np.tile(model.home, (t.size, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    q[:, axis] += amplitude * np.sin(w * t + phase)
    qd[:, axis] = amplitude * w * np.cos(w * t + phase)
    qdd[:, axis] = -amplitude * w * w * np.sin(w * t + phase)
    return t, q, qd, qdd


def _heave_volts(model, q, qd, sigma, kf):
    """V = R i + L di/dt + Ke' ldot for a pure heave: ldot = u . zdot from numpy, di/dt by
    central differences (the stated method), R, L and Ke' = Kf from the scene's numbers."""
    legs = q[:, None, :3] + model.platform_joints[None] - model.base_joints[None]
    ldot = np.einsum("nki,ni->nk", legs / _lengths(model, q)[..., None], qd[:, :3])
    i = sigma / kf
    return 0.2 * i + 2e-3 * np.gradient(i, DT, axis=0) + kf * ldot


def _runs(mask):
    """(first sample, length) of each run of True."""
    edges = np.diff(np.r_[0, mask.astype(int), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return list(zip(starts.tolist(), (ends - starts).tolist()))


def test_a_gentle_trajectory_is_inside_everything():
    model = _model()
    t, q, qd, qdd = _sine(model, 2, 0.1, 0.5)
    r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
    assert r.feasible and r.violations == () and r.drive_note is None
    np.testing.assert_allclose(r.lengths, _lengths(model, q), rtol=1e-13)
    np.testing.assert_allclose(r.cond, _cond(model, q), rtol=1e-9)
    assert {m.quantity for m in r.margins} == {"stroke_min", "stroke_max", "cond", "force",
                                               "current", "voltage"}
    assert all(0 < m.ratio < 1 for m in r.margins)
    top = next(m for m in r.margins if m.quantity == "stroke_max")
    lengths = _lengths(model, q)
    assert top.value == pytest.approx(lengths.max(), rel=1e-13) and top.ratio == pytest.approx(lengths.max() / 3.3)
    assert r.cond_limit == COND_LIMIT and r.leg_min == 1.7 and r.leg_max == 3.3


@pytest.mark.parametrize("axis", [0, 1, 2, 5])   # surge, sway, heave, yaw
def test_a_motion_made_stronger_is_caught_at_the_first_sample_past_the_stroke(axis):
    model = _model()
    step = 0.05   # m, or rad for yaw
    previous_clean = False
    for k in range(1, 100):
        amplitude = k * step
        t, q, qd, qdd = _sine(model, axis, amplitude, 0.25)
        r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
        stroke = [v for v in r.violations if v.quantity.startswith("stroke")]
        if not stroke:
            previous_clean = True
            continue
        break
    assert previous_clean, "the weakest motion already left the stroke: start lower"
    lengths = _lengths(model, q)
    crossings = 0
    for quantity, limit, above in (("stroke_max", 3.3, True), ("stroke_min", 1.7, False)):
        for leg in range(6):
            got = [(v.sample, round(v.duration / DT)) for v in stroke
                   if v.quantity == quantity and v.leg == leg + 1]
            flagged = runs_mask(got, len(t))
            assert agrees_at_limit(flagged, lengths[:, leg], limit, above) and got == _runs(flagged)
            crossings += len(got)
    assert crossings, "no crossing"
    for v in stroke:
        assert v.t == t[v.sample] and v.value == pytest.approx(lengths[v.sample, v.leg - 1], rel=1e-13)
        assert v.limit == (3.3 if v.quantity == "stroke_max" else 1.7) and v.unit == "m"
        # the sample before is inside the stroke
        assert 1.7 <= lengths[v.sample - 1, v.leg - 1] <= 3.3
    assert [v.sample for v in r.violations] == sorted(v.sample for v in r.violations)


def test_forces_past_the_drive_are_caught_with_current_and_voltage_from_the_motor():
    model = _model()
    kf = 0.5 * 10.0 / 0.04   # Kt zeta / r = Ke zeta / r, from the scene's numbers
    force_limit, i_max = kf * 80.0, 80.0
    for freq in np.arange(0.5, 6.0, 0.25):
        t, q, qd, qdd = _sine(model, 2, 0.05, freq)
        r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
        if any(v.quantity == "force" for v in r.violations):
            break
    else:
        pytest.fail("no heave frequency up to 6 Hz reached the force limit")
    assert not any(v.quantity.startswith("stroke") for v in r.violations)
    sigma = inverse_dynamics(model, q, qd, qdd)
    np.testing.assert_array_equal(r.sigma, sigma)
    assert r.force_limit == pytest.approx(force_limit) and r.current_limit == i_max
    for quantity in ("force", "current"):   # i = sigma / Kf against I_max: the same crossings
        for leg in range(6):
            got = [(v.sample, round(v.duration / DT)) for v in r.violations
                   if v.quantity == quantity and v.leg == leg + 1]
            flagged = runs_mask(got, len(t))
            assert agrees_at_limit(flagged, np.abs(sigma[:, leg]), force_limit)
            assert got == _runs(flagged)
    np.testing.assert_allclose(r.current, sigma / kf, rtol=1e-14)
    np.testing.assert_allclose(r.voltage, _heave_volts(model, q, qd, sigma, kf), rtol=1e-9, atol=1e-9)
    margin = next(m for m in r.margins if m.quantity == "force")
    assert (margin.sample, margin.leg - 1) in near_peak(sigma)
    assert margin.ratio == pytest.approx(np.abs(sigma).max() / force_limit) and margin.ratio > 1


def test_a_fast_motion_past_the_voltage_limit_is_caught():
    # a slow, wide heave from rest: the back-EMF Ke' ldot dominates the voltage
    model = _model()
    kf = 0.5 * 10.0 / 0.04
    for k in range(1, 30):
        t, q, qd, qdd = _sine(model, 2, 0.05 * k, 0.5, phase=-np.pi / 2)
        r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
        if any(v.quantity == "voltage" for v in r.violations):
            break
    else:
        pytest.fail("no heave amplitude reached the voltage limit")
    assert k > 1 and not any(v.quantity.startswith("stroke") for v in r.violations)
    volts = _heave_volts(model, q, qd, inverse_dynamics(model, q, qd, qdd), kf)
    expected = {(leg + 1, first, n) for leg in range(6) for first, n in _runs(np.abs(volts[:, leg]) > 300.0)}
    got = {(v.leg, v.sample, round(v.duration / DT)) for v in r.violations if v.quantity == "voltage"}
    assert got == expected and min(first for _, first, _ in got) > 0
    assert all(v.unit == "V" and v.limit == 300.0 for v in r.violations if v.quantity == "voltage")


def test_cond_past_its_limit_is_caught_for_the_pose():
    model = _model()
    t, q, qd, qdd = _sine(model, 3, 0.3, 0.25)   # roll
    cond = _cond(model, q)
    limit = float(np.percentile(cond, 60))
    r = feasibility(model, t, q, qd, qdd, scene_of(model).controller, cond_limit=limit)
    got = [(v.sample, round(v.duration / DT)) for v in r.violations if v.quantity == "cond"]
    # the limit is a sample's own cond (and the roll's symmetry gives it twins): those within
    # ROUNDING_BAND of it may fall on either side, every other sample may not
    flagged = runs_mask(got, cond.size)
    assert agrees_at_limit(flagged, cond, limit) and len(got) >= 2 and got == _runs(flagged)
    assert all(v.leg is None and v.limit == limit for v in r.violations if v.quantity == "cond")


def test_a_scene_without_a_controller_reports_no_current_and_says_why():
    data = scene_dict("sim")
    del data["controller"]
    model = scene_from_dict(data)
    t, q, qd, qdd = _sine(model, 2, 0.1, 0.5)
    r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
    assert r.current is None and r.voltage is None and r.force_limit is None
    assert "controller" in r.drive_note
    assert {m.quantity for m in r.margins} == {"stroke_min", "stroke_max", "cond"}
    np.testing.assert_array_equal(r.sigma, inverse_dynamics(model, q, qd, qdd))


def test_a_scene_without_stroke_limits_checks_no_stroke():
    model = replace(_model(), leg_min=None, leg_max=None)
    t, q, qd, qdd = _sine(model, 2, 0.1, 0.5)
    r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
    assert not any(m.quantity.startswith("stroke") for m in r.margins)


def test_a_scene_with_a_controller_but_no_drive_says_why():
    data = scene_dict("sim")
    del data["drive"]
    model = scene_from_dict(data)
    t, q, qd, qdd = _sine(model, 2, 0.1, 0.5)
    r = feasibility(model, t, q, qd, qdd, scene_of(model).controller)
    assert r.current is None and "[drive]" in r.drive_note


def test_a_malformed_controller_table_is_an_error_not_a_note():
    data = scene_dict("sim")
    data["controller"]["motor"]["resistance"] = -1.0
    model = scene_from_dict(data)
    t, q, qd, qdd = _sine(model, 2, 0.1, 0.5)
    with pytest.raises(SceneError, match="controller.motor.resistance"):
        feasibility(model, t, q, qd, qdd, scene_of(model).controller)
