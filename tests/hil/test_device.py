"""hil.device (the emulated micro-manipulator), hil.serve (its loop over a transport) and the
`stewart-sim device` command. All traffic stays in process, on loopback UDP or on a
pseudo-terminal; every wait is bounded."""
from __future__ import annotations

import os
import random
import select
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
import tty
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")
from pymavlink.dialects.v20 import common as pm_common  # noqa: E402

from controller.trajectory import leg_references, quintic  # noqa: E402
from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.downlink import ned_attitude, rotation  # noqa: E402
from hil.errors import LinkError  # noqa: E402
from hil.framing import Receiver  # noqa: E402
from hil.link import (  # noqa: E402
    Impairments,
    LinkEmulator,
    VirtualClock,
    queue_pair,
    udp_server,  # noqa: E402
)
from hil.serve import loopback_address, serve_in_thread  # noqa: E402
from stewart_fmu.dynamics import inverse_dynamics  # noqa: E402
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
KEY = bytes(range(32))


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def host_mav(module=ms, key: bytes | None = None):
    mav = module.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return mav


def arm(value: int = 1):
    return ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, value,
                                           0, 0, 0, 0, 0, 0)


def setpoint(seq: int, lengths, rates=None, force=None, flags: int | None = None):
    if flags is None:
        flags = ((ms.STEWART_SETPOINT_FLAG_RATE_VALID if rates is not None else 0)
                 | (ms.STEWART_SETPOINT_FLAG_FORCE_VALID if force is not None else 0))
    return ms.MAVLink_leg_setpoint_message(seq * 1000, seq, list(map(float, lengths)),
                                           list(map(float, rates if rates is not None else [0] * 6)),
                                           flags, list(map(float, force if force is not None else [0] * 6)))


def types(msgs) -> list[str]:
    return [m.get_type() for m in msgs]


def texts(msgs) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


# --------------------------------------------------------------------------- the core


def test_starts_at_home_holding_and_streams_telemetry(model):
    dev = Device(model)
    l0 = dev.plant.outputs.lengths.copy()
    seen: dict[str, int] = {}
    for _ in range(1000):
        for m in dev.tick():
            seen[m.get_type()] = seen.get(m.get_type(), 0) + 1
    # the drives hold the platform exactly at home (the master's bumpless start)
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-12
    assert np.max(np.abs(dev.plant.outputs.q - model.home)) < 1e-12
    assert seen == {"HEARTBEAT": 1, "SYS_STATUS": 1, "LEG_STATE": 100, "DRIVE_STATUS": 10,
                    "ATTITUDE_QUATERNION": 50, "ATTITUDE": 50, "LOCAL_POSITION_NED": 50}
    lp = dev.local_position()
    assert (lp.x, lp.y, lp.z) == pytest.approx((0.0, 0.0, -model.home[2]), abs=1e-12)  # NED: z down


def test_refuses_an_actuation_delay(model):
    """The device's ticks apply each sample's torque within the tick: a [controller] with
    delay = 1 (run's closed loop has it) is refused, naming the key, not ignored."""
    import dataclasses

    from controller.config import controller_config
    from stewart_fmu.errors import SceneError

    late = dataclasses.replace(controller_config(model), delay=1)
    with pytest.raises(SceneError) as info:
        Device(model, late)
    assert info.value.key == "controller.delay"


