"""hil.observe and Device.observe: the snapshots the live view reads. The device is ticked by
hand (device time, no wall clock): what is published, how often, and that it is the physics."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device, DeviceError  # noqa: E402
from hil.observe import Latest  # noqa: E402
from stewart_fmu.dynamics import inverse_dynamics  # noqa: E402
from stewart_fmu.kinematics import condition_number, inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from tests.hil.test_device import SCENE, arm, setpoint  # noqa: E402

OFFSET = np.array([0.001, -0.0005, 0.001, 0.01, -0.01, 0.02])   # m, rad: inside the stroke


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def test_publishes_at_start_then_every_rate_over_hz_ticks(model):
    dev = Device(model)
    latest = Latest()
    assert latest.latest() is None
    dev.observe(latest, hz=50.0)            # 1 kHz / 50 Hz: every 20th tick
    assert latest.published == 1 and latest.latest().tick == 0
    ticks = []
    for _ in range(100):
        dev.tick()
        ticks.append(latest.latest().tick)
    assert latest.published == 1 + 100 // 20
    assert sorted(set(ticks)) == [0, 20, 40, 60, 80, 100]
    s = latest.latest()
    assert s.t == s.tick / dev.rate == dev.time
    dev.observe(None)                       # stop: nothing more is published
    for _ in range(40):
        dev.tick()
    assert latest.published == 6


def test_observe_refuses_a_bad_rate(model):
    dev = Device(model)
    for hz in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(DeviceError, match="observe"):
            dev.observe(Latest(), hz)


def test_snapshot_at_rest_is_the_static_equilibrium(model):
    """At start the drives hold home: q = home, lengths = IK(home), forces = the static
    inverse dynamics at home (Eq. 12 with qd = qdd = 0), cond = cond(J(home)); no reference."""
    dev = Device(model)
    latest = Latest()
    dev.observe(latest)
    s = latest.latest()
    home = np.asarray(model.home, dtype=float)
    assert np.max(np.abs(np.array(s.q) - home)) < 1e-12
    assert np.max(np.abs(np.array(s.lengths) - inverse_kinematics(model, home).lengths)) < 1e-12
    static = inverse_dynamics(model, home, np.zeros(6), np.zeros(6))
    assert np.allclose(s.forces, static, rtol=1e-6, atol=1e-9)
    assert s.cond == pytest.approx(condition_number(model, home), rel=1e-12)
    assert s.q_ref is None and s.armed is False


def test_setpoint_shows_as_reference_and_the_platform_follows(model):
    """Armed, a setpoint for pose p: q_ref = p (forward kinematics of its lengths), and the
    published q converges to p; HOLD (and disarm) clear the reference."""
    dev = Device(model, watchdog=2.0)
    latest = Latest()
    dev.observe(latest, hz=100.0)
    target = np.asarray(model.home, dtype=float) + OFFSET
    lengths = inverse_kinematics(model, target).lengths
    dev.receive(arm())
    assert latest.latest().armed is False          # published on ticks, not on messages
    dev.receive(setpoint(0, lengths))
    first = None
    for _ in range(1000):                          # 1 s of device time
        dev.tick()
        first = first or latest.latest()
    s = latest.latest()
    assert s.armed and s.q_ref is not None
    assert np.max(np.abs(np.array(s.q_ref) - target)) < 1e-9        # FK(IK(p)) = p
    err0 = np.max(np.abs(np.array(first.q) - target))
    err1 = np.max(np.abs(np.array(s.q) - target))
    assert err0 > 0.25 * np.max(np.abs(OFFSET))      # 10 ms in: still on the way
    assert err1 < 1e-3 * err0                        # 1 s in: arrived (servo accuracy)
    # what is published is this pose's kinematics
    assert np.max(np.abs(np.array(s.lengths) - inverse_kinematics(model, np.array(s.q)).lengths)) < 1e-12
    assert s.cond == pytest.approx(condition_number(model, np.array(s.q)), rel=1e-12)
    dev.receive(setpoint(1, lengths, flags=ms.STEWART_SETPOINT_FLAG_HOLD))
    for _ in range(10):
        dev.tick()
    assert latest.latest().q_ref is None
    dev.receive(setpoint(2, lengths))
    dev.receive(arm(0))
    for _ in range(10):
        dev.tick()
    assert latest.latest().q_ref is None and latest.latest().armed is False
