"""The live safety envelope on simulated time: a cue inside every limit passes bit for bit; a
step is followed at the speed and acceleration limits and never leaves the stroke; forces stay
under their limit; a near-singular or non-finite cue is refused (the last good pose held);
the emergency stop brakes within the limits and holds; the fade and the ramp-in. Leg lengths
and rates are checked against stewart_fmu.kinematics' numpy inverse kinematics (the envelope
steps with the C core's), forces against stewart_fmu.dynamics."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controller.trajectory import minimum_jerk
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import condition_number, inverse_kinematics
from stewart_fmu.scene import load_scene
from stewart_sim.live.envelope import LIMITS, Envelope, Margins, envelope_limits
from stewart_sim.live.fade import BLEND_TIME, FADE_FRACTION, Blend, fade_to_home
from stewart_sim.scene.load import scene_of

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
DT = 1e-3
Z = np.zeros(6)


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def limits(model):
    return envelope_limits(model, scene_of(model).controller)


def _home(model):
    return np.asarray(model.home, dtype=float)


def _quintic(model, offset, duration, n_hold=200):
    """Samples (q, qd, qdd) of a rest-to-rest quintic from home to home + offset, then held."""
    n = int(round(duration / DT))
    u = np.arange(n + 1) * DT / duration
    s, sd, sdd = minimum_jerk(u, duration)
    off = np.asarray(offset, dtype=float)
    q = _home(model) + s[:, None] * off
    q = np.vstack([q, np.repeat(q[-1:], n_hold, axis=0)])
    qd = np.vstack([sd[:, None] * off, np.zeros((n_hold, 6))])
    qdd = np.vstack([sdd[:, None] * off, np.zeros((n_hold, 6))])
    return q, qd, qdd


def _run(env, cue):
    return [env.step(q, qd, qdd) for q, qd, qdd in zip(*cue)]


def _stack(steps, name):
    return np.array([getattr(s, name) for s in steps])


def _within_limits(steps, lim, model):
    """Stroke, speed, leg acceleration (the reported one and the rates' differences, as the
    device sees the stream) and force of the samples sent, from our own kinematics."""
    q, qd, qdd = (_stack(steps, k) for k in ("q", "qd", "qdd"))
    kin = inverse_kinematics(model, q, qd, qdd)
    np.testing.assert_allclose(_stack(steps, "lengths"), kin.lengths, rtol=0, atol=1e-12)
    np.testing.assert_allclose(_stack(steps, "rates"), kin.rates, rtol=0, atol=1e-12)
    assert kin.lengths.min() >= lim.leg_min and kin.lengths.max() <= lim.leg_max
    assert np.abs(kin.rates).max() <= lim.speed
    assert np.abs(kin.accelerations).max() <= lim.acceleration
    assert np.abs(np.diff(kin.rates, axis=0)).max() / DT <= lim.acceleration
    return kin


def test_limits_sit_inside_the_device_bounds(model, limits):
    """The envelope's stroke inside the emulated device's setpoint bounds, its speed, force
    and cond inside the drive's and the device's."""
    pytest.importorskip("pymavlink")
    from hil.device import Device
    from hil.params import COND_MAX

    dev = Device(model)
    axis = dev.servo.ctrl.axis
    assert dev.capability.leg_min < limits.leg_min < limits.leg_max < dev.capability.leg_max
    assert limits.speed == pytest.approx(0.8 * axis.no_load_speed)
    assert limits.acceleration == pytest.approx(0.8 * axis.peak_acceleration)
    assert limits.force == pytest.approx(0.8 * axis.force_constant * axis.motor.current_limit)
    assert limits.cond < COND_MAX


SCENES = {"micro_manipulator": [0.004, -0.003, 0.01, 0.03, -0.02, 0.05],
          "motion_simulator": [0.05, -0.04, 0.08, 0.03, -0.02, 0.05]}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_a_cue_inside_every_limit_passes_bit_for_bit(scene):
    model = load_scene(SCENE.parent / f"{scene}.toml")
    limits = envelope_limits(model, scene_of(model).controller)
    cue = _quintic(model, SCENES[scene], 1.5)
    env = Envelope(model, limits, DT)
    steps = _run(env, cue)
    assert all(s.passed and s.limits == () for s in steps)
    for k, name in enumerate(("q", "qd", "qdd")):
        assert np.array_equal(_stack(steps, name), cue[k])
    np.testing.assert_allclose(_stack(steps, "forces"), inverse_dynamics(model, *cue),
                               rtol=1e-12, atol=1e-12)
    _within_limits(steps, limits, model)
    iv = env.interventions
    assert iv.samples == len(steps) and iv.limited == 0
    assert set(iv.per_limit) == set(LIMITS) and not any(iv.per_limit.values())
    assert json.loads(json.dumps(iv.as_dict())) == {
        "samples": len(steps), "limited": 0, "per_limit": dict.fromkeys(LIMITS, 0),
        "per_leg": {k: [0] * 6 for k in LIMITS}}


def test_the_same_cue_gives_the_same_samples(model, limits):
    """Deterministic: two envelopes fed the same (limited) cue send the same bits."""
    cue = _quintic(model, [0, 0, 0.04, 0.1, 0, 0], 0.05)
    a, b = (_run(Envelope(model, limits, DT), cue) for _ in range(2))
    for name in ("q", "qd", "qdd", "lengths", "rates", "forces"):
        assert np.array_equal(_stack(a, name), _stack(b, name))


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_a_step_is_followed_at_the_limits_inside_the_stroke(scene):
    """A heave step of a third of the envelope's stroke: the legs reach the speed and
    acceleration limits, never pass them, do not overshoot, and the cue passes unchanged
    again once caught up."""
    model = load_scene(SCENE.parent / f"{scene}.toml")
    limits = envelope_limits(model, scene_of(model).controller)
    target = _home(model) + [0, 0, (limits.leg_max - limits.leg_min) / 3, 0, 0, 0]
    env = Envelope(model, limits, DT)
    steps = [env.step(target, Z, Z) for _ in range(1000)]
    kin = _within_limits(steps, limits, model)
    end = inverse_kinematics(model, target).lengths
    travel = np.abs(end - kin.lengths[0]).min()
    # the speed limit is reached where the travel holds speeding up at a and braking at a / 2
    # (the tracking law's approach); otherwise the triangle's peak sqrt(2 a travel / 3)
    a, v = limits.acceleration, limits.speed
    reach = v if 1.5 * v * v / a < travel else 0.8 * np.sqrt(2 * a * travel / 3)
    assert np.abs(kin.rates).max() >= 0.98 * reach
    assert np.abs(np.diff(kin.rates, axis=0)).max() / DT >= 0.98 * limits.acceleration
    assert np.all(kin.lengths <= end + 1e-12)                    # no overshoot
    assert steps[-1].passed and np.array_equal(steps[-1].q, target)
    iv = env.interventions
    assert iv.per_limit["acceleration"] > 0 and (iv.per_limit["speed"] > 0) == (reach == v)
    assert np.all(iv.per_leg["acceleration"] > 0)


@pytest.mark.parametrize("offset", [[0, 0, 0.2, 0, 0, 0], [0, 0, -0.08, 0, 0, 0],
                                    [0.08, 0, 0, 0, 0, 0.8], [0.06, 0.06, 0, 0, 0, 0]])
def test_a_cue_past_the_stroke_stops_inside_it(model, limits, offset):
    """A cue that jumps far past the stroke: the platform runs at the limits towards it and
    stops inside the envelope's stroke (its braking distance kept), counted as stroke."""
    target = _home(model) + offset
    assert inverse_kinematics(model, target).lengths.max() > limits.leg_max \
        or inverse_kinematics(model, target).lengths.min() < limits.leg_min
    env = Envelope(model, limits, DT)
    steps = [env.step(target, Z, Z) for _ in range(1500)]
    kin = _within_limits(steps, limits, model)
    assert np.abs(kin.rates[-1]).max() < 1e-6              # stopped at its stop
    assert env.interventions.per_limit["stroke"] > 0
    assert not steps[-1].passed


