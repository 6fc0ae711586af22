"""What ground stations expect of the device (in process, deterministic): sequence numbers,
COMMAND_INT, PARAM_SET types, chunked STATUSTEXT, signing errors counted once, HOME_POSITION,
ATTITUDE."""
from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.operating_mode import Mode  # noqa: E402
from hil.downlink import ned_attitude  # noqa: E402
from hil.framing import Receiver  # noqa: E402
from hil.protocol import param_encode_int, statustext_chunks  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
KEY = bytes(range(32))


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def host(key=None):
    mav = ms.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return mav


def command_long(cmd, *p):
    p = list(p) + [0.0] * (7 - len(p))
    return ms.MAVLink_command_long_message(1, 1, cmd, 0, *p)


def command_int(cmd, *p):
    p = list(p) + [0.0] * (4 - len(p))
    return ms.MAVLink_command_int_message(1, 1, ms.MAV_FRAME_LOCAL_NED, cmd, 0, 0, *p, 0, 0, 0.0)


def types(msgs):
    return [m.get_type() for m in msgs]


def test_every_frame_carries_the_next_sequence_number(model):
    dev = Device(model)
    rx = Receiver(ms, host())
    seqs = []
    for _ in range(1000):         # > 256 frames: wraps
        for m in dev.tick():
            seqs += [f.get_seq() for f in rx.feed(dev.pack(m))]
    assert len(seqs) > 256
    assert seqs == [k % 256 for k in range(len(seqs))]


def test_signed_frames_count_sequence_too(model):
    dev = Device(model, signing_key=KEY)
    frames = [dev.pack(m) for m in dev.tick() + dev.tick()]
    assert [f[4] for f in frames] == list(range(len(frames))) and all(f[2] & 1 for f in frames)


