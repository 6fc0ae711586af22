"""Telemetry datagrams: the native format round trip, OutSim packets built by hand mapped to the
vehicle frame, and bad or random bytes refused with TelemetryError only."""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from stewart_sim.live.vehicle_datagrams import (NATIVE_SIZES, OUTSIM_SIZES, TelemetryError,
                                                TelemetrySample, decode_native, decode_outsim,
                                                encode)

G = 9.81


def outsim(time_ms=1000, ang_vel=(0.0, 0.0, 0.0), heading=0.0, pitch=0.0, roll=0.0,
           accel=(0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0), pos=(0, 0, 0), ident=None) -> bytes:
    """An OutSim packet packed field by field, as Live for Speed's OutSimPack lays it out."""
    raw = struct.pack("<I", time_ms) + struct.pack("<3f", *ang_vel)
    raw += struct.pack("<fff", heading, pitch, roll) + struct.pack("<3f", *accel)
    raw += struct.pack("<3f", *vel) + struct.pack("<3i", *pos)
    return raw if ident is None else raw + struct.pack("<i", ident)


def test_sizes_as_documented():
    assert NATIVE_SIZES == (60, 84)
    assert OUTSIM_SIZES == (64, 68)
    assert len(outsim()) == 64 and len(outsim(ident=7)) == 68


@pytest.mark.parametrize("attitude", [None, (0.1, -0.2, 3.0)])
def test_native_round_trip_bit_for_bit(attitude):
    rng = np.random.default_rng(3)
    for _ in range(200):
        v = rng.normal(size=10) * np.array([100, 20, 20, 20, 3, 3, 3, 1, 1, 1])
        s = TelemetrySample(float(v[0]), tuple(v[1:4]), tuple(v[4:7]),
                            None if attitude is None else tuple(v[7:10]))
        raw = encode(s)
        assert len(raw) == NATIVE_SIZES[attitude is not None]
        back = decode_native(raw)
        assert back == s
        assert encode(back) == raw
        assert struct.pack("<7d", back.t, *back.specific_force, *back.angular_velocity) \
            == struct.pack("<7d", s.t, *s.specific_force, *s.angular_velocity)


def test_native_layout_by_hand():
    raw = b"STW\x01" + struct.pack("<7d", 2.5, 0.0, 0.0, G, 0.0, 0.0, 0.1)
    s = decode_native(raw)
    assert s.t == 2.5 and s.specific_force == (0.0, 0.0, G)
    assert s.angular_velocity == (0.0, 0.0, 0.1) and s.attitude is None


@pytest.mark.parametrize("ident", [None, 42])
def test_outsim_at_rest_level(ident):
    s = decode_outsim(outsim(time_ms=1500, ident=ident))
    assert s.t == 1.5
    np.testing.assert_allclose(s.specific_force, (0.0, 0.0, G), atol=1e-12)
    assert s.angular_velocity == (0.0, 0.0, 0.0)
    assert s.attitude == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("ident", [None, 42])
def test_outsim_turning_left(ident):
    # a car at 20 m/s on a left-hand circle of radius 50 m, heading 0 (facing world +Y):
    # yaw rate v/R about +Z, centripetal acceleration v^2/R towards its left (world -X)
    v, radius = 20.0, 50.0
    r = np.float32(v / radius)
    a = np.float32(v * v / radius)
    s = decode_outsim(outsim(ang_vel=(0.0, 0.0, r), accel=(-a, 0.0, 0.0), ident=ident))
    np.testing.assert_allclose(s.angular_velocity, (0.0, 0.0, float(r)), atol=1e-12)
    np.testing.assert_allclose(s.specific_force, (0.0, float(a), G), atol=1e-12)


@pytest.mark.parametrize("ident", [None, 42])
def test_outsim_heading_90_accelerating_forward(ident):
    # heading +90 deg (anticlockwise from above) turns the car from world +Y to world -X;
    # 3 m/s^2 forward is world (-3, 0, 0), felt as +3 m/s^2 along the vehicle's x
    s = decode_outsim(outsim(heading=math.pi / 2, accel=(-3.0, 0.0, 0.0), ident=ident))
    np.testing.assert_allclose(s.specific_force, (3.0, 0.0, G), atol=1e-6)
    assert s.angular_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert s.attitude[2] == pytest.approx(math.pi / 2)


def test_outsim_pitched_nose_up_at_rest():
    # nose up by p (LFS's positive pitch) at rest: the occupant is pressed into the seat back as
    # by a forward acceleration (tilt coordination), f = g (sin p, 0, cos p) in the vehicle
    # frame, and our pitch (about y left) is -p
    p = np.float32(0.2)
    s = decode_outsim(outsim(pitch=p))
    np.testing.assert_allclose(s.specific_force, (G * math.sin(p), 0.0, G * math.cos(p)),
                               atol=1e-12)
    assert s.attitude[1] == -float(p)


def test_outsim_rolled_right_side_down_at_rest():
    # LFS's positive roll (anticlockwise seen from the front) lowers the right side: the
    # occupant leans to the right as in a left turn, f = g (0, sin r, cos r)
    r = np.float32(0.3)
    s = decode_outsim(outsim(roll=r))
    np.testing.assert_allclose(s.specific_force, (0.0, G * math.sin(r), G * math.cos(r)),
                               atol=1e-12)


