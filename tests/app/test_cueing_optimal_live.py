"""The model-predictive cueing live (stewart_sim/live/optimal_stream.py), on a simulated clock:
a vehicle at rest leaves the platform exactly at home (no false cue: zero specific-force error,
exactly), also before a held-out forward step, after which the cue has the step's sign; the
flown q, qd, qdd are one trajectory across the MPC steps; a lead of several steps flies rest
until the first plan and re-plans every `lead` steps; bad telemetry is refused; bad options
raise. The real-time worker is checked only where its timing cannot change the outcome (rest)."""
from __future__ import annotations

import dataclasses
import multiprocessing

import numpy as np
import pytest

from stewart_sim.cueing.vestibular import delivered_motion
from stewart_sim.live.optimal_stream import LiveOptimal, LiveOptimalError
from stewart_sim.scene.cueing_config import cueing_config
from stewart_sim.scene.load import load
from tests.helpers import ROOT

LOOP = 1e-3      # s, the live loop's period
RATE = 50.0      # Hz, the MPC's
HORIZON = 0.4    # s: 20 steps, a short horizon keeps the tests quick (same formulation)


@pytest.fixture(scope="module")
def scene():
    return load(ROOT / "scenes" / "motion_simulator.toml")


def live(scene, blocking: int = 1, horizon: float = HORIZON, **kw) -> LiveOptimal:
    model = scene.model
    options = dataclasses.replace(scene.optimal, rate=RATE, horizon=horizon, blocking=blocking)
    return LiveOptimal(model, cueing_config(model), model.home, model.gravity, scene.controller,
                       options, **kw)


def fly(mpc: LiveOptimal, scene, duration: float, step_at: float | None = None,
        step: float = 2.0):
    """Drive the live MPC at 1 kHz on a simulated clock: rest, then (from step_at) a forward
    specific force of `step` m/s^2. Returns t, the vehicle's f, and q, qd, qdd."""
    g = float(np.linalg.norm(scene.model.gravity))
    t = np.arange(round(duration / LOOP) + 1) * LOOP
    f = np.zeros((t.size, 3))
    f[:, 2] = g
    if step_at is not None:
        f[t >= step_at, 0] = step
    out = []
    for k in range(t.size):
        mpc.push(t[k], f[k], np.zeros(3))
        out.append(mpc.sample(t[k]))
    q, qd, qdd = (np.array(a) for a in zip(*out))
    return t, f, q, qd, qdd


def assert_one_trajectory(t, q, qd):
    """q is the integral of qd sample to sample (trapezoid: exact within an MPC step, qd being
    linear there; across a step's end exact only if q and qd are continuous)."""
    dq = np.diff(q, axis=0)
    trap = 0.5 * (qd[1:] + qd[:-1]) * np.diff(t)[:, None]
    assert np.max(np.abs(dq - trap)) < 1e-7


def test_rest_is_home_exactly_with_no_specific_force_error(scene):
    mpc = live(scene, synchronous=True)
    t, f, q, qd, qdd = fly(mpc, scene, 1.0)
    home = np.asarray(scene.model.home, float)
    assert np.array_equal(q, np.tile(home, (t.size, 1)))
    assert not np.any(qd) and not np.any(qdd)
    delivered_f, delivered_w = delivered_motion(t, q, qd, qdd, scene.model.gravity)
    assert np.array_equal(delivered_f - f, np.zeros_like(f))
    assert not np.any(delivered_w)
    stats = mpc.stats()
    assert stats.steps == 51 and stats.late == 0 and stats.refused == 0
    assert stats.status_counts == {"solved": stats.solves}


def test_held_out_step_no_cue_before_it_and_the_right_sign_after(scene):
    mpc = live(scene, synchronous=True)
    t, f, q, qd, qdd = fly(mpc, scene, 2.0, step_at=1.0)
    delivered_f, _ = delivered_motion(t, q, qd, qdd, scene.model.gravity)
    before = t < 1.0
    assert np.array_equal(delivered_f[before] - f[before], np.zeros((before.sum(), 3)))
    assert np.array_equal(q[before], np.tile(scene.model.home, (before.sum(), 1)))
    # after the step: a forward specific force is cued forward (the one step's delay passed)
    after = t >= 1.1
    assert np.mean(delivered_f[after, 0]) > 0.2
    assert_one_trajectory(t, q, qd)
    assert mpc.stats().status_counts == {"solved": mpc.stats().solves}


