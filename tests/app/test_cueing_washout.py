"""The classical washout (stewart_sim/cueing/washout.py) and its [cueing] table, by physics:
tilt-coordination sign and steady tilt, washout of a step within the filters' own time, the
neutral pose for no motion, the yaw high-pass against its closed form, the discretisation's
order, the platform's delivered angular velocity against an independent filter, the stroke of
the shipped motion simulator, and the table's named errors."""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from scipy import signal
from scipy.optimize import brentq

from stewart_fmu import scene_from_dict
from stewart_fmu.errors import SceneError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.rotations import euler_motion
from stewart_sim.cueing.filters import high_pass_denominator
from stewart_sim.cueing.motion import VehicleMotion, read_motion
from stewart_sim.cueing.washout import classical_washout
from stewart_sim.scene.cueing_config import DEFAULTS, CueingConfig, cueing_config
from stewart_sim.scene.describe import describe
from stewart_sim.scene.load import scene_of
from tests.helpers import ROOT, level_model, scene_dict, smooth_step
from tests.helpers import vehicle_motion as motion

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])
HOME = np.array([0.0, 0.0, 2.3, 0.0, 0.0, 0.0])




def frames(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray):
    """R, omega and alpha in N of pose rows (the contract's E through stewart_fmu.rotations)."""
    n = q.shape[0]
    R, om, al = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    euler_motion(q, qd, qdd, R, om, al)
    return R, om, al


def test_no_vehicle_motion_is_the_neutral_pose_exactly():
    t = np.arange(0.0, 20.0, 0.01)
    cue = classical_washout(DEFAULTS, motion(t), HOME, GRAVITY)
    assert np.array_equal(cue.q, np.tile(HOME, (t.size, 1)))
    assert not np.any(cue.qd) and not np.any(cue.qdd) and not np.any(cue.tilt)
    assert np.array_equal(cue.t, t)


def test_sustained_forward_force_ends_as_nose_up_tilt_within_the_rate_limit():
    h, A = 0.01, 0.3 * G                       # 0.3 g forward, sustained
    t = np.arange(0.0, 60.0, h)
    f = np.zeros((t.size, 3))
    f[:, 0] = A * smooth_step(t, 1.0, 0.5)
    cue = classical_washout(DEFAULTS, motion(t, f), HOME, GRAVITY)
    k = DEFAULTS.translational_gain[0]
    expected = -math.asin(k * A / G)            # thy < 0: nose up (thy > 0 tips x down)
    assert expected < 0
    assert cue.q[-1, 4] == pytest.approx(expected, abs=1e-12)
    assert cue.tilt[-1, 1] == pytest.approx(expected, abs=1e-12)
    limit = DEFAULTS.tilt_rate_limit
    rate = np.diff(cue.tilt[:, 1]) / h
    assert np.max(np.abs(rate)) <= limit * (1 + 1e-12)
    assert np.max(np.abs(cue.qd[:, 4])) <= limit        # no rotation: the tilt is the angle
    assert np.max(np.abs(cue.qd[:, 4])) == limit        # the limit was reached (it acted)
    # The tilt delivers the force: in the platform's own frame, at rest, f = R^T (a - g).
    R, _, _ = frames(cue.q, cue.qd, cue.qdd)
    f_platform = R[-1].T @ (cue.qdd[-1, :3] - GRAVITY)
    assert f_platform[0] == pytest.approx(k * A, abs=1e-9)
    assert f_platform[1] == pytest.approx(0.0, abs=1e-12)
    # and the translational channel (third order) has washed out back to the neutral position
    assert np.allclose(cue.q[-1, :3], HOME[:3], atol=1e-6)


def _step_response_third_order(t: np.ndarray, w: float, b: float) -> np.ndarray:
    """Inverse Laplace of 1 / ((s + w)^2 (s + b)) (damping 1), t >= 0: the position under a unit
    acceleration step through s^3 / ((s^2 + 2 w s + w^2)(s + b)) integrated twice."""
    alpha, gamma = 1.0 / (w - b) ** 2, 1.0 / (b - w)
    return alpha * np.exp(-b * t) - alpha * np.exp(-w * t) + gamma * t * np.exp(-w * t)