def test_attitude_quaternion_is_the_ned_rotation():
    """q(w, x, y, z) reported == the rotation T R T (T: half turn about x, z-up -> NED)."""
    rng = np.random.default_rng(3)
    T = np.diag([1.0, -1.0, -1.0])
    for _ in range(20):
        q = np.r_[0, 0, 0, rng.uniform(-1.2, 1.2, 3)]
        w, x, y, z = ned_attitude(q)
        Rq = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                       [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                       [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        assert np.allclose(Rq, T @ rotation(q) @ T, atol=1e-14)


def test_watchdog_fires_after_the_set_time_and_the_platform_stops(model):
    dev = Device(model, watchdog=0.05)
    assert types(dev.receive(arm()))[0] == "COMMAND_ACK" and dev.armed
    l0 = dev.plant.outputs.lengths.copy()
    rate = np.array([0.02, -0.02, 0.02, -0.02, 0.02, -0.02])  # m/s, legs moving
    for k in range(100):  # 0.1 s of a ramp, one setpoint per tick
        assert dev.receive(setpoint(k, l0 + rate * (k + 1) * dev.dt, rate)) == []
        dev.tick()
    last_setpoint_tick = dev.k - 1
    assert np.max(np.abs(dev.plant.outputs.rates)) > 0.01  # moving when the setpoints stop
    trip = None
    for _ in range(200):
        out = dev.tick()
        if texts(out):
            trip = dev.k - 1  # the tick that tripped
            assert "watchdog" in texts(out)[0] and "holding" in texts(out)[0]
            break
    assert trip is not None
    # the watchdog fires at the set time after the last setpoint, within one tick
    assert 0 <= (trip - last_setpoint_tick) * dev.dt - 0.05 < dev.dt + 1e-12
    assert dev.watchdog_state == ms.STEWART_WATCHDOG_TRIPPED and dev.counters.watchdog_trips == 1
    hold = dev.l_ref.copy()
    stop_ticks, again = None, []
    for n in range(300):
        again += texts(dev.tick())
        if stop_ticks is None and np.max(np.abs(dev.plant.outputs.rates)) < 1e-4:
            stop_ticks = n + 1
    # stated: leg rates below 0.1 mm/s within 50 ms of the trip, and held there
    assert stop_ticks is not None and stop_ticks * dev.dt <= 0.05, stop_ticks
    assert np.max(np.abs(dev.plant.outputs.rates)) < 1e-5
    assert np.max(np.abs(dev.plant.outputs.lengths - hold)) < 2e-4
    assert again == []  # the STATUSTEXT is sent once
    hb = dev.heartbeat()
    assert hb.system_status == ms.MAV_STATE_CRITICAL and dev.drive_status().watchdog == 2
    # the next valid setpoint resumes
    out = dev.receive(setpoint(1000, hold))
    assert texts(out) == ["watchdog: setpoints resumed"] and dev.watchdog_state == ms.STEWART_WATCHDOG_OK


@pytest.mark.parametrize("leg", range(6))
def test_refusals_number_the_legs_1_to_6(model, leg):
    """The leg a refusal names is counted from 1, as in every table and plot (l1..l6)."""
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    past = l0.copy()
    past[leg] = model.leg_max + 1e-4
    assert texts(dev.receive(setpoint(1, past)))[0].startswith(f"refused: leg {leg + 1} at ")
    for _ in range(101):  # past the refusal's repeat time (0.1 s)
        dev.tick()
    rates = np.zeros(6)
    rates[leg] = 1e3   # m/s: far beyond any drive
    assert texts(dev.receive(setpoint(2, l0, rates)))[0].startswith(f"refused: leg {leg + 1} rate ")


def test_out_of_range_setpoints_are_refused_and_never_applied(model):
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    bad = [
        (l0 + np.r_[model.leg_max - l0[0] + 1e-4, 0, 0, 0, 0, 0], "stroke"),   # past leg_max
        (l0 - np.r_[0, 0, 0, l0[3] - model.leg_min + 1e-4, 0, 0], "stroke"),   # below leg_min
        (np.r_[[model.leg_min] * 3, [model.leg_max] * 3], ""),                  # no pose / singular
        (np.r_[np.nan, l0[1:]], "non-finite"),
    ]
    for n, (lengths, why) in enumerate(bad):
        for _ in range(101):  # 0.1 s: the refusal STATUSTEXT is rate-limited to one per 0.1 s
            dev.tick()
        out = dev.receive(setpoint(n, lengths))
        assert len(texts(out)) == 1 and texts(out)[0].startswith("refused:"), texts(out)
        assert why in texts(out)[0]
        assert dev.counters.setpoints_refused == n + 1
        assert np.array_equal(dev.l_ref, l0)  # never applied
    out = dev.receive(setpoint(9, np.r_[np.inf, l0[1:]], [0] * 6))
    assert texts(out) == [] and dev.counters.setpoints_refused == 5  # counted, text rate-limited
    assert dev.counters.statustexts_suppressed == 1
    rates = [0, 0, 0, 0, 0, np.nan]
    dev.receive(setpoint(10, l0, rates))
    assert dev.counters.setpoints_refused == 6 and dev.drive_status().setpoints_refused == 6
    for _ in range(200):
        dev.tick()
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-12  # nothing moved
    # a valid setpoint is accepted; while disarmed, valid setpoints are ignored, said once
    assert dev.receive(setpoint(11, l0 + 1e-4)) == [] and dev.counters.setpoints_accepted == 1
    dev.receive(arm(0))
    assert texts(dev.receive(setpoint(12, l0 + 2e-4))) == ["setpoints ignored: disarmed (arm first)"]
    assert dev.receive(setpoint(13, l0 + 2e-4)) == [] and dev.counters.setpoints_ignored == 2


def test_commands_and_parameters(model):
    dev = Device(model, watchdog=5.0)  # one setpoint, then holding it for longer than 0.2 s
    ack = dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0,
                                                      0, 0, 0, 0, 0, 0, 0))[0]
    assert ack.result == ms.MAV_RESULT_TEMPORARILY_REJECTED  # home needs arming
    assert dev.receive(arm())[0].result == ms.MAV_RESULT_ACCEPTED
    ack = dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_DO_SET_HOME, 0, 1, 0, 0, 0,
                                                      0, 0, 0))[0]
    assert ack.result == ms.MAV_RESULT_UNSUPPORTED
    assert dev.receive(ms.MAVLink_command_long_message(7, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0)) == []  # not for us
    # move away, then home
    l0 = dev.plant.outputs.lengths.copy()
    away = l0 + np.array([2e-3, -1e-3, 1e-3, 0, -2e-3, 1e-3])
    dev.receive(setpoint(0, away))
    for _ in range(300):
        dev.tick()
    assert np.max(np.abs(dev.plant.outputs.lengths - away)) < 1e-5
    ack = dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0,
                                                      0, 0, 0, 0, 0, 0, 0))[0]
    assert ack.result == ms.MAV_RESULT_ACCEPTED
    for _ in range(600):
        dev.tick()
    assert np.max(np.abs(dev.plant.outputs.lengths - l0)) < 1e-5
    assert np.max(np.abs(dev.plant.outputs.q - model.home)) < 1e-4
    # parameters
    values = dev.receive(ms.MAVLink_param_request_list_message(1, 1))
    names = [v.param_id for v in values]
    assert {"CTRL_KP", "CTRL_KI", "CTRL_KD", "DRV_V_LIMIT", "DRV_I_LIMIT", "WDG_TIMEOUT"} <= set(names)
    assert [v.param_index for v in values] == list(range(len(names)))
    assert {v.param_count for v in values} == {len(names)}
    kp = dev.gains.kp
    pv = dev.receive(ms.MAVLink_param_set_message(1, 1, b"CTRL_KP", kp / 2, ms.MAV_PARAM_TYPE_REAL32))
    assert types(pv) == ["PARAM_VALUE"] and pv[0].param_value == kp / 2 == dev.gains.kp
    out = dev.receive(ms.MAVLink_param_set_message(1, 1, b"DRV_V_LIMIT", -1.0, ms.MAV_PARAM_TYPE_REAL32))
    assert types(out) == ["PARAM_VALUE", "STATUSTEXT"] and out[0].param_value == 24.0
    assert dev.ctrl.axis.motor.voltage_limit == 24.0 and dev.counters.params_refused == 1
    dev.receive(ms.MAVLink_param_set_message(1, 1, b"DRV_V_LIMIT", 12.0, ms.MAV_PARAM_TYPE_REAL32))
    assert dev.ctrl.axis.motor.voltage_limit == dev.motors.axis.motor.voltage_limit == 12.0
    dev.receive(ms.MAVLink_param_set_message(1, 1, b"WDG_TIMEOUT", 0.5, ms.MAV_PARAM_TYPE_REAL32))
    assert dev.watchdog == 0.5
    read = dev.receive(ms.MAVLink_param_request_read_message(1, 1, b"", names.index("CTRL_KD")))
    assert read[0].param_id == "CTRL_KD"
    read = dev.receive(ms.MAVLink_param_request_read_message(1, 1, b"DRV_I_LIMIT", -1))
    assert read[0].param_value == 2.0
    assert texts(dev.receive(ms.MAVLink_param_request_read_message(1, 1, b"NOPE", -1))) == ["no parameter NOPE"]


