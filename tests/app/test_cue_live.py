"""The live pipeline end to end on a simulated clock: a shipped motion streamed as telemetry
(Replay over loopback UDP) -> the live session -> the emulated device in lockstep over loopback
UDP (and over a pseudo-terminal), its measured leg lengths against the offline cue through the
closed loop; bad telemetry refused without moving the platform; a flood that delays no
setpoint; loss, park, resume and the emergency stop; the command line's refusals."""
from __future__ import annotations

import math
import select
import struct
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from controller.cosim import run_closed_loop
from controller.trajectory import Trajectory
from hil.client import Client, connect_pty, connect_udp
from hil.device import Device
from hil.link import pty_pair, udp_server
from hil.serve import serve_in_thread
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim import cli
from stewart_sim.cueing.motion import VehicleMotion, read_motion
from stewart_sim.cueing.study import cue_study
from stewart_sim.cueing.washout import classical_washout
from stewart_sim.live.control import Control
from stewart_sim.live.cue_stream import CueStream, Reference
from stewart_sim.live.device_out import DeviceCounts, DeviceOut
from stewart_sim.live.pipeline_modes import Mode
from stewart_sim.live.receiver import DRAIN_BUDGET, TelemetryReceiver, UdpSource
from stewart_sim.live.replay import Replay, UdpSink
from stewart_sim.live.session import Record, make_session
from stewart_sim.live.vehicle_datagrams import TelemetrySample, encode, encode_outsim
from stewart_sim.scene.load import load
from tests.app.datagrams import Queue

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"
BRAKING = ROOT / "scenes" / "motions" / "braking_car.csv"
TELEMETRY_RATE = 100.0


@pytest.fixture(scope="module")
def scene():
    return load(SIM)