def test_a_fast_ramp_into_the_stop_brakes_in_time(model, limits):
    """A cue already moving at the speed limit towards the stroke's end, past it: braking
    begins in time; nothing leaves the stroke."""
    n = 1500
    v = 0.9 * limits.speed
    t = np.arange(n) * DT
    q = np.repeat(_home(model)[None], n, axis=0)
    q[:, 2] += v * t
    qd = np.zeros((n, 6))
    qd[:, 2] = v
    env = Envelope(model, limits, DT)
    steps = _run(env, (q, qd, np.zeros((n, 6))))
    _within_limits(steps, limits, model)
    assert env.interventions.per_limit["stroke"] > 0


@pytest.mark.parametrize("seed", range(4))
def test_random_jumpy_cues_never_leave_the_stroke(model, limits, seed):
    """Fuzz: cues that jump every 20 to 200 samples to random poses (many far past the
    stroke) with random rates and accelerations, and hold there: every sample sent stays
    within the stroke, the speed and the acceleration."""
    rng = np.random.default_rng(seed)
    scale = np.array([0.05, 0.05, 0.08, 0.5, 0.5, 0.8])
    q, qd, qdd = [], [], []
    while len(q) < 1500:
        n = int(rng.integers(20, 200))
        pose = _home(model) + scale * rng.uniform(-1, 1, 6)
        rate, acc = 0.2 * scale * rng.uniform(-1, 1, 6), scale * rng.uniform(-1, 1, 6)
        q += [pose] * n
        qd += [rate] * n
        qdd += [acc] * n
    env = Envelope(model, limits, DT)
    steps = _run(env, (q, qd, qdd))
    _within_limits(steps, limits, model)
    assert env.interventions.per_limit["stroke"] > 0