def test_command_int_is_handled_like_command_long(model):
    dev = Device(model)
    out = dev.receive(command_int(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    assert types(out)[0] == "COMMAND_ACK" and out[0].result == ms.MAV_RESULT_ACCEPTED and dev.armed
    assert out[0].target_system == 255 or out[0].command == ms.MAV_CMD_COMPONENT_ARM_DISARM
    out = dev.receive(command_int(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert out[0].result == ms.MAV_RESULT_ACCEPTED and dev.mode is Mode.HOMING
    out = dev.receive(command_int(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0))
    assert out[0].result == ms.MAV_RESULT_ACCEPTED and not dev.armed
    assert dev.receive(command_int(ms.MAV_CMD_DO_SET_HOME))[0].result == ms.MAV_RESULT_UNSUPPORTED
    other = ms.MAVLink_command_int_message(7, 1, 0, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0,
                                           1, 0, 0, 0, 0, 0, 0)
    assert dev.receive(other) == []          # not for us: no ack
    assert dev.counters.commands == 4
    # over the wire too
    rx = Receiver(ms, host())
    got = rx.feed(b"".join(dev.pack(m) for m in dev.feed(bytes(
        command_int(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1).pack(host())))))
    assert got[0].get_type() == "COMMAND_ACK" and got[0].result == ms.MAV_RESULT_ACCEPTED


def _set(dev, name, value, ptype, frame=True):
    msg = ms.MAVLink_param_set_message(1, 1, name.encode(), value, ptype)
    if frame:   # through the wire: the value's raw bytes
        return dev.feed(bytes(msg.pack(host())))
    return dev.receive(msg)


@pytest.mark.parametrize("frame", [True, False], ids=["wire", "in-process"])
def test_param_set_honours_the_type(model, frame):
    dev = Device(model)
    out = _set(dev, "SR_LEG_STATE", 250.0, ms.MAV_PARAM_TYPE_REAL32, frame)
    assert out[0].param_value == 250.0 and dev.rates["LEG_STATE"] == 250.0
    # INT32, bytewise: the int's bytes in the float field (not 200.0 cast to float)
    out = _set(dev, "SR_LEG_STATE", param_encode_int(200), ms.MAV_PARAM_TYPE_INT32, frame)
    assert types(out) == ["PARAM_VALUE"] and dev.rates["LEG_STATE"] == 200.0
    assert out[0].param_value == 200.0 and out[0].param_type == ms.MAV_PARAM_TYPE_REAL32
    out = _set(dev, "SR_LEG_STATE", param_encode_int(-5), ms.MAV_PARAM_TYPE_INT32, frame)
    assert types(out)[:2] == ["PARAM_VALUE", "STATUSTEXT"] and out[0].param_value == 200.0
    assert "-5 refused" in out[1].text
    out = _set(dev, "SR_DRIVE_STATUS", param_encode_int(20, ms.MAV_PARAM_TYPE_UINT8),
               ms.MAV_PARAM_TYPE_UINT8, frame)
    assert dev.rates["DRIVE_STATUS"] == 20.0
    # other types refused, with the unchanged value
    for t in (ms.MAV_PARAM_TYPE_REAL64, ms.MAV_PARAM_TYPE_INT64, ms.MAV_PARAM_TYPE_UINT64, 77):
        out = _set(dev, "SR_LEG_STATE", 300.0, t, frame)
        assert types(out) == ["PARAM_VALUE", "STATUSTEXT"] and out[0].param_value == 200.0
        assert "unsupported" in out[1].text and dev.rates["LEG_STATE"] == 200.0
    assert dev.counters.params_set == 3 and dev.counters.params_refused == 5


def test_param_encode_int_is_bytewise():
    assert struct.pack("<f", param_encode_int(200)) == struct.pack("<i", 200)
    assert struct.pack("<f", param_encode_int(-1)) == b"\xff\xff\xff\xff"


def _reassemble(msgs):
    assert len({m.id for m in msgs}) == 1
    assert [m.chunk_seq for m in msgs] == list(range(len(msgs)))
    # pymavlink decodes text as ASCII: take the raw bytes of the field from the frame
    raw = [bytes(m._text_raw).split(b"\0", 1)[0] for m in msgs]
    assert all(len(r) == 50 for r in raw[:-1]) or any(len(r) < 50 for r in raw)
    return b"".join(raw).decode("utf-8")


@pytest.mark.parametrize("text", ["é" * 40, "x" * 49 + "€" * 20, "a" * 50, "a" * 100, "a" * 120,
                                  "ß😀" * 30, "short"])
def test_statustext_chunks_on_character_boundaries(model, text):
    chunks = statustext_chunks(text)
    assert all(len(c) <= 50 for c in chunks)
    for c in chunks:
        c.decode("utf-8")                                  # every chunk decodes on its own
    assert b"".join(chunks).decode() == text
    if len(chunks) > 1:
        assert len(chunks[-1]) < 50                        # the last one ends with a NUL
    dev = Device(model)
    msgs = dev.statustext(ms.MAV_SEVERITY_INFO, text)
    if len(text.encode()) <= 50:
        assert len(msgs) == 1 and msgs[0].id == 0
    else:
        assert msgs[0].id != 0
    # through the wire and back
    rx = Receiver(ms, host())
    got = [m for f in msgs for m in rx.feed(dev.pack(f))]
    assert _reassemble(got) == text
    again = dev.statustext(ms.MAV_SEVERITY_INFO, "b" * 120)
    assert again[0].id != msgs[0].id


def test_signing_rejection_counted_once(model):
    dev = Device(model, signing_key=KEY)
    bad = [bytes(command_long(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1).pack(host())),
           bytes(command_long(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1).pack(host(bytes(32))))]
    for f in bad:
        assert dev.feed(f) == []
    assert dev.counters.signing_rejected == 2
    assert dev.link_errors == 2 and dev.sys_status().errors_comm == 2
    assert dev.drive_status().crc_errors == 2
    dev.feed(b"\xfd\x09" + bytes(20))    # a framing reject is counted too
    dev.flush()
    assert dev.link_errors == dev.rx.stats.rejected and dev.link_errors >= 3


def test_home_position_on_request_and_once_on_arm(model):
    dev = Device(model)
    for make in (command_long, command_int):
        out = dev.receive(make(ms.MAV_CMD_GET_HOME_POSITION))
        assert types(out) == ["COMMAND_ACK", "HOME_POSITION"]
        assert out[0].result == ms.MAV_RESULT_ACCEPTED
    out = dev.receive(command_long(ms.MAV_CMD_REQUEST_MESSAGE, ms.MAVLINK_MSG_ID_HOME_POSITION))
    assert types(out) == ["COMMAND_ACK", "HOME_POSITION"]
    hp = out[1]
    home = model.home
    # LOCAL_POSITION_NED's convention: (x, -y, -z); at start the platform is at home
    assert (hp.x, hp.y, hp.z) == pytest.approx((home[0], -home[1], -home[2]), abs=1e-6)
    lp = dev.local_position()
    assert (hp.x, hp.y, hp.z) == pytest.approx((lp.x, lp.y, lp.z), abs=1e-6)
    assert hp.q == pytest.approx(list(ned_attitude(np.asarray(home))), abs=1e-6)
    assert (hp.approach_x, hp.approach_y, hp.approach_z) == (hp.x, hp.y, hp.z)
    assert (hp.latitude, hp.longitude, hp.altitude) == (0, 0, 0)
    out = dev.receive(command_long(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    assert types(out).count("HOME_POSITION") == 1
    out = dev.receive(command_long(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1))   # already armed
    assert types(out).count("HOME_POSITION") == 0
    rx = Receiver(ms, host())
    assert types(rx.feed(dev.pack(hp))) == ["HOME_POSITION"]


def test_attitude_beside_the_quaternion(model):
    dev = Device(model)
    seen = {}
    for _ in range(100):
        for m in dev.tick():
            seen.setdefault(m.get_type(), []).append(m)
    assert len(seen["ATTITUDE"]) == len(seen["ATTITUDE_QUATERNION"]) == 5
    for a, q in zip(seen["ATTITUDE"], seen["ATTITUDE_QUATERNION"]):
        assert a.time_boot_ms == q.time_boot_ms
        # the quaternion of ZYX (yaw, pitch, roll) equals the one reported
        cr, sr = np.cos(a.roll / 2), np.sin(a.roll / 2)
        cp, sp = np.cos(a.pitch / 2), np.sin(a.pitch / 2)
        cy, sy = np.cos(a.yaw / 2), np.sin(a.yaw / 2)
        w = cr * cp * cy + sr * sp * sy
        x = sr * cp * cy - cr * sp * sy
        y = cr * sp * cy + sr * cp * sy
        z = cr * cp * sy - sr * sp * cy
        assert [w, x, y, z] == pytest.approx([q.q1, q.q2, q.q3, q.q4], abs=1e-6)
    # a rotated pose: roll = thx, pitch = -thy, yaw = -thz
    from hil.protocol import attitude_euler
    pose = np.array([0, 0, 0.1, 0.03, -0.02, 0.05])
    assert attitude_euler(pose) == pytest.approx((0.03, 0.02, -0.05))
    w, x, y, z = ned_attitude(pose)
    r, p, yw = attitude_euler(pose)
    cr, sr, cp, sp, cy, sy = np.cos(r / 2), np.sin(r / 2), np.cos(p / 2), np.sin(p / 2), \
        np.cos(yw / 2), np.sin(yw / 2)
    assert [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy] == pytest.approx(
        [w, x, y, z], abs=1e-12)
