"""The classical washout stepped one sample at a time (stewart_sim/cueing/washout_step.py):
stepping a motion gives `classical_washout`'s cue (what `stewart-sim cue` writes) on the three
shipped motions and on a random one that saturates, limits the tilt rate and rotates; the
offline cue is causal (a motion's prefix gives the prefix of its cue); reset goes back to rest;
the tilt-rate limiter moves no sample by more than its step."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stewart_sim.cueing.config import DEFAULTS, CueingConfig, cueing_config
from stewart_sim.cueing.motion import read_motion
from stewart_sim.cueing.washout import Cue, classical_washout
from stewart_sim.cueing.washout_step import CueSample, WashoutStepper, rate_limit_step
from tests.helpers import ROOT, level_model
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