def test_an_aggressive_cue_keeps_its_force_under_the_limit(model):
    """A 25 Hz heave shake within the kinematic limits asks more than a tight force limit:
    the forces sent stay under it (evaluated at each step's start state: 1e-3 of slack)."""
    lim = envelope_limits(model, scene_of(model).controller, Margins(force=0.7))
    n, w, amp = 600, 2 * np.pi * 25.0, 0.0012
    t = np.arange(n) * DT
    ramp, ramp_d, ramp_dd = minimum_jerk(np.clip(t / 0.2, 0, 1), 0.2)
    z, zd, zdd = amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)
    q = np.repeat(_home(model)[None], n, axis=0)
    qd, qdd = np.zeros((n, 6)), np.zeros((n, 6))
    q[:, 2] += ramp * z
    qd[:, 2] = ramp * zd + ramp_d * z
    qdd[:, 2] = ramp * zdd + 2 * ramp_d * zd + ramp_dd * z
    asked = np.abs(inverse_dynamics(model, q, qd, qdd)).max()
    assert asked > 1.5 * lim.force
    env = Envelope(model, lim, DT)
    steps = _run(env, (q, qd, qdd))
    forces = _stack(steps, "forces")
    np.testing.assert_allclose(forces, inverse_dynamics(model, *(_stack(steps, k) for k in
                                                                ("q", "qd", "qdd"))),
                               rtol=1e-12, atol=1e-9)
    assert np.abs(forces).max() <= lim.force * (1 + 1e-3)
    assert env.interventions.per_limit["force"] > 0


def test_a_near_singular_cue_is_refused_and_the_last_good_pose_held(model, limits):
    """A yaw out and back that climbs past a cond limit set between the home pose's and its
    peak: from the first refused sample the platform stops (passing the limit by its braking
    distance only) and holds near the last good pose; each refused sample is counted; the
    cue coming back below the limit is followed again, unchanged once caught up."""
    cond_home = condition_number(model, _home(model))
    ramp = _quintic(model, [0, 0, 0, 0, 0, 0.6], 1.0, n_hold=300)
    cue = tuple(np.vstack([a, b]) for a, b in zip(ramp, (ramp[0][::-1], -ramp[1][::-1],
                                                         ramp[2][::-1])))
    cond = np.array([condition_number(model, p) for p in cue[0]])
    limit = 0.5 * (cond_home + cond.max())
    env = Envelope(model, replace(limits, cond=limit), DT)
    steps = _run(env, cue)
    _within_limits(steps, limits, model)
    q = _stack(steps, "q")
    sent = np.array([condition_number(model, p) for p in q])
    refused = cond > limit
    first, last = int(np.argmax(refused)), len(refused) - 1 - int(np.argmax(refused[::-1]))
    good = steps[first - 1].q
    assert sent.max() <= limit * (1 + 1e-3)
    assert np.abs(q[first:last + 1] - good).max() < 3e-3      # rad: held near the last good
    assert all(not s.passed and "cond" in s.limits for s in steps[first:last + 1])
    iv = env.interventions
    assert iv.per_limit["cond"] == int(refused.sum()) and not iv.per_leg["cond"].any()
    assert steps[-1].passed and np.array_equal(steps[-1].q, cue[0][-1])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_cue_is_refused(model, limits, bad):
    env = Envelope(model, limits, DT)
    q = _home(model).copy()
    q[3] = bad
    s = env.step(q, Z, Z)
    assert not s.passed and s.limits == ("invalid",)
    assert np.array_equal(s.q, _home(model)) and np.all(np.isfinite(s.forces))
    assert env.interventions.per_limit["invalid"] == 1