# --------------------------------------------------------------------------- bad bytes, signing


def test_garbage_truncated_and_bitflipped_frames_leave_the_device_running(model):
    dev = Device(model)
    host = host_mav()
    rng = random.Random(7)
    good = bytes(ms.MAVLink_param_request_read_message(1, 1, b"CTRL_KP", -1).pack(host))
    answered = 0
    for i in range(300):
        kind = i % 4
        if kind == 0:
            chunk = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300)))
        elif kind == 1:  # truncated frame
            chunk = good[:rng.randint(1, len(good) - 1)]
        elif kind == 2:  # bit-flipped frame
            b = bytearray(good)
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
            chunk = bytes(b)
        else:
            chunk = b""
        out = dev.feed(chunk + good)  # an intact frame after every bad chunk
        answered += types(out).count("PARAM_VALUE")
        dev.tick()
    answered += types(dev.flush()).count("PARAM_VALUE")
    st = dev.rx.stats
    assert answered >= 297, answered  # every intact frame is recovered (a flip may hit STX/len...)
    assert st.crc_errors > 0 and st.rejected > 50 and dev.link_errors == st.rejected
    assert dev.counters.ticks == 300 and dev.drive_status().crc_errors == st.crc_errors
    assert dev.sys_status().errors_comm == min(st.rejected, 65535)


