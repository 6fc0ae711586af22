"""Hostile input to the emulated device: every repro of the hardening brief is refused and the
device keeps serving (controller.capability, hil.input_bounds, hil.throttle, hil.signing, hil.peer, the numerical safe
hold); a seeded fuzz in process and once against the device process over UDP. Bounded and deterministic: no
wall-clock pass/fail (wall-clock waits only bound how long a socket is read)."""
from __future__ import annotations

import math
import random
import select
import signal
import socket
import struct
import subprocess
import time
from pathlib import Path
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from controller.capability import DEVICE_FORCE, DEVICE_RATE, overshoot_room  # noqa: E402
from hil import throttle  # noqa: E402
from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device, DeviceError  # noqa: E402
from hil.framing import Receiver, crc16, pack  # noqa: E402
from hil.link import udp_server  # noqa: E402
from hil.peer import PEER_HOLD  # noqa: E402
from hil.serve import serve_in_thread  # noqa: E402
from hil.signing import SIGNING_EPOCH  # noqa: E402
from hil.spawn import _first_line, device_command, parse_udp  # noqa: E402
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
KEY = bytes(range(32))


def host_mav(key: bytes | None = None):
    mav = ms.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - SIGNING_EPOCH) * 1e5)
    return mav


def arm(value: int = 1):
    return ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, value,
                                           0, 0, 0, 0, 0, 0)


def setpoint(seq: int, lengths):
    return ms.MAVLink_leg_setpoint_message(seq * 1000, seq, list(map(float, lengths)), [0.0] * 6, 0,
                                           [0.0] * 6)


def types(msgs) -> list[str]:
    return [m.get_type() for m in msgs]


def texts(msgs) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


def joined(msgs) -> str:
    """The one text that STATUSTEXT chunks (one id, chunk_seq 0, 1, ...) carry."""
    assert len({m.id for m in msgs}) == 1 and [m.chunk_seq for m in msgs] == list(range(len(msgs)))
    return "".join(m.text for m in msgs)

RATE, FORCE, FORCE_RATE = (ms.STEWART_SETPOINT_FLAG_RATE_VALID, ms.STEWART_SETPOINT_FLAG_FORCE_VALID,
                           ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID)
T0 = 500_000_000_000  # a fixed signing clock (10 us units since 2015): deterministic tests


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def param_set(name: str, value: float):
    return ms.MAVLink_param_set_message(1, 1, name.encode(), value, ms.MAV_PARAM_TYPE_REAL32)


def read_kp():
    return ms.MAVLink_param_request_read_message(1, 1, b"CTRL_KP", -1)


def still_serving(dev: Device) -> None:
    """The device answers a PARAM_REQUEST_READ and its plant state is finite."""
    out = dev.receive(read_kp())
    assert types(out) == ["PARAM_VALUE"] and out[0].param_value == pytest.approx(dev.gains.kp, rel=1e-6)
    o = dev.plant.outputs
    assert np.all(np.isfinite(o.q)) and np.all(np.isfinite(o.lengths))
    assert dev.counters.handler_errors == 0


def full_setpoint(seq, lengths, rate=None, force=None, force_rate=None, flags=0):
    z = [0.0] * 6
    return ms.MAVLink_leg_setpoint_message(seq, seq, list(map(float, lengths)),
                                           list(map(float, rate if rate is not None else z)), flags,
                                           list(map(float, force if force is not None else z)),
                                           list(map(float, force_rate if force_rate is not None else z)))


# --------------------------------------------------------------------------- 1. setpoints


def test_rate_1e307_with_force_is_refused_and_nothing_moves(model):
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    out = dev.receive(full_setpoint(1, l0, [1e307] * 6, [1.0] * 6, flags=RATE | FORCE))
    assert dev.counters.setpoints_refused == 1 and dev.counters.setpoints_accepted == 0
    [t] = texts(out)
    assert "rate 1e+307" in t and "bound 3" in t, t   # names the value and the bound
    for _ in range(200):
        dev.tick()
    assert dev.armed and dev.counters.numeric_faults == 0 and dev.counters.faults == 0
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-12
    still_serving(dev)