def test_translational_step_washes_out_within_the_filters_time():
    cfg = dataclasses.replace(DEFAULTS, tilt_limit=0.0)   # the translational channel alone
    h, A, k0 = 0.005, 2.0, 200
    t = np.arange(0.0, 40.0, h)
    f = np.zeros((t.size, 3))
    f[k0:, 0] = A                                         # a sustained step (ramp over one sample)
    cue = classical_washout(cfg, motion(t, f), HOME, GRAVITY)
    w, b, z = (cfg.translational_frequency[0], cfg.translational_first_order[0],
               cfg.translational_damping[0])
    assert z == 1.0 and cfg.translational_order == 3
    a = cfg.translational_gain[0] * A
    # Exact continuous response to the linearly interpolated input: the step response averaged
    # over the ramp's sample (Gauss-Legendre, the integrand is smooth there).
    nodes, weights = np.polynomial.legendre.leggauss(20)
    tau = 0.5 * h * (nodes + 1.0)
    s = t[k0:, None] - t[k0 - 1] - tau[None, :]
    exact = a * (_step_response_third_order(s, w, b) @ (0.5 * weights))
    x = cue.q[:, 0] - HOME[0]
    assert np.array_equal(x[:k0], np.zeros(k0))
    assert np.max(np.abs(x[k0:] - exact)) <= 1e-12 * np.max(np.abs(exact))
    # Washout time from the filter: |x(t)| <= a (alpha e^-bt + alpha e^-wt + |gamma| t e^-wt);
    # the bound falls below eps at T_eps. After it the platform is back at neutral within eps.
    alpha, gamma = 1.0 / (w - b) ** 2, 1.0 / abs(b - w)
    eps = 1e-3
    bound = lambda s: a * (alpha * np.exp(-b * s) + alpha * np.exp(-w * s)
                           + gamma * s * np.exp(-w * s)) - eps
    t_eps = brentq(bound, 1.0 / w, 100.0)
    after = t >= t[k0] + t_eps
    assert after[-1]                                      # the record runs past T_eps
    assert np.max(np.abs(cue.q[after] - HOME)) <= eps
    assert np.max(np.abs(x)) > 10 * eps                  # it did move first
    # a second-order high-pass keeps the steady offset a / w^2 (why the default is third order)
    cfg2 = dataclasses.replace(cfg, translational_order=2)
    cue2 = classical_washout(cfg2, motion(t, f), HOME, GRAVITY)
    assert cue2.q[-1, 0] - HOME[0] == pytest.approx(a / w ** 2, rel=1e-9)


def _yaw_closed_form(t: np.ndarray, rate: float, w: float, z: float) -> np.ndarray:
    """Yaw under a rate step through s^2 / (s^2 + 2 z w s + w^2), integrated: the impulse
    response of rate / (s^2 + 2 z w s + w^2)."""
    if z == 1.0:
        return rate * t * np.exp(-w * t)
    wd = w * math.sqrt(1.0 - z * z)
    return rate / wd * np.exp(-z * w * t) * np.sin(wd * t)


def test_yaw_rate_step_gives_a_high_passed_yaw_that_returns_to_zero():
    cfg = DEFAULTS
    w, z, k = cfg.rotational_frequency[2], cfg.rotational_damping[2], cfg.rotational_gain[2]
    rate = 0.3                                          # rad/s; scaled 0.15, under the limit
    assert k * rate < cfg.rotational_limit[2] and cfg.rotational_order == 2
    errors = []
    for h in (0.004, 0.002, 0.001):
        t = np.arange(0.0, 40.0, h)
        k0 = round(1.0 / h)
        wv = np.zeros((t.size, 3))
        wv[k0:, 2] = rate
        cue = classical_washout(cfg, motion(t, w=wv), HOME, GRAVITY)
        # pure yaw: nothing else moves, exactly
        assert np.array_equal(cue.q[:, :5], np.tile(HOME[:5], (t.size, 1)))
        yaw = cue.q[:, 5]
        # the FOH input ramps over [t_{k0-1}, t_{k0}]: a step at its middle to O(h^2)
        exact = _yaw_closed_form(np.maximum(t - (t[k0] - h / 2), 0.0), k * rate, w, z)
        errors.append(np.max(np.abs(yaw - exact)))
        peak = k * rate / (w * math.e)                 # at t = 1 / w (z = 1)
        assert np.max(yaw) == pytest.approx(peak, rel=1e-5)
        assert abs(yaw[-1]) < 1e-9 * peak              # returned to zero
    # second order in h
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.9), (errors, orders)


