"""The live pipeline's input side: addresses, the OutSim encoder against its decoder, the replay
schedule, and the telemetry receiver's counting (each kind of bad datagram refused, newest wins,
a bounded drain) over a queue and over real loopback UDP."""
from __future__ import annotations

import math
import select
import struct
from pathlib import Path

import numpy as np
import pytest

from stewart_sim.cueing.motion import read_motion
from stewart_sim.live.address import AddressError, device_address, telemetry_address
from stewart_sim.live.receiver import TelemetryReceiver, UdpSource
from stewart_sim.live.replay import Replay, UdpSink
from stewart_sim.live.vehicle_datagrams import (TelemetryError, TelemetrySample, decode_native,
                                                decode_outsim, encode, encode_outsim)
from tests.app.datagrams import Queue

ROOT = Path(__file__).resolve().parents[2]
BRAKING = ROOT / "scenes" / "motions" / "braking_car.csv"


class Ticking:
    """A simulated clock that moves `cost` s every time it is read."""

    def __init__(self, cost: float = 0.0) -> None:
        self.t, self.cost = 0.0, cost

    def __call__(self) -> float:
        self.t += self.cost
        return self.t


def sample(t: float, f=(0.0, 0.0, 9.81), w=(0.0, 0.0, 0.0)) -> TelemetrySample:
    return TelemetrySample(t, f, w)


def test_addresses():
    assert telemetry_address("udp://127.0.0.1:5005") == ("127.0.0.1", 5005)
    assert telemetry_address("udp://localhost:0") == ("127.0.0.1", 0)
    assert telemetry_address("udp://0.0.0.0:5005", remote=True) == ("0.0.0.0", 5005)
    for bad in ("udp://10.1.2.3:5", "tcp://127.0.0.1:5", "127.0.0.1:5", "udp://127.0.0.1:x",
                "udp://127.0.0.1:70000", "udp://host:5"):
        with pytest.raises(AddressError, match="telemetry address"):
            telemetry_address(bad)
    with pytest.raises(AddressError, match="port must be 1..65535"):
        telemetry_address("udp://127.0.0.1:0", listen=False)
    assert device_address("udp:127.0.0.1:14550").port == 14550
    assert device_address("serial:/dev/pts/3").host == "/dev/pts/3"
    for bad in ("udp:10.0.0.1:5", "serial:", "tcp:1", "udp://127.0.0.1:5"):
        with pytest.raises(AddressError, match="device address"):
            device_address(bad)


def test_outsim_encoder_inverts_the_decoder():
    rng = np.random.default_rng(5)
    for _ in range(200):
        v = rng.normal(size=9) * np.array([5, 5, 5, 1, 1, 1, 0.3, 0.3, 3])
        s = TelemetrySample(float(rng.integers(0, 10 ** 6)) / 1000, tuple(v[0:3] + (0, 0, 9.81)),
                            tuple(v[3:6]), (float(v[6]), float(v[7]), float(v[8])))
        back = decode_outsim(encode_outsim(s))
        assert back.t == s.t
        # float32 on the wire: about 7 significant digits of g and the angles' sines
        np.testing.assert_allclose(back.specific_force, s.specific_force, atol=2e-5)
        np.testing.assert_allclose(back.angular_velocity, s.angular_velocity, atol=2e-6)
        np.testing.assert_allclose(back.attitude, s.attitude, atol=1e-6)


def test_replay_schedule_and_loop():
    motion = read_motion(BRAKING)
    r = Replay(motion, "native")
    assert r.period == pytest.approx(0.01)
    first = r.due(0.0)
    assert len(first) == 1 and decode_native(first[0]).t == 0.0
    assert r.due(0.0) == []
    got = [decode_native(d) for d in r.due(0.0501)]
    assert [round(s.t, 9) for s in got] == [0.01, 0.02, 0.03, 0.04, 0.05]
    np.testing.assert_array_equal(got[-1].specific_force, motion.specific_force[5])
    rest = r.due(math.inf)
    assert len(rest) == 1000                 # MAX_BURST: a late sender catches up in bursts
    rest += r.due(math.inf)
    assert r.done and 1 + 5 + len(rest) == motion.t.size
    looped = Replay(motion, "outsim", loop=True)
    n = motion.t.size
    end = looped.span + 0.5 * looped.period
    ts = [decode_outsim(d).t for d in looped.due(end) + looped.due(end)]
    assert len(ts) == n + 1 and ts[n] == pytest.approx(looped.span)
    assert all(b > a for a, b in zip(ts, ts[1:]))    # time never goes back
    # --rate: the motion resampled
    assert Replay(motion, rate=1000.0).period == pytest.approx(1e-3)