def _follow(dev: Device, lengths, seconds: float, seq: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Stream one setpoint for `seconds` of device time (one per tick, as a host does); the
    smallest and largest length each leg reached, and the next sequence number."""
    lo, hi = np.full(6, np.inf), np.full(6, -np.inf)
    for _ in range(round(seconds * dev.rate)):
        dev.receive(setpoint(seq, lengths))
        seq += 1
        dev.tick()
        lo = np.minimum(lo, dev.plant.outputs.lengths)
        hi = np.maximum(hi, dev.plant.outputs.lengths)
    return lo, hi, seq


@pytest.mark.parametrize("scene", ["micro_manipulator", "motion_simulator"])
def test_every_accepted_bound_is_reached_without_a_fault(scene):
    """A setpoint of exactly SP_LEN_MAX (then SP_LEN_MIN, then SP_LEN_MAX again) on every leg,
    each a full-stroke step at the drive's no-load speed: were SP_LEN_MAX = leg_max, the servo
    would overshoot into the end stop (fault, disarmed); the bounds keep the servo's overshoot
    room free, so every step is accepted, reached, and nothing faults. Device time only
    (ticks), deterministic."""
    m = load_scene(ROOT / "scenes" / f"{scene}.toml")
    dev = Device(m)
    room = overshoot_room(dev.ctrl.axis, float(np.max(np.abs(dev.plant.rack_force))))
    b = dev.capability
    assert room > 0 and (b.leg_min, b.leg_max) == pytest.approx((m.leg_min + room, m.leg_max - room))
    values = {p.param_id: p.param_value for p in dev.receive(ms.MAVLink_param_request_list_message(1, 1))}
    assert (values["SP_LEN_MIN"], values["SP_LEN_MAX"]) == pytest.approx((b.leg_min, b.leg_max))
    dev.receive(arm())
    seconds = 1.0 if scene == "micro_manipulator" else 2.0   # a full stroke, then settled
    seq = 1
    for bound in (b.leg_max, b.leg_min, b.leg_max):
        target = np.full(6, bound)
        lo, hi, seq = _follow(dev, target, seconds, seq)
        assert dev.counters.setpoints_refused == 0 and dev.counters.faults == 0
        assert dev.counters.numeric_faults == 0 and dev.armed
        assert np.all(lo > m.leg_min) and np.all(hi < m.leg_max)          # never at a stop
        assert np.max(np.abs(dev.plant.outputs.lengths - target)) < 1e-3 * (m.leg_max - m.leg_min)
    # one leg at a time to each bound from home, where the lengths have a pose (others refused)
    for leg in range(6):
        for bound in (b.leg_max, b.leg_min):
            dev = Device(m)
            dev.receive(arm())
            target = dev.plant.outputs.lengths.copy()
            target[leg] = bound
            _, _, _ = _follow(dev, target, seconds, 1)
            c = dev.counters
            assert c.faults == 0 and c.numeric_faults == 0, (leg, bound)
            assert c.setpoints_accepted == 0 or dev.armed


def test_a_stroke_shorter_than_the_overshoot_room_is_refused(model):
    """A stroke that leaves no setpoint once the overshoot room is kept at both ends: the device
    is not built (one line naming the stroke and the room), it does not accept setpoints it
    could only fault on."""
    l0 = float(inverse_kinematics(model, model.home).lengths[0])
    narrow = replace(model, leg_min=l0 - 0.004, leg_max=l0 + 0.004)   # room 4.7 mm > 4 mm
    with pytest.raises(DeviceError, match=r"leaves no setpoint .*overshoot room \(0\.0046"):
        Device(narrow)


def test_a_setpoint_past_the_overshoot_room_is_refused(model):
    """Between SP_LEN_MAX and the stroke's end: refused, the text names the setpoint stroke."""
    dev = Device(model)
    dev.receive(arm())
    past = np.full(6, dev.capability.leg_max + 1e-5)
    assert past[0] < model.leg_max
    [t] = texts(dev.receive(setpoint(1, past)))
    assert t == f"refused: leg 1 at {past[0]:.4g} m, stroke max {dev.capability.leg_max:.4g}", t
    assert dev.counters.setpoints_refused == 1 and dev.counters.setpoints_accepted == 0

@pytest.mark.parametrize("field, value, flags", [("force", 1e308, FORCE), ("rate", 1e300, RATE),
                                                 ("force_rate", 1e300, FORCE | FORCE_RATE),
                                                 ("force", -1e5, FORCE), ("rate", 3.5, RATE)])
def test_absurd_finite_setpoints_are_refused(model, field, value, flags):
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    kw = {field: [0.0, 0.0, value, 0.0, 0.0, 0.0]}
    if field == "force_rate":
        kw["force"] = [0.0] * 6
    out = dev.receive(full_setpoint(1, l0, flags=flags, **kw))
    assert dev.counters.setpoints_refused == 1, texts(out)
    # the value sits at index 2: the third leg, numbered 1..6 as in every table
    assert texts(out)[0].startswith("refused: leg 3") and f"{value:.3g}" in texts(out)[0]
    for _ in range(100):
        dev.tick()
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-12
    still_serving(dev)


def test_bounds_table_follows_the_drive(model):
    dev = Device(model)
    b, ax, r = dev.capability, dev.ctrl.axis, dev.param_ranges
    # 10 x 0.3 m/s
    assert b.setpoint_rate == pytest.approx(DEVICE_RATE * 24.0 / ax.emf_constant)
    assert b.setpoint_force == pytest.approx(DEVICE_FORCE * ax.force_constant * 2.0)
    room = overshoot_room(ax, float(np.max(np.abs(dev.plant.rack_force))))
    assert (b.leg_min, b.leg_max) == (model.leg_min + room, model.leg_max - room)
    assert r.voltage_range[1] == 24.0 and r.current_range[1] == 2.0
    values = {m.param_id: m.param_value for m in dev.receive(ms.MAVLink_param_request_list_message(1, 1))}
    assert values["SP_RATE_MAX"] == pytest.approx(b.setpoint_rate)
    assert values["SP_FORCE_MAX"] == pytest.approx(b.setpoint_force)
    out = dev.receive(param_set("SP_RATE_MAX", 1e9))  # read-only
    assert out[0].param_value == pytest.approx(b.setpoint_rate) and "read-only" in texts(out)[0]
    with pytest.raises(DeviceError):
        Device(model, watchdog=1e-38)


# --------------------------------------------------------------------------- parameters


@pytest.mark.parametrize("name, value", [("DRV_V_LIMIT", 1e6), ("DRV_I_LIMIT", 1e6), ("CTRL_KP", 1e9),
                                         ("CTRL_KD", 3e38), ("CTRL_KI", -1.0), ("WDG_TIMEOUT", 1e-38),
                                         ("WDG_TIMEOUT", 1e6), ("SP_COND_MAX", 1e30),
                                         ("SR_LEG_STATE", 1e9), ("DRV_V_LIMIT", 0.0)])
def test_hostile_parameter_is_refused_with_the_unchanged_value(model, name, value):
    dev = Device(model)
    before = dev.params[name].get()
    out = dev.receive(param_set(name, value))
    assert types(out)[0] == "PARAM_VALUE" and set(types(out)[1:]) == {"STATUSTEXT"}
    assert out[0].param_value == pytest.approx(before) and dev.params[name].get() == before
    text = "".join(texts(out))  # one text (in 50-byte chunks when longer)
    assert f"{value:g}" in text and "must be in" in text, text
    assert dev.counters.params_refused == 1
    still_serving(dev)


def test_hostile_parameter_set_then_4mm_step_tracks(model):
    """The brief's repro 2: DRV_V_LIMIT 1e6, DRV_I_LIMIT 1e6, CTRL_KP 1e9, then a 4 mm step."""
    dev = Device(model, watchdog=5.0)
    for name, value in (("DRV_V_LIMIT", 1e6), ("DRV_I_LIMIT", 1e6), ("CTRL_KP", 1e9)):
        dev.receive(param_set(name, value))
    assert dev.counters.params_refused == 3
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    goal = l0 + np.array([0.004, 0, 0, 0, 0, 0])
    dev.receive(setpoint(1, goal))
    for _ in range(500):
        dev.tick()
    assert dev.armed and dev.counters.numeric_faults == 0
    assert np.max(np.abs(dev.plant.outputs.lengths - goal)) < 1e-4
    still_serving(dev)


def test_watchdog_flood_is_refused_and_statustext_is_rate_limited(model):
    dev = Device(model)
    out = dev.receive(param_set("WDG_TIMEOUT", 1e-38))
    assert out[0].param_value == pytest.approx(0.2) and dev.watchdog == 0.2
    # the shortest allowed watchdog with setpoints just slower: trips and resumes 50 times a
    # second; and 2000 refusals of distinct texts: the token bucket keeps the link usable
    dev.receive(param_set("WDG_TIMEOUT", 0.01))
    assert dev.watchdog == 0.01
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    n_text = 0
    for k in range(1000):  # 1 s of device time
        if k % 20 == 0:
            n_text += len(texts(dev.receive(setpoint(k, l0))))
        if k % 2 == 0:
            n_text += len(texts(dev.receive(param_set(f"NOPE{k}", 1.0))))
        n_text += len(texts(dev.tick()))
    assert dev.counters.watchdog_trips == 50
    assert n_text <= throttle.STATUS_BURST + throttle.STATUS_RATE * 1.0 + 1, n_text
    assert dev.counters.statustexts_rate_limited >= 500
    still_serving(dev)


# --------------------------------------------------------------------------- 2. numbers


def test_numerical_failure_in_the_loop_gives_a_safe_hold(model):
    """Drive limits and gain beyond what the checks accept (set behind them): the 4 mm
    step makes the integration fail; the device holds the last good pose, disarms, says so
    once (CRITICAL) and keeps serving with the designed gains and rated limits."""
    dev = Device(model)
    dev.servo.set_motor("voltage_limit", 1e6)
    dev.servo.set_motor("current_limit", 1e6)
    dev.ctrl.gains = replace(dev.ctrl.gains, kp=1e9)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    dev.receive(setpoint(1, l0 + np.array([0.004, 0, 0, 0, 0, 0])))
    out = []
    for _ in range(300):
        out += dev.tick()
    crit = [m for m in out if m.get_type() == "STATUSTEXT" and m.severity == ms.MAV_SEVERITY_CRITICAL]
    assert len({m.id for m in crit}) == 1 and crit[0].text.startswith("numeric fault (IntegrationError)")
    assert dev.counters.numeric_faults == 1 and not dev.armed
    assert dev.gains == dev.design_gains and dev.ctrl.axis.motor.voltage_limit == 24.0
    # the text (one text in chunks) names every gain and limit restored, before and after
    g = dev.design_gains
    assert joined(crit) == (
        "numeric fault (IntegrationError): hold, disarmed; restored "
        f"CTRL_KP 1e+09 -> {g.kp:.4g}, DRV_V_LIMIT 1e+06 -> 24, DRV_I_LIMIT 1e+06 -> 2 "
        f"(CTRL_KI {g.ki:.4g}, CTRL_KD {g.kd:.4g} kept)")
    assert dev.last_fault.endswith(joined(crit).split("; ", 1)[1])
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-6   # held at the last good pose
    still_serving(dev)


def test_non_finite_torque_gives_a_safe_hold(model, monkeypatch):
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    real = dev.motors.step
    calls = {"n": 0}

    def bad_once(v, ldot):
        calls["n"] += 1
        torque, lim = real(v, ldot)
        return (torque * np.nan if calls["n"] == 5 else torque), lim

    monkeypatch.setattr(dev.motors, "step", bad_once)
    out = []
    for _ in range(100):
        out += dev.tick()
    crit = [m for m in out if m.get_type() == "STATUSTEXT" and m.severity == ms.MAV_SEVERITY_CRITICAL]
    g = dev.design_gains
    assert joined(crit) == (
        "numeric fault (FloatingPointError): hold, disarmed; design gains and limits kept: "
        f"CTRL_KP {g.kp:.4g}, CTRL_KI {g.ki:.4g}, CTRL_KD {g.kd:.4g}, DRV_V_LIMIT 24, DRV_I_LIMIT 2")
    assert dev.counters.numeric_faults == 1 and not dev.armed
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-9
    still_serving(dev)


# --------------------------------------------------------------------------- 3. signing


def signed_device(model) -> Device:
    dev = Device(model, signing_key=KEY)
    dev.signing_clock = lambda: T0
    return dev


def host_at(ts: int, link_id: int = 0):
    mav = host_mav(key=KEY)
    mav.signing.timestamp = ts
    mav.signing.link_id = link_id
    return mav


def test_forged_future_timestamp_does_not_lock_the_host_out(model):
    dev = signed_device(model)
    forged = bytearray(arm().pack(host_mav(key=bytes(32))))  # the host's ids: 255/190
    forged[-13:] = bytes((0,)) + (2**48 - 1).to_bytes(6, "little") + b"\xde\xad\xbe\xef\x00\x01"
    assert forged[2] & 1 and Receiver(ms).feed(bytes(forged))  # CRC good: only the signature is bad
    assert dev.feed(bytes(forged)) == [] and dev.counters.signing_rejected == 1
    assert dev.verifier.streams == {}                  # nothing stored
    host = host_at(T0 - 1000)
    out = dev.feed(bytes(arm().pack(host)))
    assert types(out)[0] == "COMMAND_ACK" and dev.armed
    # pymavlink's own check, for the record: the same forged frame does lock it out
    victim = host_mav(key=KEY)
    victim.signing.allow_unsigned_callback = lambda *a: False
    pm = ms.MAVLink(None, 1, 1)
    pm.signing.secret_key, pm.signing.timestamp = KEY, T0
    pm.signing.allow_unsigned_callback = lambda *a: False
    with pytest.raises(Exception):
        pm.decode(bytearray(forged))
    with pytest.raises(Exception):
        pm.decode(bytearray(arm().pack(host_at(T0 + 10))))
    assert still_serving(dev) is None


def test_signing_timestamp_rules(model):
    dev = signed_device(model)
    host = host_at(T0)
    frame = bytes(read_kp().pack(host))
    assert types(dev.feed(frame)) == ["PARAM_VALUE"]
    assert dev.feed(frame) == []                                   # replay: same timestamp
    ahead = bytes(read_kp().pack(host_at(T0 + 6_000_001, link_id=1)))
    assert dev.feed(ahead) == []                                   # > 1 min ahead, valid signature
    old = bytes(read_kp().pack(host_at(T0 - 6_000_001, link_id=2)))
    assert dev.feed(old) == []                                     # new stream, > 1 min behind
    ok = bytes(read_kp().pack(host_at(T0 + 5_000_000, link_id=3)))
    assert types(dev.feed(ok)) == ["PARAM_VALUE"]                 # within the minute
    assert dev.verifier.rejected == {"timestamp replayed": 1, "timestamp ahead": 1,
                                     "timestamp too old": 1}
    assert dev.counters.signing_rejected == 3
    assert types(dev.feed(bytes(read_kp().pack(host)))) == ["PARAM_VALUE"]  # host goes on
    still_serving(dev)


# --------------------------------------------------------------------------- UDP peer


class _Udp:
    def __init__(self, server_address):
        self.s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.s.bind(("127.0.0.1", 0))
        self.s.setblocking(False)
        self.to = server_address

    def send(self, data: bytes) -> None:
        self.s.sendto(data, self.to)

    def collect(self, rx: Receiver, until, limit: float = 5.0) -> list:
        got, deadline = [], time.monotonic() + limit
        while time.monotonic() < deadline:
            if select.select([self.s], [], [], 0.02)[0]:
                got += rx.feed(self.s.recv(65536))
                if until(got):
                    break
        return got

    def drain(self, wait: float = 0.2) -> int:
        n, deadline = 0, time.monotonic() + wait
        while time.monotonic() < deadline:
            if select.select([self.s], [], [], 0.02)[0]:
                self.s.recv(65536)
                n += 1
        return n


def _has(kind, pred=lambda m: True):
    return lambda got: any(m.get_type() == kind and pred(m) for m in got)


@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signed"])
def test_a_datagram_cannot_hijack_the_replies(model, signed):
    dev = Device(model, signing_key=KEY if signed else None)
    server = udp_server("127.0.0.1", 0)
    thread, stop, _ = serve_in_thread(dev, server)
    host, attacker = _Udp(server.address), _Udp(server.address)
    hmav = host_mav(key=KEY if signed else None)
    try:
        host.send(bytes(read_kp().pack(hmav)))
        assert _has("PARAM_VALUE")(host.collect(Receiver(ms, host_mav(key=KEY if signed else None)), _has("PARAM_VALUE")))
        attacker.send(bytes(random.Random(1).getrandbits(8) for _ in range(64)))   # garbage
        attacker.send(b"\xfd" + bytes(40))
        if signed:  # a valid frame, unsigned or with a wrong key: dropped, no change
            attacker.send(bytes(read_kp().pack(host_mav())))
            attacker.send(bytes(read_kp().pack(host_mav(key=bytes(32)))))
        host.send(bytes(read_kp().pack(hmav)))
        got = host.collect(Receiver(ms, host_mav(key=KEY if signed else None)),
                           _has("PARAM_VALUE"))
        assert _has("PARAM_VALUE")(got)                              # replies
        # ... and telemetry: everything the device sends goes to its transport's peer (waiting
        # for the 1 Hz HEARTBEAT instead made the test depend on the machine's load)
        assert server.peer == host.s.getsockname()
        assert attacker.drain() == 0                                 # the attacker gets nothing
        assert dev.counters.peer_changes == 0
        if not signed:  # a valid frame from a new port moves the peer (once the host has been
            time.sleep(PEER_HOLD)   # quiet for the hold, hil.peer), and the earlier one is told
            attacker.send(bytes(read_kp().pack(host_mav())))
            told = host.collect(Receiver(ms), _has("STATUSTEXT", lambda m: "peer" in m.text))
            assert _has("STATUSTEXT", lambda m: m.text.startswith("peer 127.0.0.1:"))(told)
            assert dev.counters.peer_changes == 1
    finally:
        stop.set()
        thread.join(5)
        server.close()
        host.s.close()
        attacker.s.close()
    assert not thread.is_alive()
    assert dev.counters.handler_errors == 0 and dev.counters.numeric_faults == 0


class _Server:
    """An unconnected UDP server end as hil.peer sees it, without a socket: the test says who
    sent each datagram (deterministic, no wall clock)."""

    connected = False

    def __init__(self):
        self.follow_sender = True
        self.peer = self.sender = None
        self.sent: list[tuple[tuple[str, int], bytes]] = []

    def send(self, data: bytes) -> int:
        self.sent.append((self.peer, data))
        return len(data)


def test_signed_frames_from_another_address_do_not_move_the_peer_while_armed(model):
    """Signed: the host arms from port 1000; a correctly signed frame from port 2000 (another
    holder of the key, or a replayed stream on a new link) is handled, but the replies and the
    telemetry stay with the host while armed (they do not follow the new address); after disarm a
    signed frame from port 2000 may take the peer, and says so."""
    from hil.peer import PeerGuard

    dev, tr = signed_device(model), _Server()
    guard = PeerGuard(dev, tr)
    host, other = ("127.0.0.1", 1000), ("127.0.0.1", 2000)
    hmav, omav = host_at(T0 - 1000, link_id=0), host_at(T0 - 1000, link_id=1)

    def datagram(sender, mav, msg):
        tr.sender = sender
        out = dev.feed(pack(mav, msg))
        guard.after_feed()
        return out

    assert types(datagram(host, hmav, arm()))[0] == "COMMAND_ACK" and dev.armed
    assert tr.peer == host
    tr.sent.clear()
    assert types(datagram(other, omav, read_kp())) == ["PARAM_VALUE"]   # authenticated: handled
    assert tr.peer == host and dev.counters.peer_kept == 1 and dev.counters.peer_changes == 0
    notice = Receiver(ms).feed(b"".join(f for _, f in tr.sent))
    assert {p for p, _ in tr.sent} == {host}
    assert texts(notice) == ["peer kept while armed: 127.0.0.1:2000"]
    for _ in range(5):                                                  # and again: still kept
        datagram(other, omav, read_kp())
    assert tr.peer == host and dev.counters.peer_kept == 6
    datagram(host, hmav, arm(0))
    assert not dev.armed
    datagram(other, omav, read_kp())                                     # disarmed: it may move
    assert tr.peer == other and dev.counters.peer_changes == 1 and dev.counters.peer_kept == 6
    # the new peer arms; the earlier host's signed frames do not move it
    datagram(other, omav, arm())
    assert dev.armed
    datagram(host, hmav, read_kp())
    assert tr.peer == other and dev.counters.peer_kept == 7
    still_serving(dev)


def test_unsigned_a_streaming_peer_keeps_its_replies(model):
    """Unsigned: a valid frame from another port moves the peer only when the peer has sent no
    valid frame for PEER_HOLD s (a host streaming setpoints keeps its replies under a flood of
    valid frames; a host gone quiet is replaced at once, and the change is told)."""
    from hil.peer import PEER_HOLD, PeerGuard

    t = [0.0]
    dev, tr = Device(model), _Server()
    guard = PeerGuard(dev, tr, clock=lambda: t[0])
    host, other = ("127.0.0.1", 1000), ("127.0.0.1", 2000)

    def datagram(at, sender):
        t[0], tr.sender = at, sender
        dev.feed(pack(host_mav(), read_kp()))
        guard.after_feed()

    datagram(0.0, host)
    assert tr.peer == host
    for k in range(1, 40):                       # the host streams every 1 ms...
        datagram(k * 1e-3, host)
        datagram(k * 1e-3 + 5e-4, other)         # ... another port floods valid frames
    assert tr.peer == host and dev.counters.peer_kept == 39 and dev.counters.peer_changes == 0
    datagram(0.039 + PEER_HOLD * 0.99, other)    # the host quiet for less than the hold
    assert tr.peer == host
    datagram(0.039 + PEER_HOLD * 1.01, other)    # ... and for the hold: the peer moves
    assert tr.peer == other and dev.counters.peer_changes == 1


def test_source_limiter_budgets_and_bounded_memory():
    """hil.throttle.SourceLimiter: a stranger gets its burst and its rate, 10,000 rotating source
    addresses hold at most SOURCES + 1 buckets and share one budget beyond SOURCES, and an idle
    source is forgotten."""
    lim = throttle.SourceLimiter()
    # one stranger flooding 21-byte frames every 10 us for 1 s: its burst, then its rate
    ok = sum(lim.admit("a", 21, 10.0 + k * 1e-5) for k in range(100_000))
    assert ok * 21 <= throttle.STRANGER_BURST + throttle.STRANGER_RATE * 1.0 + 21
    assert ok * 21 >= throttle.STRANGER_RATE * 1.0
    # 10,000 addresses, each one datagram, within 0.1 s: bounded table, bounded total
    lim2 = throttle.SourceLimiter()
    ok = sum(lim2.admit(("127.0.0.1", 1024 + i), 100, i * 1e-5) for i in range(10_000))
    assert len(lim2) <= throttle.SOURCES + 1
    assert ok * 100 <= (throttle.SOURCES + 1) * throttle.STRANGER_BURST + throttle.STRANGER_RATE * 0.1
    assert lim2.dropped == 10_000 - ok and lim2.bytes_dropped == 100 * lim2.dropped
    # 2 s later the table's sources are idle: a new address gets a bucket of its own
    assert lim2.admit(("127.0.0.1", 9), 1000, 2.1) and len(lim2) <= throttle.SOURCES + 1
    # flooding: over the budget within FLOOD_MEMORY s (the shared bucket for sources beyond)
    assert lim.flooding("a", 11.0) and not lim.flooding("a", 11.0 + throttle.FLOOD_MEMORY)
    assert not lim2.flooding(("127.0.0.1", 9), 2.1) and not lim.flooding("b", 11.0)
    assert ("127.0.0.1", 9) in lim2._buckets


# --------------------------------------------------------------------------- fuzz

_HANDLED = (ms.MAVLINK_MSG_ID_LEG_SETPOINT, ms.MAVLINK_MSG_ID_COMMAND_LONG,
            ms.MAVLINK_MSG_ID_PARAM_REQUEST_LIST, ms.MAVLINK_MSG_ID_PARAM_REQUEST_READ,
            ms.MAVLINK_MSG_ID_PARAM_SET, ms.MAVLINK_MSG_ID_LOCKSTEP)
_HOSTILE = [0.0, -0.0, 1e-38, -1e-38, 1e38, -3e38, 1e300, -1e307, 1e308, 5e-324, 3.5, -2.0,
            1.0, 100.0, 1e6, 1e9]


def _frame(rng: random.Random, msgid: int, payload: bytes) -> bytes:
    """A MAVLink 2 frame with a valid CRC (CRC_EXTRA of the id), random sequence and ids."""
    cls = ms.mavlink_map[msgid]
    sysid, compid = rng.choice([(255, 190), (rng.randrange(256), rng.randrange(256))])
    head = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, rng.randrange(256), sysid, compid,
                       msgid & 0xFFFF, msgid >> 16)
    crc = crc16(bytes((cls.crc_extra,)), crc16(head[1:] + payload))
    return head + payload + struct.pack("<H", crc)