def test_signing_rejects_unsigned_and_wrongly_signed_frames(model):
    dev = Device(model, signing_key=KEY)
    unsigned = bytes(arm().pack(host_mav()))
    wrong = bytes(arm().pack(host_mav(key=bytes(32))))
    assert dev.feed(unsigned) == [] and dev.feed(wrong) == []
    assert dev.counters.signing_rejected == 2 and not dev.armed
    assert dev.drive_status().crc_errors == 2
    host = host_mav(key=KEY)
    out = dev.feed(bytes(arm().pack(host)))
    assert types(out)[0] == "COMMAND_ACK" and dev.armed
    # what the device sends is signed with the key: the host verifies it
    frame = dev.pack(out[0])
    assert frame[2] & 0x01  # incompat flag: signed
    rx = Receiver(ms, host)
    got = rx.feed(frame)
    assert types(got) == ["COMMAND_ACK"] and got[0]._signed
    rx_nokey = Receiver(ms, host_mav(key=bytes(32)))
    assert rx_nokey.feed(frame) == [] and rx_nokey.stats.decode_errors == 1


# --------------------------------------------------------------------------- lockstep


def quintic_references(model, duration=0.25):
    goal = model.home + np.array([0.002, -0.0015, 0.003, 0.03, -0.02, 0.025])
    traj = quintic(model.home, goal, rate=1000.0, duration=duration)
    refs = leg_references(model, traj)
    force = inverse_dynamics(model, traj.q, traj.qd, traj.qdd)
    return refs, force


def run_direct(model, refs, force) -> list:
    dev = Device(model, lockstep=True)
    dev.receive(arm())
    states = []
    for k in range(len(refs.t)):
        assert dev.receive(setpoint(k, refs.l[k], refs.ldot[k], force[k])) == []
        out = dev.receive(ms.MAVLink_lockstep_message(0, k))
        assert types(out)[-2:] == ["LEG_STATE", "LOCKSTEP"] and out[-1].step == k
        states += [m for m in out if m.get_type() == "LEG_STATE"]
    return states, dev


