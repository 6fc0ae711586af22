"""The classical washout stepped one sample at a time (stewart_sim/cueing/washout_step.py):
stepping a motion gives `classical_washout`'s cue (what `stewart-sim cue` writes) on the three
shipped motions and on a random one that saturates, limits the tilt rate and rotates; the
offline cue is causal (a motion's prefix gives the prefix of its cue); reset goes back to rest;
the tilt-rate limiter moves no sample by more than its step. The position limiter: a sustained
motion that takes the washout past the limit stays inside it with continuous velocity and
acceleration, a limit beyond the excursion changes nothing, stepped == offline with it on, and
its bad values name the key."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from stewart_fmu import scene_from_dict
from stewart_fmu.errors import SceneError
from stewart_sim.cueing.motion import read_motion
from stewart_sim.cueing.washout import Cue, classical_washout
from stewart_sim.cueing.washout_step import (
    CueSample,
    WashoutStepper,
    rate_limit_step,
    soft_limit,
)
from stewart_sim.scene.cueing_config import DEFAULTS, CueingConfig, cueing_config
from stewart_sim.scene.describe import describe
from stewart_sim.scene.load import scene_of
from tests.helpers import ROOT, level_model, scene_dict, smooth_step
from tests.helpers import vehicle_motion as motion

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])
HOME = np.array([0.0, 0.0, 2.3, 0.0, 0.0, 0.0])
TOL = 1e-12     # m, rad and their derivatives


def stepped(config: CueingConfig, mo, home, gravity) -> Cue:
    """The motion fed to a WashoutStepper one sample at a time, as a live loop would."""
    t = mo.t
    h = float((t[-1] - t[0]) / (t.size - 1))
    stepper = WashoutStepper(config, home, gravity, h)
    samples = [stepper.step(f, w) for f, w in zip(mo.specific_force, mo.angular_velocity)]
    assert all(isinstance(s, CueSample) for s in samples)
    return Cue(t=t, q=np.array([s.q for s in samples]), qd=np.array([s.qd for s in samples]),
               qdd=np.array([s.qdd for s in samples]), tilt=np.array([s.tilt for s in samples]))


def worst(a: Cue, b: Cue) -> float:
    return max(float(np.max(np.abs(getattr(a, k) - getattr(b, k))))
               for k in ("q", "qd", "qdd", "tilt"))


def random_motion(seed: int, h: float = 0.01, duration: float = 30.0):
    """Sums of random sines (surge and sway up to 0.8 g, heave, roll, pitch and yaw rates up to
    1.2 rad/s: the translational and rotational limits act) on a sustained 0.8 g surge from
    t = 2 s (the tilt limit and its rate limit act)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, h)
    cols = []
    for amp in (8.0, 8.0, 3.0, 1.2, 1.2, 1.2):
        w = rng.uniform(0.2, 6.0, 3)
        ph = rng.uniform(0.0, 2 * np.pi, 3)
        a = rng.uniform(-1.0, 1.0, 3) * amp / 2
        cols.append(np.sin(np.outer(t, w) + ph) @ a)
    x = np.column_stack(cols)
    x[:, 0] += 0.8 * G * np.clip((t - 2.0) / 0.5, 0.0, 1.0)
    return motion(t, x[:, :3], x[:, 3:])


@pytest.mark.parametrize("name", ["braking_car", "lane_change", "takeoff"])
def test_stepping_a_shipped_motion_gives_the_offline_cue(name):
    model = level_model("sim", "full")
    config = cueing_config(model)
    mo = read_motion(ROOT / "scenes" / "motions" / f"{name}.csv")
    offline = classical_washout(config, mo, model.home, model.gravity)
    live = stepped(config, mo, model.home, model.gravity)
    assert worst(live, offline) <= TOL
    assert np.max(np.abs(offline.q - model.home)) > 0.01       # the platform did move


@pytest.mark.parametrize("variant", [
    {},
    {"translational_order": 2, "rotational_order": 1},
    {"tilt_limit": 0.0},
    {"translational_gain": (1.0, 1.0, 1.0), "rotational_gain": (1.0, 1.0, 1.0)},
])
def test_stepping_a_random_motion_gives_the_offline_cue(variant):
    config = dataclasses.replace(DEFAULTS, **variant)
    mo = random_motion(seed=len(variant))
    offline = classical_washout(config, mo, HOME, GRAVITY)
    assert worst(stepped(config, mo, HOME, GRAVITY), offline) <= TOL
    if config.tilt_limit:
        # the limits acted: the tilt moves at its rate limit somewhere, reaches its angle
        step = config.tilt_rate_limit * 0.01
        assert np.max(np.abs(np.diff(offline.tilt, axis=0))) == pytest.approx(step, rel=1e-9)
        assert np.max(np.abs(offline.tilt)) == pytest.approx(config.tilt_limit, rel=1e-9)