def _hostile_message(rng: random.Random, l0: np.ndarray, seq: int):
    """A handled message with hostile numbers (valid encoding), addressed to the device."""
    h = lambda: rng.choice(_HOSTILE)  # noqa: E731
    h32 = lambda: rng.choice([x for x in _HOSTILE if abs(x) < 3e38] + [math.nan, math.inf])  # noqa: E731
    kind = rng.randrange(5)
    if kind == 0:
        lengths = l0 + np.array([rng.choice([0.0, 1e-3, -2e-3, h()]) for _ in range(6)])
        return full_setpoint(seq, lengths, [h() for _ in range(6)], [h() for _ in range(6)],
                             [h() for _ in range(6)], flags=rng.randrange(16))
    if kind == 1:
        name = rng.choice(["CTRL_KP", "CTRL_KI", "CTRL_KD", "DRV_V_LIMIT", "DRV_I_LIMIT", "WDG_TIMEOUT",
                           "SP_COND_MAX", "SR_LEG_STATE", "SP_RATE_MAX", "NOPE"])
        return ms.MAVLink_param_set_message(1, 1, name.encode(), h32(),
                                            ms.MAV_PARAM_TYPE_REAL32)
    if kind == 2:
        return ms.MAVLink_command_long_message(1, 1, rng.choice([400, 20, 179, 511, 0, 65535]), 0,
                                               *[rng.choice([h32(), 1.0, 0.0]) for _ in range(7)])
    if kind == 3:
        return ms.MAVLink_lockstep_message(rng.getrandbits(64), rng.getrandbits(32))
    return ms.MAVLink_param_request_read_message(1, 1, b"", rng.randrange(-2, 40))