@pytest.mark.parametrize("raw, message", [
    (b"", "native telemetry: 0 bytes, expected 60 or 84"),
    (b"XYZ\x01" + bytes(56), "native telemetry: magic b'XYZ', expected b'STW'"),
    (b"STW\x02" + bytes(56), "native telemetry: version 2, expected 1"),
    (b"STW\x01" + struct.pack("<7d", math.nan, 0, 0, G, 0, 0, 0),
     "telemetry: t: non-finite value nan"),
    (b"STW\x01" + struct.pack("<7d", 0, 1e308, 0, G, 0, 0, 0),
     "telemetry: specific force: 1e+308 beyond the bound 1000 m/s^2"),
    (b"STW\x01" + struct.pack("<7d", 0, 0, 0, G, 0, 0, -math.inf),
     "telemetry: angular velocity: non-finite value -inf"),
    (b"STW\x01" + struct.pack("<7d", 0, 0, 0, G, 0, 2e3, 0),
     "telemetry: angular velocity: 2000.0 beyond the bound 1000 rad/s"),
])
def test_native_bad_input_one_line(raw, message):
    with pytest.raises(TelemetryError) as err:
        decode_native(raw)
    assert str(err.value) == message


def test_outsim_bad_input_one_line():
    cases = [
        (outsim()[:63], "OutSim telemetry: 63 bytes, expected 64 or 68"),
        (outsim(accel=(math.nan, 0, 0)), "OutSim telemetry: Accel: non-finite value nan"),
        (outsim(heading=math.inf), "OutSim telemetry: Heading, Pitch, Roll: non-finite value inf"),
        (outsim(accel=(3e38, 0, 0)), "beyond the bound 1000 m/s^2"),
        (outsim(ang_vel=(0, 0, 1e4)), "beyond the bound 1000 rad/s"),
        ("text", "OutSim telemetry: a datagram must be bytes, got str"),
    ]
    for raw, message in cases:
        with pytest.raises(TelemetryError) as err:
            decode_outsim(raw)
        assert message in str(err.value) and "\n" not in str(err.value)


def test_fuzz_only_telemetry_error_or_a_finite_sample():
    rng = np.random.default_rng(24)
    seeds = [encode(TelemetrySample(1.0, (0.5, -0.2, G), (0.0, 0.01, 0.1))),
             encode(TelemetrySample(1.0, (0.5, -0.2, G), (0.0, 0.01, 0.1), (0.0, 0.1, 1.0))),
             outsim(ang_vel=(0.0, 0.0, 0.4), heading=1.0, accel=(1.0, 2.0, 0.0)),
             outsim(ident=3)]
    counts = {"refused": 0, "decoded": 0}
    for k in range(5000):
        if k % 2:
            raw = rng.integers(0, 256, size=int(rng.choice([0, 1, 59, 60, 63, 64, 68, 84, 100])),
                               dtype=np.uint8).tobytes()
        else:
            buf = bytearray(seeds[k // 2 % len(seeds)])
            for _ in range(int(rng.integers(1, 6))):
                buf[int(rng.integers(0, len(buf)))] = int(rng.integers(0, 256))
            raw = bytes(buf[:int(rng.integers(len(buf) - 2, len(buf) + 1))]) if k % 10 == 4 \
                else bytes(buf)
        for decode in (decode_native, decode_outsim):
            try:
                s = decode(raw)
            except TelemetryError as exc:
                assert "\n" not in str(exc)
                counts["refused"] += 1
                continue
            values = (s.t, *s.specific_force, *s.angular_velocity, *(s.attitude or ()))
            assert all(math.isfinite(v) for v in values)
            assert max(abs(v) for v in s.specific_force) <= 1e3
            assert max(abs(v) for v in s.angular_velocity) <= 1e3
            counts["decoded"] += 1
    assert counts["refused"] > 1000 and counts["decoded"] > 100


def test_outsim_any_attitude_against_an_independent_rotation():
    # the car's axes from scipy's intrinsic Z-X-Y Euler angles (heading about Z, then pitch
    # about the car's X, then roll about its Y): the decoded vectors, mapped back to LFS's car
    # axes and into the world, give back the packet's Accel - g and AngVel
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(5)
    for _ in range(50):
        h, p, r = (float(np.float32(v)) for v in rng.uniform(-3.0, 3.0, 3) * (1.0, 0.4, 0.4))
        accel = tuple(float(np.float32(v)) for v in rng.normal(0.0, 5.0, 3))
        ang_vel = tuple(float(np.float32(v)) for v in rng.normal(0.0, 1.0, 3))
        s = decode_outsim(outsim(ang_vel=ang_vel, heading=h, pitch=p, roll=r, accel=accel))
        car_to_world = Rotation.from_euler("ZXY", [h, p, r]).as_matrix()

        def lfs_car(v):  # ours (forward, left, up) -> LFS car (right, forward, up)
            return np.array([-v[1], v[0], v[2]])
        np.testing.assert_allclose(car_to_world @ lfs_car(s.specific_force),
                                   np.array(accel) + (0.0, 0.0, G), atol=1e-12)
        np.testing.assert_allclose(car_to_world @ lfs_car(s.angular_velocity), ang_vel,
                                   atol=1e-12)
        assert s.attitude == (r, -p, h)