def test_the_emergency_stop_brakes_within_the_limits_and_holds(model, limits):
    """Moving at 90 % of the speed limit, the brake stops every leg within the acceleration
    limit in about v / a, then holds the pose exactly."""
    n = 100
    v = 0.9 * limits.speed
    q = np.repeat(_home(model)[None], n, axis=0)
    q[:, 0] += v * np.arange(n) * DT
    qd = np.zeros((n, 6))
    qd[:, 0] = v
    env = Envelope(model, limits, DT)
    moving = _run(env, (q, qd, np.zeros((n, 6))))
    stop = [env.brake() for _ in range(200)]
    _within_limits(moving + stop, limits, model)
    rates = _stack(stop, "rates")
    k = int(np.argmax(np.abs(rates).max(axis=1) == 0.0))
    assert k > 0 and k * DT <= v / limits.acceleration * 1.5 + 2 * DT
    assert np.array_equal(stop[-1].q, stop[k].q)


def test_fade_goes_home_within_a_fraction_of_the_limits(model, limits):
    """The fade from an offset pose passes the envelope unchanged, its legs within
    FADE_FRACTION of the speed and acceleration limits, and ends at home at rest."""
    start = _home(model) + [0.01, -0.008, 0.02, 0.05, -0.04, 0.1]
    env = Envelope(model, limits, DT, start=start)
    fade = fade_to_home(model, limits, start, t0=0.0)
    n = int(np.ceil(fade.duration / DT)) + 50
    steps = [env.step(*fade.sample(k * DT)) for k in range(n)]
    assert all(s.passed for s in steps) and fade.done(n * DT)
    kin = _within_limits(steps, limits, model)
    assert np.abs(kin.rates).max() <= FADE_FRACTION * limits.speed * 1.05
    assert np.abs(kin.accelerations).max() <= FADE_FRACTION * limits.acceleration * 1.05
    assert np.array_equal(steps[-1].q, _home(model)) and not steps[-1].qd.any()


def test_a_fade_from_motion_is_absorbed_by_the_envelope(model, limits):
    """A fade that begins while the platform moves (a rate jump) stays within the limits."""
    n = 300
    v = 0.8 * limits.speed
    q = np.repeat(_home(model)[None], n, axis=0)
    q[:, 2] += v * np.arange(n) * DT
    qd = np.zeros((n, 6))
    qd[:, 2] = v
    env = Envelope(model, limits, DT)
    steps = _run(env, (q, qd, np.zeros((n, 6))))
    fade = fade_to_home(model, limits, steps[-1].q, t0=n * DT)
    m = int(np.ceil(fade.duration / DT)) + 300
    steps += [env.step(*fade.sample((n + k) * DT)) for k in range(m)]
    _within_limits(steps, limits, model)
    assert steps[-1].passed and np.array_equal(steps[-1].q, _home(model))