def fuzz_frames(seed: int, l0: np.ndarray, n_random: int = 6, n_hostile: int = 1500):
    """(frames, payload count): n_random random payloads (valid CRC, random length up to the
    message's size) of every message id of the dialect (common + ours), then n_hostile encoded
    hostile messages of the ids the device handles; shuffled, with arms sprinkled in."""
    rng = random.Random(seed)
    frames = []
    for msgid, cls in sorted(ms.mavlink_map.items()):
        for _ in range(n_random * (4 if msgid in _HANDLED else 1)):
            size = cls.unpacker.size
            payload = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, size)))
            frames.append(_frame(rng, msgid, payload))
    mav = host_mav()
    for k in range(n_hostile):
        frames.append(bytes(_hostile_message(rng, l0, k).pack(mav)))
        if k % 100 == 0:
            frames.append(bytes(arm().pack(mav)))
    rng.shuffle(frames)
    return frames


def test_fuzz_in_process(model, capsys):
    dev = Device(model)
    l0 = inverse_kinematics(model, model.home).lengths
    frames = fuzz_frames(11, l0)
    assert len(frames) > 2000
    replies = 0
    for i, f in enumerate(frames):
        replies += len(dev.feed(f))
        if i % 3 == 0:
            replies += len(dev.tick())
    replies += len(dev.flush())
    c, st = dev.counters, dev.rx.stats
    report = (f"fuzz in process: {len(frames)} frames, {sum(map(len, frames))} bytes, "
              f"{st.frames_ok} decoded, {st.rejected} dropped by framing, "
              f"{c.setpoints_refused} setpoints refused, {c.params_refused} params refused, "
              f"{c.commands_refused} commands refused, {c.lockstep_refused} lockstep refused, "
              f"{c.faults} end-stop faults, {c.numeric_faults} numeric faults, "
              f"{c.statustexts_rate_limited} STATUSTEXT cut, exits 0")
    with capsys.disabled():
        print("\n" + report)
    assert st.frames_ok + st.rejected >= len(frames) - 10
    assert c.handler_errors == 0                  # no handler raised (nothing hidden)
    assert c.setpoints_refused > 100 and c.params_refused > 100
    # no parameter left outside its bounds
    b = dev.param_ranges
    assert dev.gains.kp <= b.gain_max["kp"] and dev.gains.kd <= b.gain_max["kd"]
    assert dev.ctrl.axis.motor.voltage_limit <= 24.0 and dev.ctrl.axis.motor.current_limit <= 2.0
    assert b.watchdog_range[0] <= dev.watchdog <= b.watchdog_range[1]
    dev.receive(arm(0))
    still_serving(dev)