def test_each_kind_refused_and_counted():
    q = Queue()
    rx = TelemetryReceiver(q, "native", Ticking())
    good = encode(sample(1.0))
    nan = bytearray(encode(sample(2.0)))
    nan[12:20] = struct.pack("<d", math.nan)
    absurd = b"STW\x01" + struct.pack("<7d", 3.0, 1e308, 0.0, 9.81, 0.0, 0.0, 0.0)
    cases = [(b"STW\x01" + b"\0" * 10, "truncated"), (b"XYZ\x01" + good[4:], "malformed"),
             (good + b"\0", "malformed"), (bytes(nan), "non_finite"), (absurd, "absurd"),
             (encode(sample(1e6)), "ahead"),
             (b"STW\x01" + struct.pack("<7d", 1e300, 0.0, 0.0, 9.81, 0.0, 0.0, 0.0), "absurd")]
    q.q.append(good)
    assert rx.poll() == sample(1.0)
    for data, kind in cases:
        q.q.append(data)
        assert rx.poll() is None
        assert rx.counts.refused[kind] >= 1
    q.q.append(good)
    assert rx.poll() is None and rx.counts.refused["duplicate"] == 1
    q.q.append(encode(sample(0.5)))
    assert rx.poll() is None and rx.counts.refused["out_of_order"] == 1
    assert rx.counts.accepted == 1 and rx.counts.refused_total == 9
    assert rx.counts.refused == {"malformed": 2, "truncated": 1, "non_finite": 1, "absurd": 2,
                                 "out_of_order": 1, "duplicate": 1, "ahead": 1}
    rx.forget_order()          # after a loss: a restarted sender is taken
    q.q.append(encode(sample(0.5)))
    assert rx.poll() == sample(0.5)


def test_newest_wins_within_a_drain():
    q = Queue()
    rx = TelemetryReceiver(q, "native", Ticking())
    q.q.extend(encode(sample(t)) for t in (1.0, 3.0, 2.0, 3.0))
    assert rx.poll().t == 3.0
    c = rx.counts
    assert c.superseded == 1 and c.refused["out_of_order"] == 1 and c.refused["duplicate"] == 1


def test_the_stream_clock_refuses_samples_ahead_and_keeps_a_real_sender():
    """The receiver's time line (stewart_sim.live.receiver): a sender on time, one whose first
    sample came late by less than AHEAD, one that stutters (one datagram 0.08 s late, then on
    time again, the datagrams meanwhile lost) and one whose clock runs slow are all taken whole;
    a sender at twice our clock's speed is refused as ahead once its lead passes AHEAD, so the
    stream's time never runs ahead of the clock by more than AHEAD plus DRIFT of the time
    elapsed."""
    from stewart_sim.live.receiver import AHEAD, DRIFT

    def feed(times, arrivals):
        q = Queue()
        rx = TelemetryReceiver(q, "native", Ticking())
        got = []
        for t, now in zip(times, arrivals):
            q.q.append(encode(sample(t)))
            s = rx.poll(now)
            got.append(s is not None)
            # the stream's accepted time against the clock (the first sample's lag as zero)
            assert rx.last_t - times[0] <= (now - arrivals[0]) * (1 + DRIFT) + AHEAD + 1e-12
        return rx, got

    t = [j / 100 for j in range(300)]
    late_first = [0.8 * AHEAD] + t[1:]                   # the first came late, then on time
    kept = [tj for j, tj in enumerate(t) if not 51 <= j <= 57]      # 51-57 lost, and
    stutter = [tj + (0.08 if tj == t[50] else 0.0) for tj in kept]  # 50 came 0.08 s late
    slow = [tj * 1.05 for tj in t]                       # the sender's clock 5 % slow
    for times, arrivals in ((t, t), (t, late_first), (kept, stutter), (t, slow)):
        rx, got = feed(times, arrivals)
        assert all(got) and rx.counts.refused["ahead"] == 0
    rx, got = feed(t, [tj / 2 for tj in t])                          # twice our speed
    assert rx.counts.refused["ahead"] > 250 and rx.counts.accepted < 50


def test_drain_is_bounded_by_count_and_clock():
    q = Queue()
    q.q.extend(b"junk" for _ in range(10_000))
    rx = TelemetryReceiver(q, "native", Ticking(cost=1e-6), max_read=10_000, budget=1e-4)
    assert rx.poll() is None
    # one clock read of 1 us per datagram: budget / 1 us = 100 datagrams (+-1 for rounding)
    assert 99 <= rx.counts.received <= 101
    rx = TelemetryReceiver(q, "native", Ticking(), max_read=256)
    rx.poll()
    assert rx.counts.received == 256


def test_over_loopback_udp():
    src = UdpSource("127.0.0.1", 0)
    sink = UdpSink(*src.address)
    try:
        rx = TelemetryReceiver(src, "outsim", Ticking())
        motion = read_motion(BRAKING)
        for data in Replay(motion, "outsim").due(0.05):
            sink.send(data)
        sink.send(b"\0" * 3)
        select.select([src], [], [], 2.0)
        got = None
        for _ in range(100):            # bounded: the datagrams are on loopback already
            got = rx.poll() or got
            if rx.counts.received == 7:
                break
            select.select([src], [], [], 0.01)
        assert got is not None and got.t == pytest.approx(0.05)
        assert rx.counts.received == 7 and rx.counts.refused["truncated"] == 1
    finally:
        sink.close()
        src.close()