class SimClock:
    """The simulated clock of a test: set by the loop, read by the receiver."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class FakeDevice:
    """The device end for the unit tests: records every setpoint and answers each with a
    LEG_STATE of the lengths sent, until `silent_after` setpoints (then it answers nothing: a
    device that is gone)."""

    watchdog = 0.2          # s: the emulated device's default WDG_TIMEOUT

    def __init__(self, silent_after: float = math.inf) -> None:
        self.setpoints: list[tuple] = []
        self.counts = DeviceCounts()
        self.send_time = 0.0
        self.held = False
        self.silent_after = silent_after

    def send(self, k, t, l, ldot, force, force_rate):
        self.setpoints.append((k, t, np.array(l), np.array(ldot), np.array(force)))
        self.send_time = time.monotonic()
        self.counts.setpoints += 1
        if self.counts.setpoints > self.silent_after:
            return []
        self.counts.states += 1
        return [SimpleNamespace(length=tuple(np.asarray(l, float)))]

    def hold(self) -> bool:
        self.held = True
        return True


def delivered(src: UdpSource, timeout: float = 2.0) -> None:
    """Wait (bounded) until the datagrams just sent on loopback are readable."""
    select.select([src], [], [], timeout)


# --- the chain end to end -----------------------------------------------------------------------


def lockstep_chain(scene, motion: VehicleMotion, device_transport, client_transport,
                   device: Device, seconds: float):
    """Replay -> UDP -> session -> the device in lockstep; the session and its record."""
    rate = scene.controller.rate
    thread, stop, _ = serve_in_thread(device, device_transport, poll=0.01)
    out = DeviceOut(Client(client_transport), lockstep=True, timeout=1.0)
    src = UdpSource("127.0.0.1", 0)
    sink = UdpSink(*src.address)
    clock = SimClock()
    try:
        out.start(rate)
        replay = Replay(motion, "native")
        n = int(round(seconds * rate))
        session = make_session(scene, TelemetryReceiver(src, "native", clock), out,
                               TELEMETRY_RATE, record=Record(n))
        for k in range(n):
            clock.t = k / rate
            sent = replay.due(clock.t)
            for d in sent:
                sink.send(d)
            if sent:
                delivered(src)
            session.tick(clock.t)
    finally:
        stop.set()
        thread.join(5)
        sink.close()
        src.close()
        out.close()
        device_transport.close()
    return session


class OfflineCue:
    """A stepper that hands out the rows of an offline cue (cueing.washout.Cue), so that
    CueStream upsamples the offline cue exactly as the live loop upsamples its own."""

    def __init__(self, cue) -> None:
        self.cue, self.k = cue, 0

    def reset(self) -> None:
        self.k = 0

    def step(self, specific_force, angular_velocity):
        k, self.k = self.k, self.k + 1
        return Reference(self.cue.q[k], self.cue.qd[k], self.cue.qdd[k])


def legs(table, prefix: str, rows: slice) -> np.ndarray:
    return np.column_stack([table[f"{prefix}{i}"][rows] for i in range(1, 7)])


def test_shipped_motion_through_the_chain_equals_the_offline_closed_loop(scene):
    """Done when: the braking car streamed as telemetry over loopback UDP (Replay), the live
    session, the device in lockstep over loopback UDP: its measured legs equal the offline
    `cue` (classical_washout at the motion's 100 Hz) through the closed loop
    (controller.cosim.run_closed_loop) within that loop's own tracking error.

    The loop runs at the controller's 1 kHz, so the offline cue goes into it upsampled by the
    live loop's rule (CueStream's C2 blend of extrapolations, fed the offline rows): what
    differs between the two runs is everything else, the stepped washout against the offline
    one, the datagrams, the receiver, the envelope (which must pass the cue unchanged), the
    feed-forward force sent over MAVLink and its backward-difference rate, and the device. The
    bound is the loop's tracking error max |l_ref - l| because both runs are that loop on the
    same reference: a difference larger than what the loop leaves between reference and legs is
    a different reference or a different loop. The second check is against track_cue (the cue
    recomputed at 1 kHz from the motion interpolated linearly, `cue --track`): there the
    references differ by the upsampling's extrapolation error, and the bound is the triangle
    through both loops (measured -> offline loop -> its reference -> the 1 kHz reference -> its
    loop)."""
    motion = read_motion(BRAKING)
    seconds = 6.0       # the braking (from 3.01 s) and its washout back: 6000 lockstep ticks
    rate = scene.controller.rate
    server = udp_server("127.0.0.1", 0)
    session = lockstep_chain(scene, motion, server, connect_udp(*server.address),
                             Device(scene.model, scene.controller, lockstep=True), seconds)
    rec = session.record.table()
    n = len(rec)
    assert session.receiver.counts.accepted == int(seconds * TELEMETRY_RATE)
    assert session.receiver.counts.refused_total == 0
    assert session.mode is Mode.RUNNING
    assert session.envelope.interventions.limited == 0
    measured = rec[:, -6:]
    assert np.all(np.isfinite(measured)) and np.ptp(measured) > 0.05
    # the offline cue, upsampled as the live loop does (sample j arrives at tick 10 j)
    offline = classical_washout(scene.cueing, motion, scene.model.home, scene.model.gravity)
    stream = CueStream(OfflineCue(offline), 1.0 / TELEMETRY_RATE, scene.model.home)
    q, qd, qdd = (np.empty((n + 1, 6)) for _ in range(3))
    for k in range(n + 1):
        if k % 10 == 0:
            stream.push(TelemetrySample(k / rate, (0.0, 0.0, 9.81), (0.0, 0.0, 0.0)), k / rate)
        r = stream.reference(k / rate)
        q[k], qd[k], qdd[k] = r.q, r.qd, r.qdd
    t = np.arange(n + 1) / rate
    loop = run_closed_loop(scene.model, scene.controller, Trajectory(t, q, qd, qdd)).table
    # row k of the record: the device's state after step k, at t_(k+1): the loop's row k + 1
    l_loop = legs(loop, "l", slice(1, n + 1))
    tracking = float(np.max(np.abs(legs(loop, "l_ref", slice(1, n + 1)) - l_loop)))
    gap = float(np.max(np.abs(measured - l_loop)))
    # against `cue --track`'s closed loop (the cue at 1 kHz)
    study = cue_study(scene, motion, ("classical",), track=True)
    fine = study.tracking.table
    upsampling = float(np.max(np.abs(legs(fine, "l_ref", slice(1, n + 1))
                                     - legs(loop, "l_ref", slice(1, n + 1)))))
    tracking_fine = float(np.max(np.abs(legs(fine, "e", slice(1, n + 1)))))
    gap_fine = float(np.max(np.abs(measured - legs(fine, "l", slice(1, n + 1)))))
    print(f"\nlive vs offline closed loop: {gap:.3e} m (its tracking error {tracking:.3e} m); "
          f"vs cue --track: {gap_fine:.3e} m (upsampling {upsampling:.3e} m + tracking "
          f"{tracking_fine:.3e} m)")
    assert 0 < gap <= tracking
    # the triangle through both loops' references
    assert gap_fine <= gap + tracking + upsampling + tracking_fine


def test_serial_over_a_pty_pair(scene):
    motion = read_motion(BRAKING)
    master, slave = pty_pair()
    try:
        session = lockstep_chain(scene, motion, master, connect_pty(slave.name),
                                 Device(scene.model, scene.controller, lockstep=True), 0.5)
    finally:
        slave.close()
    assert session.device.counts.setpoints == 500
    assert session.device.counts.states >= 500
    assert session.receiver.counts.accepted == 50


# --- bad input ---------------------------------------------------------------------------------


def offline_session(scene, source, fmt="native", control=None, clock=None):
    clock = clock or SimClock()
    dev = FakeDevice()
    return make_session(scene, TelemetryReceiver(source, fmt, clock), dev, TELEMETRY_RATE,
                        control), dev, clock


def bad_datagrams(t: float) -> dict[str, bytes]:
    good = encode(TelemetrySample(t, (0.0, 0.0, 9.81), (0.0, 0.0, 0.0)))
    nan = bytearray(good)
    nan[12:20] = struct.pack("<d", math.nan)
    return {"truncated": good[:30], "malformed": b"XYZ\x01" + good[4:],
            "non_finite": bytes(nan),
            "absurd": b"STW\x01" + struct.pack("<7d", t, 1e308, 0.0, 9.81, 0.0, 0.0, 0.0)}


def test_each_bad_kind_counted_and_the_platform_not_moved(scene):
    """At home waiting for telemetry: every kind of bad datagram is counted and no setpoint
    leaves home."""
    q = Queue()
    session, dev, clock = offline_session(scene, q)
    home = inverse_kinematics(scene.model, scene.model.home, with_cond=False).lengths
    k = 0
    for kind, data in bad_datagrams(1.0).items():
        for _ in range(3):
            q.q.append(data)
            clock.t = k / scene.controller.rate
            session.tick(clock.t)
            k += 1
        assert session.receiver.counts.refused[kind] == 3
    assert session.mode is Mode.STARTING
    for _, _, l, ldot, _ in dev.setpoints:
        np.testing.assert_array_equal(l, home)
        np.testing.assert_array_equal(ldot, np.zeros(6))


def test_bad_datagrams_while_cueing_change_nothing(scene):
    """The same motion with and without bad datagrams (every kind, samples 1e6 s ahead of the
    stream's clock, out-of-order and duplicated samples) between its samples: the setpoints
    are identical, the washout took the same steps."""
    motion = read_motion(BRAKING)
    rate = scene.controller.rate

    def run(bad: bool):
        q = Queue()
        session, dev, clock = offline_session(scene, q)
        replay = Replay(motion, "native")
        previous = None
        for k in range(int(4.0 * rate)):        # through the start of the braking at 3.01 s
            clock.t = k / rate
            now = replay.due(clock.t)
            q.q.extend(now)
            if bad and k % 7 == 3:
                q.q.extend(bad_datagrams(clock.t).values())
                q.q.append(encode(TelemetrySample(clock.t + 1e6, (3.0, 0.0, 9.81),
                                                  (0.0, 0.0, 0.0))))   # far ahead of the clock
                if previous is not None:
                    q.q.extend([previous, previous])          # duplicated, then out of order
            if now:
                previous = now[-1]
            session.tick(clock.t)
        return session, dev

    clean, dev_clean = run(False)
    dirty, dev_dirty = run(True)
    assert dirty.receiver.counts.refused_total > 4 * 500
    assert all(dirty.receiver.counts.refused[k] > 0 for k in
               ("truncated", "malformed", "non_finite", "absurd", "duplicate", "out_of_order",
                "ahead"))
    assert dirty.cue.steps == clean.cue.steps == 400
    assert dirty.receiver.counts.accepted == clean.receiver.counts.accepted == 400
    assert len(dev_clean.setpoints) == len(dev_dirty.setpoints)
    for a, b in zip(dev_clean.setpoints, dev_dirty.setpoints):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


class CostClock:
    """A simulated clock that moves `cost` s every time it is read: the drain's reading of a
    datagram costs clock time, so a flood could hold a tick back if it were not bounded."""

    def __init__(self, cost: float) -> None:
        self.t, self.cost = 0.0, cost

    def __call__(self) -> float:
        self.t += self.cost
        return self.t


def test_a_flood_delays_no_setpoint(scene):
    """10^4 garbage datagrams between two ticks: every tick still sends its setpoint, none
    spends more than the drain budget (plus one datagram) on input, and the good sample after
    the flood is taken once the flood has drained."""
    q = Queue()
    clock = CostClock(cost=1e-6)     # each datagram read costs 1 us of simulated time
    session, dev, _ = offline_session(scene, q, clock=clock)
    rate = scene.controller.rate
    q.q.append(encode(TelemetrySample(0.0, (0.0, 0.0, 9.81), (0.0, 0.0, 0.0))))
    session.tick(0.0)
    q.q.extend([b"\x00garbage"] * 10_000)
    q.q.append(encode(TelemetrySample(0.01, (1.0, 0.0, 9.81), (0.0, 0.0, 0.0))))
    spent = []
    for k in range(1, 200):
        before = clock.t
        session.tick(k / rate)
        spent.append(clock.t - before)
        if session.receiver.counts.accepted == 2:
            break
    assert len(dev.setpoints) == k + 1             # one setpoint per tick, none skipped
    assert [s[0] for s in dev.setpoints] == list(range(k + 1))
    assert max(spent) <= DRAIN_BUDGET + 3e-6
    c = session.receiver.counts
    assert c.refused["truncated"] == 10_000 and c.accepted == 2


# --- loss, park, resume, stop ----------------------------------------------------------------


def test_loss_fades_home_then_telemetry_resumes(scene):
    q = Queue()
    session, dev, clock = offline_session(scene, q)
    rate = scene.controller.rate
    push = TelemetrySample(0.0, (3.0, 0.0, 9.81), (0.0, 0.0, 0.0))
    k = 0
    for j in range(50):                          # 0.5 s of a forward push at 100 Hz
        q.q.append(encode(TelemetrySample(j / 100, push.specific_force, push.angular_velocity)))
        for _ in range(10):
            session.tick(k / rate)
            k += 1
    assert session.mode is Mode.RUNNING
    moved = np.max(np.abs(session.envelope.last.q - scene.model.home))
    assert moved > 1e-3
    modes = []
    for _ in range(int(10 * rate)):              # silence: loss, fade, home
        session.tick(k / rate)
        modes.append(session.mode)
        k += 1
        if session.mode is Mode.STARTING:
            break
    assert Mode.FADING in modes and session.mode is Mode.STARTING
    for _ in range(int(2 * rate)):      # the envelope's own state settles on home (the fade
        session.tick(k / rate)          # began with the platform moving: it lags the quintic)
        k += 1
    np.testing.assert_allclose(session.envelope.last.q, scene.model.home, atol=1e-9)
    assert session.counts.fades == 1
    # a restarted sender (times from 0 again) is taken
    q.q.append(encode(TelemetrySample(0.0, (0.0, 0.0, 9.81), (0.0, 0.0, 0.0))))
    session.tick(k / rate)
    assert session.mode is Mode.RUNNING


def test_operator_park_resume_estop_over_udp(scene):
    control = Control(udp=("127.0.0.1", 0))
    sender = UdpSink(*control.address)
    q = Queue()
    session, dev, clock = offline_session(scene, q, control=control)
    rate = scene.controller.rate
    k = 0

    def ticks(n, telemetry=True):
        nonlocal k
        for _ in range(n):
            if telemetry and k % 10 == 0:
                q.q.append(encode(TelemetrySample(k / rate, (2.0, 1.0, 9.81), (0.1, 0.0, 0.2))))
            session.tick(k / rate)
            k += 1

    def say(word):
        sender.send(word.encode())
        select.select([control.sock], [], [], 2.0)

    try:
        ticks(500)
        assert session.mode is Mode.RUNNING
        say("park")
        ticks(1)
        assert session.mode is Mode.PARKING
        ticks(int(20 * rate))
        assert session.mode is Mode.PARKED
        np.testing.assert_allclose(session.envelope.last.q, scene.model.home, atol=1e-9)
        say("resume")
        ticks(1)
        assert session.mode in (Mode.STARTING, Mode.RUNNING)
        ticks(500)
        assert session.mode is Mode.RUNNING
        say("estop")
        ticks(1)
        assert session.mode is Mode.STOPPED
        ticks(int(2 * rate))
        np.testing.assert_allclose(session.envelope.last.qd, 0.0, atol=1e-9)
        say("bogus")
        ticks(1)
        assert control.unknown == 1
        assert session.counts.commands == {"park": 1, "resume": 1, "estop": 1}
    finally:
        sender.close()
        control.close()


# --- the command line ------------------------------------------------------------------------


@pytest.mark.parametrize("argv, words", [
    (["--telemetry", "udp://10.0.0.1:5000", "--device", "udp:127.0.0.1:1"], "loopback"),
    (["--telemetry", "udp://127.0.0.1:0", "--device", "tcp:1"], "device address"),
    (["--telemetry", "udp://127.0.0.1:0", "--device", "udp:10.0.0.2:14550"], "loopback"),
])
def test_cue_live_refuses_bad_addresses(argv, words, capsys):
    assert cli.main(["cue-live", str(SIM), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0]


def test_optimal_mode_at_rest_sends_home_exactly(scene):
    """`--mode optimal` (the MPC without preview, inline on the simulated clock): a vehicle at
    rest is no cue at all, every setpoint the home lengths."""
    q = Queue()
    clock = SimClock()
    dev = FakeDevice()
    session = make_session(scene, TelemetryReceiver(q, "native", clock), dev, TELEMETRY_RATE,
                           mode="optimal", synchronous=True)
    home = inverse_kinematics(scene.model, scene.model.home, with_cond=False).lengths
    rate = scene.controller.rate
    try:
        for k in range(300):
            clock.t = k / rate
            if k % 10 == 0:
                q.q.append(encode(TelemetrySample(clock.t, (0.0, 0.0, 9.81), (0.0, 0.0, 0.0))))
            session.tick(clock.t)
        assert session.mode is Mode.RUNNING and session.cue.steps == 30
        for _, _, l, ldot, _ in dev.setpoints:
            np.testing.assert_array_equal(l, home)
            np.testing.assert_array_equal(ldot, np.zeros(6))
    finally:
        session.cue.close()


def test_ctrl_c_parks_then_exits_130(tmp_path):
    """The command in real time against the device in its own process: SIGINT parks the
    platform (the summary says parked), writes the record, then exits 130 with one line."""
    import os
    import signal
    import subprocess
    import sys

    from hil.spawn import device_process, parse_udp

    record = tmp_path / "rec.csv"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with device_process(SIM, "udp") as first:
        host, port = parse_udp(first)
        proc = subprocess.Popen(
            [sys.executable, "-m", "stewart_sim", "cue-live", str(SIM), "--telemetry",
             "udp://127.0.0.1:0", "--device", f"udp:{host}:{port}", "--record", str(record)],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, env=env)
        try:
            ready, _, _ = select.select([proc.stdout], [], [], 120.0)
            assert ready and proc.stdout.readline().startswith("cue-live:")
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=120.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 130, err
    assert "mode at the end parked" in out, out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted" in lines[0] and "parked" in lines[0]
    header = record.read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "seq", "mode", "t_telemetry"]


@pytest.mark.parametrize("every", [1, 2, 3])
def test_a_slower_sender_is_resampled_onto_the_grid(scene, every):
    """A sender at the nominal rate, at half and at a third of it: the washout steps on the
    nominal grid, the input between samples interpolated linearly, so its cue is the offline
    `cue` of the sent motion resampled to the nominal rate (cueing.study.resample), to 1e-12."""
    from stewart_sim.cueing.study import resample
    from stewart_sim.cueing.washout_step import WashoutStepper

    motion = read_motion(BRAKING)
    sent = VehicleMotion(motion.t[::every], motion.specific_force[::every],
                         motion.angular_velocity[::every])
    h = 1.0 / TELEMETRY_RATE
    model = scene.model
    stream = CueStream(WashoutStepper(scene.cueing, model.home, model.gravity, h), h,
                       model.home)
    q = []
    for i, t in enumerate(sent.t):
        n = stream.push(TelemetrySample(float(t), tuple(sent.specific_force[i]),
                                        tuple(sent.angular_velocity[i])), float(t))
        assert n == (1 if i == 0 else every)
        q.append(stream.cue.q)
    offline = classical_washout(scene.cueing, resample(sent, TELEMETRY_RATE), model.home,
                                model.gravity)
    np.testing.assert_allclose(np.array(q), offline.q[::every], rtol=0, atol=1e-12)
    assert stream.interpolated == (len(sent.t) - 1) * (every - 1)


def test_outsim_telemetry_drives_the_same_cue(scene):
    """The same motion as OutSim packets (float32, whole milliseconds) and as native datagrams:
    the setpoints agree to what float32 keeps."""
    motion = read_motion(BRAKING)
    rate = scene.controller.rate
    out = {}
    for fmt in ("native", "outsim"):
        q = Queue()
        session, dev, clock = offline_session(scene, q, fmt)
        replay = Replay(motion, fmt)
        for k in range(int(4.0 * rate)):
            clock.t = k / rate
            q.q.extend(replay.due(clock.t))
            session.tick(clock.t)
        assert session.receiver.counts.accepted == 400
        out[fmt] = np.array([s[2] for s in dev.setpoints])
    assert np.ptp(out["native"]) > 0.05
    np.testing.assert_allclose(out["outsim"], out["native"], rtol=0, atol=1e-5)


def test_the_live_view_gets_the_vehicle_and_the_delivered_specific_force(scene):
    """--view's snapshots: at rest both specific forces are gravity's (0, 0, g) at the head;
    under a sustained forward push the vehicle's is the telemetry's and the delivered one has
    the tilt's share of it."""
    from hil.observe import OBSERVE_HZ, Latest

    latest = Latest()
    q = Queue()
    clock = SimClock()
    session = make_session(scene, TelemetryReceiver(q, "native", clock), FakeDevice(),
                           TELEMETRY_RATE, observer=latest)
    rate = scene.controller.rate
    g = float(np.linalg.norm(scene.model.gravity))
    for k in range(500):
        clock.t = k / rate
        if k % 10 == 0:
            q.q.append(encode(TelemetrySample(clock.t, (0.0, 0.0, g), (0.0, 0.0, 0.0))))
        session.tick(clock.t)
    snap = latest.latest()
    assert latest.published == math.ceil(500 / round(rate / OBSERVE_HZ))
    np.testing.assert_allclose(snap.f_vehicle, (0.0, 0.0, g), atol=1e-12)
    np.testing.assert_allclose(snap.f_delivered, (0.0, 0.0, g), atol=1e-9)
    np.testing.assert_allclose(snap.q, scene.model.home, atol=1e-12)
    for k in range(500, 5500):                    # 5 s of 2 m/s^2 forward
        clock.t = k / rate
        if k % 10 == 0:
            q.q.append(encode(TelemetrySample(clock.t, (2.0, 0.0, g), (0.0, 0.0, 0.0))))
        session.tick(clock.t)
    snap = latest.latest()
    assert snap.f_vehicle == (2.0, 0.0, g)
    # the tilt coordination delivers the sustained push as gravity's share: f_x > 0, by then
    # most of the scaled 0.5 x 2 m/s^2
    assert 0.5 < snap.f_delivered[0] < 1.2


# --- hostile timing: the work per tick is bounded ------------------------------------------------


def test_a_far_future_stream_costs_no_washout_step(scene):
    """The attack of a datagram 1e6 s past the newest sample on every tick, over a clean 100 Hz
    stream: every one refused as ahead of the stream's clock, the clean stream taken as if alone
    (one washout step per clean sample, at most one a tick), the setpoints those of the clean
    stream bit for bit."""
    rate = scene.controller.rate

    def run(hostile: bool):
        q = Queue()
        session, dev, clock = offline_session(scene, q)
        steps = []
        for k in range(int(2.0 * rate)):
            clock.t = k / rate
            if k % 10 == 0:
                q.q.append(encode(TelemetrySample(clock.t, (2.0, 0.5, 9.81), (0.1, 0.0, 0.0))))
            if hostile and k > 0:                # once the stream has its time line
                newest = session.receiver.last_t
                q.q.append(encode(TelemetrySample(newest + 1e6, (5.0, 0.0, 9.81),
                                                  (0.0, 0.0, 0.0))))
            before = session.cue.steps
            session.tick(clock.t)
            steps.append(session.cue.steps - before)
        return session, dev, steps

    clean, dev_clean, _ = run(False)
    hostile, dev_hostile, steps = run(True)
    assert hostile.receiver.counts.refused["ahead"] == int(2.0 * rate) - 1
    assert hostile.receiver.counts.accepted == 200 and max(steps) == 1
    assert hostile.cue.reanchored == 0 and hostile.mode is Mode.RUNNING
    for a, b in zip(dev_clean.setpoints, dev_hostile.setpoints):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_a_long_gap_is_caught_up_max_steps_a_tick_and_a_huge_one_re_anchors(scene):
    """A gap of 3 MAX_STEPS + 4 grid points: the sample's tick takes MAX_STEPS washout steps,
    the next ticks (advance) MAX_STEPS each and then the last 4, the cue exactly that of the
    washout stepped on the input interpolated over the whole gap; a sample more than
    MAX_BACKLOG grid points past the last step re-anchors: one step on the sample, the grid
    restarted at its time (the next sample one period later takes one step)."""
    from stewart_sim.cueing.washout_step import WashoutStepper
    from stewart_sim.live.cue_stream import MAX_BACKLOG, MAX_STEPS

    h = 1.0 / TELEMETRY_RATE
    model = scene.model

    def stepper():
        return WashoutStepper(scene.cueing, model.home, model.gravity, h)

    stream = CueStream(stepper(), h, model.home)
    a = TelemetrySample(0.0, (1.0, 0.0, 9.81), (0.0, 0.1, 0.0))
    n = 3 * MAX_STEPS + 4
    b = TelemetrySample(n * h + 0.37 * h, (-2.0, 1.0, 9.0), (0.2, 0.0, -0.1))   # off the grid
    assert stream.push(a, 0.0) == 1
    assert stream.push(b, 1.0) == MAX_STEPS and stream.behind
    assert [stream.advance(1.0 + k * 1e-3) for k in range(1, 5)] == [MAX_STEPS, MAX_STEPS, 4, 0]
    assert not stream.behind and stream.steps == n + 1 and stream.reanchored == 0
    alone = stepper()
    alone.step(a.specific_force, a.angular_velocity)
    for j in range(1, n + 1):
        x = (j * h - a.t) / (b.t - a.t)
        c = alone.step(tuple(p + x * (r - p) for p, r in zip(a.specific_force, b.specific_force)),
                       tuple(p + x * (r - p) for p, r in zip(a.angular_velocity,
                                                             b.angular_velocity)))
    np.testing.assert_allclose(stream.cue.q, c.q, rtol=0, atol=1e-12)
    assert stream.cue_time == pytest.approx(n * h)
    t = b.t + (MAX_BACKLOG + 1) * h                      # too far: re-anchored
    assert stream.push(TelemetrySample(t, a.specific_force, a.angular_velocity), 2.0) == 1
    assert stream.reanchored == 1 and stream.cue_time == t and not stream.behind
    assert stream.push(TelemetrySample(t + h, a.specific_force, a.angular_velocity), 2.1) == 1
    for far in (t + 1e6, t + 2e6, 4e9):
        assert stream.push(TelemetrySample(far, a.specific_force, a.angular_velocity), 3.0) == 1
    assert stream.push(TelemetrySample(4e9 + h, a.specific_force, a.angular_velocity), 4.0) == 1
    assert stream.reanchored == 4 and np.all(np.isfinite(stream.cue.q))


def test_a_sample_during_a_backlog_continues_from_the_newest_step(scene):
    """A sample that comes while grid points before the last one remain: the segment goes on
    from the newest step's input to the new sample, so its grid points are taken in time
    order, each once, and every step is finite."""
    from stewart_sim.cueing.washout_step import WashoutStepper
    from stewart_sim.live.cue_stream import MAX_STEPS

    h = 1.0 / TELEMETRY_RATE
    model = scene.model
    stream = CueStream(WashoutStepper(scene.cueing, model.home, model.gravity, h), h,
                       model.home)
    f, w = (1.0, 0.0, 9.81), (0.0, 0.0, 0.0)
    stream.push(TelemetrySample(0.0, f, w), 0.0)
    assert stream.push(TelemetrySample(25 * h, f, w), 0.25) == MAX_STEPS
    times = [stream.cue_time]
    assert stream.push(TelemetrySample(30 * h, (3.0, 0.0, 9.81), w), 0.3) == MAX_STEPS
    times.append(stream.cue_time)
    while stream.behind:
        stream.advance(0.31)
        times.append(stream.cue_time)
    assert times == pytest.approx([MAX_STEPS * h, 2 * MAX_STEPS * h, 30 * h])
    assert stream.steps == 31 and np.all(np.isfinite(stream.cue.q))


# --- the loss of the device --------------------------------------------------------------------


def test_a_device_that_stops_answering_is_lost_once_and_the_session_ends(scene):
    """On a simulated clock: the device answers the first 100 setpoints, then nothing. The
    tick whose time is more than the device's watchdog (0.2 s) past the last LEG_STATE finds it
    lost: one line, at once, counted, the summary says so; run_realtime ends there (no park:
    no setpoint after that tick) and disarms."""
    from stewart_sim.live.session import run_realtime, summary_lines

    class Clock:                      # moves 0.25 ms a read: run_realtime's waits end at once
        t = 0.0

        def __call__(self) -> float:
            self.t += 2.5e-4
            return self.t

    q = Queue()
    dev = FakeDevice(silent_after=100)
    said: list[str] = []
    session = make_session(scene, TelemetryReceiver(q, "native", SimClock()), dev,
                           TELEMETRY_RATE, warn=said.append)
    assert session.device_timeout == FakeDevice.watchdog
    for k in range(int(0.05 * scene.controller.rate)):     # telemetry for a while: cueing
        if k % 10 == 0:
            q.q.append(encode(TelemetrySample(k / 1000, (2.0, 0.0, 9.81), (0.0, 0.0, 0.0))))
    run_realtime(session, duration=30.0, clock=Clock())
    # the last LEG_STATE came with setpoint 99 (t = 0.099 s): lost at the first tick past
    # 0.099 + 0.2 s, tick 300
    assert session.device_lost and session.device_lost_at == pytest.approx(0.300)
    assert len(dev.setpoints) == 301 and dev.held
    assert session.counts.device_losses == 1 and session.stopped_by == "the device's loss"
    assert len(said) == 1 and "device lost at 0.300 s" in said[0]
    text = "\n".join(summary_lines(session))
    assert "lost 1 (at 0.300 s" in text and "stopped by the device's loss" in text


def test_a_device_that_answers_late_is_not_lost(scene):
    """A device whose states come in bunches (the host stalled: they waited in the socket) is
    not lost as long as each gap is within its watchdog."""
    class Bunching(FakeDevice):
        def send(self, k, t, l, ldot, force, force_rate):
            states = super().send(k, t, l, ldot, force, force_rate)
            return states * 190 if k % 190 == 0 else []     # a bunch every 0.19 s

    dev = Bunching()
    said: list[str] = []
    session = make_session(scene, TelemetryReceiver(Queue(), "native", SimClock()), dev,
                           TELEMETRY_RATE, warn=said.append)
    for k in range(2000):
        session.tick(k / scene.controller.rate)
    assert not session.device_lost and said == [] and session.counts.device_losses == 0


def test_killing_the_device_mid_session_ends_cue_live_at_once(tmp_path):
    """The command in real time against the device in its own process, which is then killed:
    one line on stderr saying the device is lost, the summary counts it, exit 2 (no park, no
    Ctrl-C needed), the record written."""
    import os
    import subprocess
    import sys

    from hil.spawn import device_command, parse_udp

    record = tmp_path / "rec.csv"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    device = subprocess.Popen(device_command(SIM, "udp", False), stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True)
    proc = None
    try:
        ready, _, _ = select.select([device.stdout], [], [], 120.0)
        assert ready
        host, port = parse_udp(device.stdout.readline().strip())
        proc = subprocess.Popen(
            [sys.executable, "-m", "stewart_sim", "cue-live", str(SIM), "--telemetry",
             "udp://127.0.0.1:0", "--device", f"udp:{host}:{port}", "--record", str(record),
             "--duration", "600"],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, env=env)
        ready, _, _ = select.select([proc.stdout], [], [], 120.0)
        assert ready and proc.stdout.readline().startswith("cue-live:")
        device.kill()
        device.wait()
        out, err = proc.communicate(timeout=120.0)
    finally:
        for p in (device, proc):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
    assert proc.returncode == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 2 and "device lost at" in lines[0] and "watchdog" in lines[0]
    assert "the device was lost" in lines[1] and "Traceback" not in err
    assert "lost 1 (at" in out and "stopped by the device's loss" in out
    assert record.read_text().splitlines()[0].startswith("t,seq,mode,t_telemetry")


# --- fuzzed telemetry timing ---------------------------------------------------------------------


def hostile_tick(rng, t: float, newest: float | None, last: bytes | None) -> list[bytes]:
    """One tick's datagrams, a seeded draw of the timing attacks: on time, far future,
    backwards, bursts, duplicates, random times, absurd times, silence; values anywhere within
    the decoder's bounds (+-999 m/s^2 alternating as often as not)."""
    from stewart_sim.cueing.motion import VALUE_BOUNDS

    def sample(when: float) -> bytes:
        f = rng.uniform(-1, 1, 3) * (0.98 * VALUE_BOUNDS["f"] if rng.random() < 0.3 else 5.0)
        w = rng.uniform(-1, 1, 3) * (VALUE_BOUNDS["w"] if rng.random() < 0.3 else 0.5)
        return encode(TelemetrySample(when, tuple(f + (0.0, 0.0, 9.81)), tuple(w)))

    base = newest if newest is not None else t
    kind = rng.integers(9)
    if kind == 0:                                           # on time
        return [sample(t)]
    if kind == 1:                                           # far future
        return [sample(base + 10.0 ** rng.uniform(-3, 9))]
    if kind == 2:                                           # backwards
        return [sample(base - 10.0 ** rng.uniform(-4, 9))]
    if kind == 3:                                           # a burst around now
        return [sample(t + d) for d in rng.uniform(-0.2, 0.2, int(rng.integers(1, 300)))]
    if kind == 4 and last is not None:                      # duplicates
        return [last] * int(rng.integers(1, 50))
    if kind == 5:                                           # any time at all
        return [sample(float(rng.uniform(-4e9, 4e9)))]
    if kind == 6:                                           # beyond any clock: refused
        return [b"STW\x01" + struct.pack("<7d", float(rng.choice([1e300, -1e300, 5e9])),
                                         0.0, 0.0, 9.81, 0.0, 0.0, 0.0)]
    return []                                               # silence


@pytest.mark.parametrize("seed, loss_timeout", [(0, 0.1), (1, 0.1), (2, 1.0), (3, 1.0)])
def test_fuzzed_telemetry_timing(scene, seed, loss_timeout):
    """Seeded hostile timing (hostile_tick) over 3 s of ticks, with the default loss timeout
    and a long one (where gaps re-anchor the washout): never an exception, every datagram
    accounted for, no tick takes more than MAX_STEPS washout steps, every setpoint finite and
    inside the legs' stroke."""
    from stewart_sim.live.cue_stream import MAX_STEPS

    rng = np.random.default_rng(seed)
    q = Queue()
    clock = SimClock()
    dev = FakeDevice()
    session = make_session(scene, TelemetryReceiver(q, "native", clock), dev, TELEMETRY_RATE,
                           loss_timeout=loss_timeout)
    rate = scene.controller.rate
    last = None
    most = 0
    for k in range(int(3.0 * rate)):
        clock.t = k / rate
        sent = hostile_tick(rng, clock.t, session.receiver.last_t, last)
        q.q.extend(sent)
        last = sent[-1] if sent else last
        before = session.cue.steps
        session.tick(clock.t)
        most = max(most, session.cue.steps - before)
    c = session.receiver.counts
    assert c.received == c.accepted + c.superseded + c.refused_total + len(q.q)
    assert c.accepted > 20 and c.refused["ahead"] > 10 and c.refused["out_of_order"] > 10
    assert 1 <= most <= MAX_STEPS
    lengths = np.array([s[2] for s in dev.setpoints])
    model = scene.model
    assert np.all(np.isfinite(lengths))
    assert np.all(lengths >= model.leg_min) and np.all(lengths <= model.leg_max)
    print(f"\nseed {seed}: {c.accepted} accepted, refused {c.refused}, most steps a tick "
          f"{most}, re-anchored {session.cue.reanchored}, fades {session.counts.fades}")