def test_fuzz_device_process_over_udp(model, capsys):
    """The same fuzz (fewer hostile messages) against `python -m hil.spawn SCENE --udp`: the
    process never exits; afterwards it answers a PARAM_REQUEST_READ; SIGINT stops it (0)."""
    l0 = inverse_kinematics(model, model.home).lengths
    frames = fuzz_frames(12, l0, n_random=4, n_hostile=800)
    proc = subprocess.Popen(device_command(SCENE, "udp", False), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    host = None
    try:
        host = _Udp(parse_udp(_first_line(proc, 60.0)))
        sent = 0
        for i in range(0, len(frames), 4):  # 4 frames per datagram
            host.send(b"".join(frames[i:i + 4]))
            sent += 1
            if sent % 10 == 0:
                time.sleep(0.003)  # pace below the socket buffer (no pass/fail on time)
        match = _has("PARAM_VALUE", lambda m: m.param_id == "CTRL_KP")
        ok = False
        for _ in range(20):
            host.send(bytes(read_kp().pack(host_mav())))
            if match(host.collect(Receiver(ms), match, limit=1.0)):
                ok = True
                break
        alive = proc.poll() is None
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    finally:
        if host is not None:
            host.s.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    assert alive and ok, "the device process stopped answering"
    assert proc.returncode == 0, err
    summary = [ln for ln in err.splitlines() if ln.startswith("device stopped")]
    with capsys.disabled():
        print(f"\nfuzz over UDP: {len(frames)} frames in {sent} datagrams, "
              f"{sum(map(len, frames))} bytes; exit status {proc.returncode}; {summary}")
    assert summary and "setpoints refused" in summary[0]