def test_lockstep_over_the_link_equals_the_direct_run(model):
    refs, force = quintic_references(model)
    direct, dev_direct = run_direct(model, refs, force)
    # the same, through encode -> queue transport -> link emulator (latency, jitter, on a
    # virtual clock) -> robust receiver -> decode, with the device's serve loop in a thread
    dev = Device(model, lockstep=True)
    host_end, emu_a = queue_pair()
    emu_b, dev_end = queue_pair()
    clock = VirtualClock()
    emu = LinkEmulator(emu_a, emu_b, Impairments(baud=921600, latency=0.002, jitter=0.001),
                       clock=clock, seed=1)
    thread, stop, result = serve_in_thread(dev, dev_end, realtime=False, poll=0.01)
    host, rx = host_mav(), Receiver(ms)
    received: list = []
    deadline = time.monotonic() + 60

    def exchange(msgs, until) -> list:
        for m in msgs:
            host_end.send(bytes(m.pack(host)))
        got: list = []
        while not until(got):
            assert time.monotonic() < deadline, "lockstep exchange timed out"
            emu.pump()
            while data := host_end.recv(0.0):
                got += rx.feed(data)
            if until(got):
                break
            nxt = emu.next_event()
            if nxt is not None and nxt > clock.now():
                clock.advance(nxt - clock.now())
            elif nxt is None:
                time.sleep(0.0001)  # the device thread is working
        return got

    try:
        got = exchange([arm()], lambda g: "COMMAND_ACK" in types(g))
        for k in range(len(refs.t)):
            got = exchange([setpoint(k, refs.l[k], refs.ldot[k], force[k]),
                            ms.MAVLink_lockstep_message(0, k)],
                           lambda g: any(m.get_type() == "LOCKSTEP" for m in g))
            assert got[-1].step == k
            received += [m for m in got if m.get_type() == "LEG_STATE"]
    finally:
        stop.set()
        thread.join(5)
    assert not thread.is_alive() and result
    assert len(received) == len(direct) == len(refs.t)
    for a, b in zip(direct, received):
        assert (a.time_usec, a.step) == (b.time_usec, b.step)
        for name in ("length", "rate", "force"):
            # bitwise: the doubles of the direct run == those decoded from the link
            assert struct.pack("<6d", *getattr(a, name)) == struct.pack("<6d", *getattr(b, name))
    assert np.array_equal(dev.plant.get_state().y, dev_direct.plant.get_state().y)
    # the move happened: the platform tracked the quintic to within 50 um
    assert np.max(np.abs(np.array([m.length for m in received]) - refs.l)) < 5e-5
    assert emu.ab.stats.packets_in > 2 * len(refs.t) and dev.counters.lockstep_refused == 0


def test_lockstep_step_numbers(model):
    dev = Device(model, lockstep=True)
    assert texts(dev.receive(ms.MAVLink_lockstep_message(0, 5))) == ["LOCKSTEP 5 refused: expected 0"]
    first = dev.receive(ms.MAVLink_lockstep_message(0, 0))
    assert dev.k == 1 and first[-1].time_usec == 1000
    again = dev.receive(ms.MAVLink_lockstep_message(0, 0))  # a resend: answered, no tick
    assert dev.k == 1 and again == first and dev.counters.lockstep_repeated == 1
    rt = Device(model)
    assert texts(rt.receive(ms.MAVLink_lockstep_message(0, 0))) == ["LOCKSTEP ignored: real-time mode"]
    assert rt.k == 0


# --------------------------------------------------------------------------- real time over UDP


def test_common_only_client_over_udp_sees_heartbeat_attitude_and_parameters(model):
    dev = Device(model, telemetry={"LEG_STATE": 50.0})
    server = udp_server("127.0.0.1", 0)
    thread, stop, result = serve_in_thread(dev, server)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.connect(server.address)
    client.setblocking(False)
    gcs = pm_common.MAVLink(None, 255, 190)  # knows only common.xml
    gcs.robust_parsing = True
    seen: dict[str, list] = {}
    try:
        client.send(bytes(gcs.heartbeat_encode(pm_common.MAV_TYPE_GCS, pm_common.MAV_AUTOPILOT_INVALID,
                                               0, 0, 0).pack(gcs)))
        client.send(bytes(gcs.param_request_list_encode(1, 1).pack(gcs)))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            if select.select([client], [], [], 0.05)[0]:
                for m in gcs.parse_buffer(client.recv(65536)) or []:
                    seen.setdefault(m.get_type(), []).append(m)
            if ({"HEARTBEAT", "ATTITUDE_QUATERNION", "UNKNOWN_44001"} <= set(seen)
                    and len(seen.get("PARAM_VALUE", [])) == len(dev.params)):
                break
    finally:
        stop.set()
        thread.join(5)
        server.close()
        client.close()
    assert not thread.is_alive()
    hb = seen["HEARTBEAT"][0]
    assert (hb.type, hb.autopilot, hb.get_srcSystem()) == (pm_common.MAV_TYPE_GENERIC,
                                                           pm_common.MAV_AUTOPILOT_GENERIC, 1)
    aq = seen["ATTITUDE_QUATERNION"][-1]
    assert (aq.q1, aq.q2, aq.q3, aq.q4) == pytest.approx((1.0, 0.0, 0.0, 0.0), abs=1e-6)
    params = {p.param_id: p.param_value for p in seen["PARAM_VALUE"]}
    assert params["CTRL_KP"] == pytest.approx(dev.gains.kp, rel=1e-6)
    assert params["WDG_TIMEOUT"] == pytest.approx(0.2)
    assert "UNKNOWN_44001" in seen  # our LEG_STATE: unknown to it (a client must drop these)
    st = result[0]
    assert st.ticks > 0 and st.messages_in == 2