def test_blocking_keeps_rest_exact_and_cues_the_step(scene):
    """Move blocking (5 MPC steps per prediction step, 1 s horizon: the live setting): no cue
    before the step, exactly; the step cued forward; one trajectory (the blocks refined to the
    MPC steps exactly); every QP solved."""
    mpc = live(scene, blocking=5, horizon=1.0, synchronous=True)
    t, f, q, qd, qdd = fly(mpc, scene, 2.0, step_at=1.0)
    delivered_f, _ = delivered_motion(t, q, qd, qdd, scene.model.gravity)
    before = t < 1.0
    assert np.array_equal(delivered_f[before] - f[before], np.zeros((before.sum(), 3)))
    assert np.array_equal(q[before], np.tile(scene.model.home, (before.sum(), 1)))
    assert np.mean(delivered_f[t >= 1.1, 0]) > 0.2
    assert_one_trajectory(t, q, qd)
    assert mpc.stats().status_counts == {"solved": mpc.stats().solves}


def test_a_lead_of_three_steps_flies_rest_until_its_first_plan(scene):
    mpc = live(scene, synchronous=True, lead_steps=3)
    t, f, q, qd, qdd = fly(mpc, scene, 0.5, step_at=0.0)
    dt = 1.0 / RATE
    # the first solve is started at step 0 for step 3: steps 0-2 fly rest
    first = t < 3 * dt - 1e-9
    assert np.array_equal(q[first], np.tile(scene.model.home, (first.sum(), 1)))
    assert np.any(q[t >= 3 * dt] != scene.model.home)
    assert_one_trajectory(t, q, qd)
    stats = mpc.stats()
    # one solve out at a time: a re-plan every third step (steps 0, 3, ..., 24)
    assert stats.steps == 26 and stats.solves == 9 and stats.lead_max == 3 and stats.late == 0


def test_bad_telemetry_is_refused_and_moves_nothing(scene):
    mpc = live(scene, synchronous=True)
    g = float(np.linalg.norm(scene.model.gravity))
    mpc.push(0.0, (0.0, 0.0, g), np.zeros(3))
    mpc.push(0.002, (0.0, 0.0, g), np.zeros(3))
    mpc.push(0.003, (np.nan, 0.0, g), np.zeros(3))
    mpc.push(0.002, (5.0, 0.0, g), np.zeros(3))          # not after the last
    mpc.push(0.001, (5.0, 0.0, g), np.zeros(3))          # out of order
    mpc.push(np.inf, (0.0, 0.0, g), np.zeros(3))
    mpc.push(0.003, (0.0, 0.0, g), (0.0, np.inf, 0.0))
    mpc.push(0.003, (0.0, g), np.zeros(3))                # wrong length
    for k in range(40):
        q, qd, qdd = mpc.sample(k * 0.001)
        assert np.array_equal(q, scene.model.home) and not np.any(qd) and not np.any(qdd)
    assert mpc.stats().refused == 6
    with pytest.raises(LiveOptimalError, match="finite"):
        mpc.sample(np.nan)


def test_bad_options_raise(scene):
    model = scene.model
    slow = dataclasses.replace(scene.optimal, rate=20.0)
    with pytest.raises(LiveOptimalError, match="rate must be >= 50"):
        LiveOptimal(model, cueing_config(model), model.home, model.gravity, scene.controller,
                    slow, synchronous=True)
    with pytest.raises(LiveOptimalError, match="lead_steps"):
        live(scene, synchronous=True, lead_steps=20)


def test_real_time_worker_at_rest_is_home_whatever_its_timing(scene):
    # late or not, every plan at rest is rest: the outcome does not depend on the clock
    with live(scene) as mpc:
        t, f, q, qd, qdd = fly(mpc, scene, 0.2)
        assert np.array_equal(q, np.tile(scene.model.home, (t.size, 1)))
        assert not np.any(qd) and not np.any(qdd)
        assert len(multiprocessing.active_children()) == 1
    assert multiprocessing.active_children() == []