def test_bad_listen_address_is_one_line():
    src = UdpSource("127.0.0.1", 0)
    try:
        with pytest.raises(TelemetryError, match="cannot listen"):
            UdpSource(*src.address)
    finally:
        src.close()


def test_telemetry_replay_command(capsys):
    """The command streams the motion's samples due within --duration (a count fixed by the
    schedule, whatever the machine's speed), in the format asked for."""
    from stewart_sim import cli

    src = UdpSource("127.0.0.1", 0)
    try:
        assert cli.main(["telemetry-replay", str(BRAKING), "--to",
                         f"udp://127.0.0.1:{src.address[1]}", "--format", "outsim",
                         "--rate", "1000", "--duration", "0.05"]) == 0
        got = []
        for _ in range(1000):                   # bounded: all were sent before main returned
            data = src.recv()
            if data is None:
                break
            got.append(decode_outsim(data).t)
    finally:
        src.close()
    assert got == pytest.approx([k / 1000 for k in range(51)])
    assert "51 datagrams sent" in capsys.readouterr().out
    assert cli.main(["telemetry-replay", str(BRAKING), "--to", "udp://127.0.0.1:0"]) == 2


def test_operator_words_from_a_terminal_line_and_a_datagram():
    import os

    from stewart_sim.live.control import Control

    r, w = os.pipe()
    reader = os.fdopen(r, "r")
    control = Control(stdin=reader, udp=("127.0.0.1", 0))
    sink = UdpSink(*control.address)
    try:
        assert control.poll() == []
        os.write(w, b"park\nbogus\n")
        sink.send(b"ESTOP\n")
        select.select([control.sock], [], [], 2.0)
        assert control.poll() == ["park", "estop"]
        assert control.unknown == 1
        os.close(w)                  # end of input: the terminal is no longer read
        assert control.poll() == [] and control.stdin is None
    finally:
        sink.close()
        control.close()
        reader.close()


@pytest.mark.parametrize("rate, reason", [("1e-9", "fewer than 2 samples"),
                                          ("0.05", "fewer than 2 samples"),
                                          ("1e9", "memory budget")])
def test_telemetry_replay_refuses_a_rate_naming_it(rate, reason, capsys):
    """--rate that resamples the motion to fewer than two samples, or to more than the memory
    budget holds: one line naming --rate and the reason, exit 2, nothing sent."""
    from stewart_sim import cli

    src = UdpSource("127.0.0.1", 0)
    try:
        assert cli.main(["telemetry-replay", str(BRAKING), "--to",
                         f"udp://127.0.0.1:{src.address[1]}", "--rate", rate]) == 2
        assert src.recv() is None
    finally:
        src.close()
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "--rate" in err[0] and reason in err[0]
    assert "Traceback" not in captured.err and captured.out == ""


@pytest.mark.parametrize("seed", range(3))
def test_fuzzed_timing_never_runs_the_stream_ahead_of_the_clock(seed):
    """Seeded hostile times (on time, far ahead, behind, bursts, duplicates, any time at all)
    at 1 kHz polls, the time line forgotten now and then (a loss): every accepted sample is
    newer than the last, and never more than AHEAD past the anchor carried on at (1 + DRIFT)
    times the clock: the stream's time cannot run ahead of ours."""
    from stewart_sim.live.receiver import AHEAD, DRIFT

    rng = np.random.default_rng(seed)
    q = Queue()
    rx = TelemetryReceiver(q, "native", Ticking())
    anchor = prev = None
    for k in range(5000):
        now = k * 1e-3
        base = prev if prev is not None else now
        offsets = rng.choice([0.0, 1e-3, 0.02, 0.03, 1.0, 1e6, -1e-3, -1.0, -1e6],
                             size=int(rng.integers(0, 8)))
        times = [base + o for o in offsets] + [float(rng.uniform(-1e9, 1e9))] * (k % 97 == 0)
        q.q.extend(encode(sample(t)) for t in times)
        if prev is not None and rng.random() < 0.05:
            q.q.extend([encode(sample(prev))] * 3)                  # duplicates
        s = rx.poll(now)
        if s is not None:
            if anchor is None:
                anchor = (now, s.t)
            assert s.t <= anchor[1] + (now - anchor[0]) * (1 + DRIFT) + AHEAD + 1e-9
            assert prev is None or s.t > prev
            prev = s.t
        if rng.random() < 2e-3:
            rx.forget_order()
            anchor = prev = None
    c = rx.counts
    assert c.received == c.accepted + c.superseded + c.refused_total
    assert c.accepted > 100 and c.refused["ahead"] > 100 and c.refused["duplicate"] > 10