def test_udp_addresses_are_loopback_only():
    assert loopback_address("127.0.0.1:14550") == ("127.0.0.1", 14550)
    assert loopback_address("localhost:0") == ("127.0.0.1", 0)
    for bad in ("0.0.0.0:14550", "192.168.1.2:14550", "example.com:1", "127.0.0.1", "127.0.0.1:x",
                "127.0.0.1:70000"):
        with pytest.raises(LinkError):
            loopback_address(bad)


# --------------------------------------------------------------------------- the command


def test_cli_refuses_non_loopback(capsys):
    from stewart_sim.cli import main

    assert main(["device", str(SCENE), "--udp", "10.1.2.3:14550"]) == 2
    assert "loopback" in capsys.readouterr().err


def _stewart_sim() -> str:
    exe = shutil.which("stewart-sim", path=str(Path(sys.executable).parent))
    assert exe, f"stewart-sim is not installed next to {sys.executable}"
    return exe


def test_cli_device_pty_answers_and_stops_on_sigint():
    proc = subprocess.Popen([_stewart_sim(), "device", str(SCENE), "--pty", "--watchdog", "0.5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    fd = None
    try:
        assert select.select([proc.stdout], [], [], 60)[0], "no pty path printed"
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), path
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd)
        gcs = pm_common.MAVLink(None, 255, 190)
        os.write(fd, bytes(gcs.heartbeat_encode(pm_common.MAV_TYPE_GCS, pm_common.MAV_AUTOPILOT_INVALID,
                                                0, 0, 0).pack(gcs)))
        os.write(fd, bytes(gcs.param_request_read_encode(1, 1, b"WDG_TIMEOUT", -1).pack(gcs)))
        rx = Receiver(pm_common)
        seen: dict[str, object] = {}
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not {"HEARTBEAT", "PARAM_VALUE"} <= set(seen):
            if select.select([fd], [], [], 0.1)[0]:
                for m in rx.feed(os.read(fd, 65536)):
                    seen[m.get_type()] = m
        assert {"HEARTBEAT", "PARAM_VALUE"} <= set(seen)
        assert seen["PARAM_VALUE"].param_value == pytest.approx(0.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
        assert proc.returncode == 0, err
        assert "device stopped" in err
    finally:
        if fd is not None:
            os.close(fd)
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_lockstep_step_without_its_setpoint_is_refused(model):
    """Armed in lockstep, LOCKSTEP(k) runs only after setpoint k: a lost setpoint is never
    replaced by the previous one (the step is refused, counted and said, and no time passes);
    once setpoint k arrives the same LOCKSTEP(k) runs."""
    dev = Device(model, lockstep=True)
    dev.receive(arm())
    home = inverse_kinematics(model, model.home).lengths
    dev.receive(setpoint(0, home))
    assert "LEG_STATE" in types(dev.receive(ms.MAVLink_lockstep_message(0, 0)))
    k_before, refused = dev.k, dev.counters.lockstep_refused
    out = dev.receive(ms.MAVLink_lockstep_message(1000, 1))          # setpoint 1 lost
    assert dev.k == k_before and dev.counters.lockstep_refused == refused + 1
    assert any("setpoint 1 missing" in t for t in texts(out))
    dev.receive(setpoint(1, home))
    assert "LEG_STATE" in types(dev.receive(ms.MAVLink_lockstep_message(1000, 1)))
    assert dev.k == k_before + 1