def _smooth_motion(h: float):
    """A smooth combined motion inside every limit (no saturation, tilt below its rate
    limit): surge and sway bumps, roll, pitch and yaw rates."""
    t = np.arange(0.0, 12.0, h)
    bump = lambda t0, T: np.sin(np.pi * np.clip((t - t0) / T, 0, 1)) ** 4
    f = np.column_stack([0.8 * bump(1.0, 3.0), -0.4 * bump(2.0, 4.0), 0.8 * bump(1.5, 2.0)])
    wv = np.column_stack([0.2 * bump(1.0, 2.5), -0.15 * bump(2.0, 3.0), 0.3 * bump(1.2, 4.0)])
    return t, motion(t, f, wv)


def test_rates_and_accelerations_are_the_derivatives_to_second_order():
    err_d, err_dd = [], []
    for h in (0.01, 0.005, 0.0025):
        t, mo = _smooth_motion(h)
        cue = classical_washout(DEFAULTS, mo, HOME, GRAVITY)
        # inside the tilt-rate limit (a limited tilt has a kink in its rate: first order)
        assert np.max(np.abs(np.diff(cue.tilt, axis=0))) < 0.9 * DEFAULTS.tilt_rate_limit * h
        assert np.max(np.abs(cue.tilt)) > 0.01                 # rad: the tilt did act
        fd = (cue.q[2:] - cue.q[:-2]) / (2 * h)
        fdd = (cue.qd[2:] - cue.qd[:-2]) / (2 * h)
        err_d.append(np.max(np.abs(fd - cue.qd[1:-1]), axis=0))
        err_dd.append(np.max(np.abs(fdd - cue.qdd[1:-1]), axis=0))
    for errs in (np.array(err_d), np.array(err_dd)):
        assert np.all(errs[-1] < 1e-4)
        orders = np.log2(errs[:-1] / errs[1:])
        assert np.all((orders > 1.9) & (orders < 2.1)), (errs, orders)


def test_platform_angular_velocity_is_the_high_passed_vehicle_rate():
    """Without tilt the platform's angular velocity in its own frame, R^T E thetadot, is the
    scaled vehicle rate through the rotational high-pass, and its derivative R^T alpha the
    filtered angular acceleration: against scipy's lsim of each transfer function."""
    cfg = dataclasses.replace(DEFAULTS, tilt_limit=0.0)
    h = 0.002
    t, mo = _smooth_motion(h)
    cue = classical_washout(cfg, mo, HOME, GRAVITY)
    R, om, al = frames(cue.q, cue.qd, cue.qdd)
    body = np.einsum("nji,nj->ni", R, om)
    body_acc = np.einsum("nji,nj->ni", R, al)      # d/dt (R^T omega) = R^T alpha
    u = np.asarray(cfg.rotational_gain) * mo.angular_velocity
    for i in range(3):
        den = high_pass_denominator(cfg.rotational_frequency[i], cfg.rotational_damping[i], 2)
        _, y, _ = signal.lsim((np.array([1.0, 0.0, 0.0]), den), u[:, i], t)
        # d/dt HP(u) = HP(du/dt): the filter on the input's derivative (smooth, O(h^2))
        _, yd, _ = signal.lsim((np.array([1.0, 0.0, 0.0]), den), np.gradient(u[:, i], h), t)
        assert np.max(np.abs(body[:, i] - y)) < 1e-6 * np.max(np.abs(y))
        assert np.max(np.abs(body_acc[:, i] - yd)) < 1e-3 * np.max(np.abs(yd))


def _shipped_kinds(h: float) -> dict[str, VehicleMotion]:
    """The kinds of motion the project ships (scenes/motions/): a braking car (0.8 g for 3 s),
    a lane change (+-0.4 g lateral over 4 s with the yaw rate a_y / V of a car at 25 m/s) and an
    aircraft take-off (0.3 g roll for 30 s, then rotation at 3 deg/s nose up for 3 s)."""
    out = {}
    t = np.arange(0.0, 15.0, h)
    f = np.zeros((t.size, 3))
    f[:, 0] = -0.8 * G * (smooth_step(t, 1.0, 0.3) - smooth_step(t, 4.0, 0.3))
    out["braking"] = motion(t, f)
    t = np.arange(0.0, 12.0, h)
    ay = 0.4 * G * np.sin(2 * np.pi * (t - 1.0) / 4.0) * ((t >= 1.0) & (t <= 5.0))
    f, wv = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    f[:, 1], wv[:, 2] = ay, ay / 25.0
    out["lane change"] = motion(t, f, wv)
    t = np.arange(0.0, 45.0, h)
    f, wv = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    f[:, 0] = 0.3 * G * smooth_step(t, 1.0, 0.5)
    wv[:, 1] = -np.deg2rad(3.0) * (smooth_step(t, 31.0, 0.2) - smooth_step(t, 34.0, 0.2))
    out["take-off"] = motion(t, f, wv)
    return out