def test_the_offline_cue_is_causal():
    """The cue up to a sample depends on the motion up to it only: a prefix of the motion
    gives the prefix of the cue, whatever follows."""
    mo = random_motion(seed=7, duration=20.0)
    full = classical_washout(DEFAULTS, mo, HOME, GRAVITY)
    k = 1234
    prefix = dataclasses.replace(mo, t=mo.t[:k], specific_force=mo.specific_force[:k],
                                 angular_velocity=mo.angular_velocity[:k])
    part = classical_washout(DEFAULTS, prefix, HOME, GRAVITY)
    for key in ("q", "qd", "qdd", "tilt"):
        assert np.max(np.abs(getattr(part, key) - getattr(full, key)[:k])) <= TOL


def test_reset_goes_back_to_rest():
    mo = random_motion(seed=3, duration=5.0)
    stepper = WashoutStepper(DEFAULTS, HOME, GRAVITY, 0.01)
    first = [stepper.step(f, w) for f, w in zip(mo.specific_force, mo.angular_velocity)]
    stepper.reset()
    again = [stepper.step(f, w) for f, w in zip(mo.specific_force, mo.angular_velocity)]
    for a, b in zip(first, again):
        for key in ("q", "qd", "qdd", "tilt"):
            assert np.array_equal(getattr(a, key), getattr(b, key))
    stepper.reset()
    rest = stepper.step([0.0, 0.0, G], [0.0, 0.0, 0.0])
    assert np.array_equal(rest.q, HOME) and not np.any(rest.qd) and not np.any(rest.qdd)


def test_rate_limit_step_moves_no_sample_further_than_its_step():
    rng = np.random.default_rng(11)
    limit, h = 0.05, 0.01
    step = limit * h
    cmd = np.cumsum(rng.normal(0.0, 2.0 * step, 2000))       # often faster than the limit
    lag, prev, out = None, cmd[0], [cmd[0]]
    lagged = 0
    for c in cmd[1:]:
        o, o_d, o_dd, lag = rate_limit_step(lag, prev, float(c), 0.0, 0.0, limit, step)
        prev = float(c)
        if lag is not None:
            lagged += 1
            assert abs(o_d) == limit and o_dd == 0.0
        else:
            assert o == c                    # on the command where it is not behind
        out.append(o)
    assert lagged > 100
    assert np.max(np.abs(np.diff(out))) <= step * (1 + 1e-12)


# --- the position limiter ([cueing] position_limit)

LIMIT = (0.1, 0.1, 0.05)      # m: below the unlimited excursion of SUSTAINED on every axis


def sustained(h: float):
    """A 0.8 g braking held 9 s, a 0.5 g sustained sway from t = 3 s and a 0.3 g heave bump:
    the unlimited washout moves the platform 0.36, 0.18 and 0.059 m."""
    t = np.arange(0.0, 20.0, h)
    f = np.zeros((t.size, 3))
    f[:, 0] = 0.8 * G * (smooth_step(t, 1.0, 0.5) - smooth_step(t, 10.0, 0.5))
    f[:, 1] = -0.5 * G * smooth_step(t, 3.0, 1.0)
    f[:, 2] = 0.3 * G * (smooth_step(t, 2.0, 0.3) - smooth_step(t, 2.5, 0.3))
    return motion(t, f)


def test_position_limit_keeps_a_sustained_motion_inside_with_continuous_rates():
    limited = dataclasses.replace(DEFAULTS, position_limit=LIMIT)
    jumps_d, jumps_dd, errs = [], [], []
    for h in (0.01, 0.005, 0.0025):
        mo = sustained(h)
        free = classical_washout(DEFAULTS, mo, HOME, GRAVITY)
        assert np.all(np.max(np.abs(free.q[:, :3] - HOME[:3]), axis=0) > np.array(LIMIT) * 1.15)
        cue = classical_washout(limited, mo, HOME, GRAVITY)
        pos = cue.q[:, :3] - HOME[:3]
        assert np.all(np.abs(pos) <= np.array(LIMIT))
        assert np.all(np.max(np.abs(pos), axis=0) > 0.9 * np.array(LIMIT))   # it did bind
        assert np.all(np.isfinite(cue.qd)) and np.all(np.isfinite(cue.qdd))
        # the angles are the washout's own: the limiter acts on the translation only
        assert np.array_equal(cue.q[:, 3:], free.q[:, 3:])
        # its braking: |a| <= |a_free| + 0.770 v_free^2 / room (washout_step's module doc)
        room = 0.5 * np.array(LIMIT)
        bound = np.abs(free.qdd[:, :3]) + 4 / (3 * np.sqrt(3)) * free.qd[:, :3] ** 2 / room
        assert np.all(np.abs(cue.qdd[:, :3]) <= bound + 1e-12)
        assert np.all(np.abs(cue.qd[:, :3]) <= np.abs(free.qd[:, :3]))
        jumps_d.append(np.max(np.abs(np.diff(cue.qd[:, :3], axis=0)), axis=0))
        jumps_dd.append(np.max(np.abs(np.diff(cue.qdd[:, :3], axis=0)), axis=0))
        # qd is the derivative of q (to second order in h)
        errs.append(np.max(np.abs((cue.q[2:, :3] - cue.q[:-2, :3]) / (2 * h) - cue.qd[1:-1, :3]),
                           axis=0))
    # continuous velocity and acceleration: the largest step of each between samples shrinks
    # with h (as h: a bounded acceleration and jerk); a jump would stay as h shrinks
    for jumps in (np.array(jumps_d), np.array(jumps_dd)):
        assert np.all(jumps[1:] < 0.6 * jumps[:-1]), jumps
    errs = np.array(errs)
    assert np.all(np.log2(errs[:-1] / errs[1:]) > 1.9), errs