def test_blend_ramps_the_cue_in_from_rest(model):
    start = _home(model) + [0, 0, 0.01, 0, 0, 0]
    cue = (_home(model) + [0.01, 0, 0, 0, 0, 0.1], np.full(6, 0.2), np.full(6, 3.0))
    b = Blend(start, t0=2.0)
    q, qd, qdd = b.apply(2.0, *cue)
    assert np.array_equal(q, start) and not qd.any() and not qdd.any()
    q, qd, qdd = b.apply(2.0 + BLEND_TIME, *cue)
    np.testing.assert_allclose(q, cue[0], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(qd, cue[1])
    np.testing.assert_array_equal(qdd, cue[2])
    assert b.done(2.0 + BLEND_TIME) and not b.done(2.0 + 0.5 * BLEND_TIME)
    # the product rule: the blended rate is the derivative of the blended pose
    h = 1e-6
    mid = 2.0 + 0.4 * BLEND_TIME
    const = (cue[0], np.zeros(6), np.zeros(6))
    num = (b.apply(mid + h, *const)[0] - b.apply(mid - h, *const)[0]) / (2 * h)
    np.testing.assert_allclose(b.apply(mid, *const)[1], num, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("name, value", [("speed", 1.0), ("force", -0.1), ("stroke", np.nan)])
def test_a_margin_outside_its_range_is_refused(model, name, value):
    with pytest.raises(ValueError, match=f"margin '{name}' must be in"):
        envelope_limits(model, scene_of(model).controller, Margins(**{name: value}))


def test_a_scene_without_drives_is_refused():
    from stewart_fmu.errors import SceneError
    from tests.helpers import level_model

    model = level_model("sim", "full")
    with pytest.raises(SceneError, match="drives' limits"):
        envelope_limits(model, None)


def test_start_outside_the_stroke_is_refused(model, limits):
    with pytest.raises(ValueError, match="start pose"):
        Envelope(model, limits, DT, start=_home(model) + [0, 0, 0.2, 0, 0, 0])


def test_the_emulated_device_accepts_every_setpoint_and_stays_in_its_stroke(model, limits):
    """The envelope's samples of a cue that jumps past the stroke's end and back, sent as
    LEG_SETPOINTs (lengths, rates, feed-forward forces) to the emulated device at its rate:
    the device refuses none, does not fault, and its legs stay inside the stroke."""
    pytest.importorskip("pymavlink")
    from hil import mavlink_stewart as ms
    from hil.device import Device
    from hil.operating_mode import Mode

    dev = Device(model, watchdog=1.0)
    assert dev.dt == DT
    dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                                0, 0, 0, 0, 0, 0))
    env = Envelope(model, limits, DT)
    flags = ms.STEWART_SETPOINT_FLAG_RATE_VALID | ms.STEWART_SETPOINT_FLAG_FORCE_VALID
    far = _home(model) + [0.02, 0, 0.2, 0, 0, 0.3]
    texts, lengths = [], []
    for k in range(1200):
        s = env.step(far if k < 700 else _home(model), Z, Z)
        out = dev.receive(ms.MAVLink_leg_setpoint_message(
            k * 1000, k, s.lengths.tolist(), s.rates.tolist(), flags, s.forces.tolist()))
        out += dev.tick()
        texts += [m.text for m in out if m.get_type() == "STATUSTEXT"]
        lengths.append(dev.plant.outputs.lengths.copy())
    assert texts == [] and dev.mode is Mode.TRACKING
    lengths = np.array(lengths)
    assert lengths.min() > model.leg_min and lengths.max() < model.leg_max
    assert env.interventions.per_limit["stroke"] > 0


def test_the_washout_of_a_shipped_motion_passes_but_for_short_catch_ups():
    """The classical washout's cue of the shipped lane change on the motion simulator at 1 kHz
    (the live pipeline's input): inside the limits but for a few rate steps of the washout's
    tilt-rate limiter, which the envelope takes at its acceleration limit and catches up from
    within a quarter of a second each; everywhere else the cue goes through bit for bit."""
    from stewart_sim.cueing.motion import read_motion
    from stewart_sim.cueing.study import make_cue, resample

    model = load_scene(SCENE.parent / "motion_simulator.toml")
    scene = scene_of(model)
    limits = envelope_limits(model, scene.controller)
    motion = resample(read_motion(SCENE.parent / "motions" / "lane_change.csv"), 1 / DT)
    cue, _ = make_cue("classical", scene, scene.cueing, motion)
    env = Envelope(model, limits, DT)
    steps = _run(env, (cue.q, cue.qd, cue.qdd))
    _within_limits(steps, limits, model)
    passed = np.array([s.passed for s in steps])
    assert passed.mean() > 0.9
    assert np.array_equal(_stack(steps, "q")[passed], cue.q[passed])
    edges = np.diff(np.r_[0, (~passed).astype(np.int8), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    assert 0 < runs.size and runs.max() <= 250


def test_a_resume_mid_fade_ramps_the_cue_in_within_the_limits(model, limits):
    """Telemetry back halfway through a fade (FADING -> RUNNING): the cue, a sine about home,
    is ramped in from the pose sent then (still moving); the envelope takes the rate step,
    everything stays within the limits, and after the ramp the cue goes through unchanged."""
    start = _home(model) + [0.01, 0, 0.015, 0, 0.03, 0]
    env = Envelope(model, limits, DT, start=start)
    fade = fade_to_home(model, limits, start, t0=0.0)
    half = int(fade.duration / DT / 2)
    steps = [env.step(*fade.sample(k * DT)) for k in range(half)]
    t0 = half * DT
    blend = Blend(steps[-1].q, t0)
    w, amp = 2 * np.pi * 0.7, np.array([0.004, 0, 0.006, 0.02, 0, 0])
    n = int((BLEND_TIME + 1.0) / DT)
    for k in range(n):
        t = t0 + k * DT
        tau = t - t0
        cue = (_home(model) + amp * np.sin(w * tau), amp * w * np.cos(w * tau),
               -amp * w * w * np.sin(w * tau))
        steps.append(env.step(*(cue if blend.done(t) else blend.apply(t, *cue))))
    _within_limits(steps, limits, model)
    assert all(s.passed for s in steps[-int(0.5 / DT):])