@pytest.mark.parametrize("name", ["braking", "lane change", "take-off"])
def test_defaults_keep_the_motion_simulator_inside_its_stroke(name):
    model = level_model("sim", "full")
    cfg = cueing_config(model)
    mo = _shipped_kinds(0.01)[name]
    cue = classical_washout(cfg, mo, model.home, model.gravity)
    lengths = inverse_kinematics(model, cue.q).lengths     # raises if a leg leaves the stroke
    margin = min(lengths.min() - model.leg_min, model.leg_max - lengths.max())
    assert margin > 0.3                                      # m, room for stronger motions
    assert np.max(np.abs(cue.q[:, :3] - model.home[:3])) > 0.005  # the platform did move


@pytest.mark.parametrize("name", ["braking_car", "lane_change", "takeoff"])
def test_defaults_keep_the_shipped_motions_inside_the_stroke(name):
    """scenes/motions/*.csv (tools/vehicle_motions.py) through the scene's [cueing] table."""
    model = level_model("sim", "full")
    mo = read_motion(ROOT / "scenes" / "motions" / f"{name}.csv")
    cue = classical_washout(cueing_config(model), mo, model.home, model.gravity)
    lengths = inverse_kinematics(model, cue.q).lengths
    assert min(lengths.min() - model.leg_min, model.leg_max - lengths.max()) > 0.3


def test_scene_table_holds_the_defaults():
    assert cueing_config(level_model("sim", "full")) == DEFAULTS
    data = scene_dict("sim")
    del data["cueing"]
    assert cueing_config(scene_from_dict(data)) == DEFAULTS
    data = scene_dict("sim")
    data["cueing"] = {"tilt_limit": 0, "rotational_order": 1, "translational_gain": [1, 0, 0.5]}
    cfg = cueing_config(scene_from_dict(data))
    assert cfg == dataclasses.replace(DEFAULTS, tilt_limit=0.0, rotational_order=1,
                                      translational_gain=(1.0, 0.0, 0.5))
    assert isinstance(cfg, CueingConfig)


@pytest.mark.parametrize("key, value, reason", [
    ("translational_speed", 1.0, "unknown key"),
    ("tilt_frequency", -1.0, "finite number > 0"),
    ("tilt_frequency", 0.0, "finite number > 0"),
    ("tilt_damping", float("nan"), "finite number"),
    ("tilt_rate_limit", float("inf"), "finite number"),
    ("tilt_limit", -0.1, ">= 0"),
    ("tilt_limit", 1.6, "below pi/2"),
    ("tilt_limit", True, "finite number"),
    ("translational_frequency", [2.5, -2.5, 4.0], "finite number > 0"),
    ("translational_limit", [4.0, 4.0], "list of 3 numbers"),
    ("translational_limit", [4.0, 0.0, 4.0], "finite number > 0"),
    ("rotational_gain", [0.5, -0.5, 0.5], ">= 0"),
    ("rotational_limit", "fast", "list of 3 numbers"),
    ("translational_order", 4, "one of (2, 3)"),
    ("translational_order", 3.0, "one of (2, 3)"),
    ("rotational_order", 3, "one of (1, 2)"),
])
def test_bad_cueing_values_name_the_key(key, value, reason):
    data = scene_dict("sim")
    data["cueing"][key] = value
    with pytest.raises(SceneError, match=re.escape(reason)) as err:
        cueing_config(scene_from_dict(data))
    assert err.value.key == f"cueing.{key}"


def test_cueing_must_be_a_table():
    data = scene_dict("sim")
    data["cueing"] = 3
    with pytest.raises(SceneError) as err:
        cueing_config(scene_from_dict(data))
    assert err.value.key == "cueing"


def test_scene_info_shows_the_cueing_table():
    data = scene_dict("sim")
    data["cueing"]["rotational_order"] = 1
    text = describe(scene_of(scene_from_dict(data)))
    line = next(x for x in text.splitlines() if x.startswith("cueing:"))
    assert "classical washout" in line and "rotational gain [0.5, 0.5, 0.5]" in line
    assert "high-pass order 1 at [1, 1, 1] rad/s" in line and "tilt low-pass 4 rad/s" in line
    del data["cueing"]
    assert "cueing: none" in describe(scene_of(scene_from_dict(data)))