def test_position_limit_beyond_the_excursion_is_the_unlimited_cue_exactly():
    mo = sustained(0.01)
    free = classical_washout(DEFAULTS, mo, HOME, GRAVITY)
    wide = dataclasses.replace(DEFAULTS, position_limit=(1.0, 1.0, 1.0))   # knee 0.5 m
    cue = classical_washout(wide, mo, HOME, GRAVITY)
    for key in ("q", "qd", "qdd", "tilt"):
        assert np.array_equal(getattr(cue, key), getattr(free, key))


@pytest.mark.parametrize("name", ["braking_car", "takeoff"])
def test_stepping_with_the_position_limit_gives_the_offline_cue(name):
    model = level_model("sim", "full")
    config = dataclasses.replace(cueing_config(model), position_limit=(0.02, 0.02, 0.01))
    mo = read_motion(ROOT / "scenes" / "motions" / f"{name}.csv")
    offline = classical_washout(config, mo, model.home, model.gravity)
    assert worst(stepped(config, mo, model.home, model.gravity), offline) <= TOL
    free = classical_washout(cueing_config(model), mo, model.home, model.gravity)
    assert np.max(np.abs(free.q[:, :3] - offline.q[:, :3])) > 1e-3      # the limit acted


def test_stepping_a_random_motion_with_the_position_limit_gives_the_offline_cue():
    config = dataclasses.replace(DEFAULTS, position_limit=LIMIT)
    mo = random_motion(seed=5)
    offline = classical_washout(config, mo, HOME, GRAVITY)
    assert worst(stepped(config, mo, HOME, GRAVITY), offline) <= TOL
    assert np.all(np.abs(offline.q[:, :3] - HOME[:3]) <= np.array(LIMIT))


def test_soft_limit_is_its_own_derivatives():
    """soft_limit's velocity and acceleration are f'(p) v and f'(p) a + f''(p) v^2: checked by
    mapping p(t) = A sin(t) through it and differencing the position it returns."""
    t = np.linspace(0.0, 2 * np.pi, 20001)
    h = t[1] - t[0]
    rows = np.array([soft_limit(2.0 * np.sin(x), 2.0 * np.cos(x), -2.0 * np.sin(x), 1.0)
                     for x in t])
    p, v, a = rows.T
    assert np.max(np.abs(p)) < 1.0 and np.max(np.abs(p)) > 0.9
    assert np.max(np.abs((p[2:] - p[:-2]) / (2 * h) - v[1:-1])) < 1e-6
    err = np.abs((v[2:] - v[:-2]) / (2 * h) - a[1:-1])
    # the jerk jumps at the knee (tanh'''(0) = -2): there the difference is first order
    far = np.abs(np.abs(2.0 * np.sin(t[1:-1])) - 0.5) > 0.01
    assert np.max(err[far]) < 1e-4 and np.max(err) < 10 * h      # a wrong f'' gives O(1)
    inside = np.abs(2.0 * np.sin(t)) <= 0.5
    assert np.array_equal(p[inside], 2.0 * np.sin(t[inside]))     # the linear zone: untouched


@pytest.mark.parametrize("value, reason", [
    ([0.1, 0.0, 0.1], "finite number > 0"),
    ([0.1, -0.1, 0.1], "finite number > 0"),
    ([0.1, float("inf"), 0.1], "finite number"),
    ([0.1, 0.1], "list of 3 numbers"),
    (0.1, "list of 3 numbers"),
])
def test_bad_position_limit_names_the_key(value, reason):
    data = scene_dict("sim")
    data["cueing"]["position_limit"] = value
    with pytest.raises(SceneError, match=re.escape(reason)) as err:
        cueing_config(scene_from_dict(data))
    assert err.value.key == "cueing.position_limit"


def test_position_limit_from_the_scene():
    data = scene_dict("sim")
    data["cueing"]["position_limit"] = [0.3, 0.25, 0.2]
    assert cueing_config(scene_from_dict(data)) == dataclasses.replace(
        DEFAULTS, position_limit=(0.3, 0.25, 0.2))
    assert "position limit [0.3, 0.25, 0.2] m" in describe(scene_of(scene_from_dict(data)))
