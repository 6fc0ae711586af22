"""POSE_SETPOINT (hil.pose_setpoint, hil.handlers.on_pose_setpoint): a pose in a frame of the
scene's [frames] drives the device as the LEG_SETPOINT of its leg lengths does, through the same
checks. Messages go through the host's own encoding (hil.client.Client -> in-process queue ->
Device.feed), through pymavlink's mavutil over loopback UDP, and signed as LEG_SETPOINT is."""
from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from controller.trajectory import quintic  # noqa: E402
from hil import dialect  # noqa: E402
from hil import mavlink_stewart as ms  # noqa: E402
from hil.client import Client  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.input_bounds import pose_position_max, pose_rate_max  # noqa: E402
from hil.link import queue_pair, udp_server  # noqa: E402
from hil.pose_setpoint import FRAMES  # noqa: E402
from hil.serve import serve_in_thread  # noqa: E402
from stewart_fmu.dynamics import leg_state  # noqa: E402
from stewart_fmu.errors import StewartError  # noqa: E402
from stewart_fmu.frames import (frame_change, from_platform, motion_from_platform,  # noqa: E402
                                motion_to_platform, to_platform)
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.reach_params import FRAME_NAMES  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from tests.hil.test_device_reach import CROSSED, YAWED  # noqa: E402
from tests.app.test_workspace import Reference, tomllib_load  # noqa: E402  (numpy, independent)

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
KEY = bytes(range(32))
# every frame moved and turned off C and N, so no conversion is a plain copy
FRAMES_TABLE = ("\n[frames]\npivot = [0.004, -0.003, 0.021]\n"
                "user = [0.013, -0.021, 0.052, 0.02, -0.015, 0.7]\n"
                "tool = [0.006, 0.008, 0.035, 0.12, -0.07, 0.4]\n")
GOAL = np.array([0.002, -0.0015, 0.003, 0.03, -0.02, 0.025])   # off home, inside every limit
MOVE, STEPS = 150, 500              # a 0.15 s quintic at 1 kHz, then its end held 0.35 s


def scene(tmp_path: Path, extra: str = ""):
    path = tmp_path / "micro_frames.toml"
    path.write_text(MICRO.read_text() + FRAMES_TABLE + extra)
    return load_scene(path)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return scene(tmp_path_factory.mktemp("pose"))


def arm():
    return ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                           0, 0, 0, 0, 0, 0)


def leg_setpoint(k: int, lengths):
    return ms.MAVLink_leg_setpoint_message(k * 1000, k, [float(v) for v in lengths], [0.0] * 6, 0)


def texts(msgs) -> list[str]:
    """The texts said: the chunks of one STATUSTEXT id (hil.statustext) joined."""
    said: dict[int, str] = {}
    for m in msgs:
        if m.get_type() == "STATUSTEXT":
            said[m.id] = said.get(m.id, "") + m.text
    return list(said.values())


class Wire:
    """A device fed in process through the host's own encoding: Client -> queue -> Device.feed."""

    def __init__(self, model, **kw):
        self.dev = Device(model, **kw)
        host_end, self.dev_end = queue_pair()
        self.client = Client(host_end)

    def send(self, *msgs) -> list:
        self.client.send_together(*msgs)
        out: list = []
        while data := self.dev_end.recv(0.0):
            out += self.dev.feed(data)
        return out


def lockstep(model, setpoints) -> tuple[list, Device]:
    """Arm, then per step k the setpoint setpoints(k) and LOCKSTEP(k) in one send; the
    LEG_STATEs and the device."""
    w = Wire(model, lockstep=True)
    w.send(arm())
    states = []
    for k in range(STEPS):
        out = w.send(setpoints(w.client, k), ms.MAVLink_lockstep_message(0, k))
        assert [m.get_type() for m in out][-2:] == ["LEG_STATE", "LOCKSTEP"], texts(out)
        states += [m for m in out if m.get_type() == "LEG_STATE"]
    assert w.dev.counters.setpoints_refused == 0 and w.dev.counters.setpoints_accepted == STEPS
    return states, w.dev


def bits(states, name: str) -> list[bytes]:
    return [struct.pack("<6d", *getattr(s, name)) for s in states]


def rotation(th) -> np.ndarray:
    """Rz Ry Rx in numpy (independent of the core's)."""
    cx, cy, cz = np.cos(th)
    sx, sy, sz = np.sin(th)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


# --------------------------------------------------------------------------- the same lengths


def test_the_frame_codes_are_the_frames_names_and_hold_is_leg_setpoints_bit():
    assert [FRAMES[getattr(ms, f"STEWART_FRAME_{n.upper()}")] for n in FRAME_NAMES] == \
        list(FRAME_NAMES)
    assert ms.STEWART_POSE_SETPOINT_FLAG_HOLD == ms.STEWART_SETPOINT_FLAG_HOLD   # the XML says so


@pytest.mark.parametrize("frame", ["user", "tool", "pivot", "platform"])
def test_a_pose_in_a_frame_drives_the_legs_as_its_leg_setpoint(model, frame):
    """Lockstep, 150 steps of a quintic written in `frame` and 350 at its end: bit for bit the
    run of the LEG_SETPOINTs of the lengths of its platform poses (the core's leg_state: what a
    host converting itself sends); within the frames' round trip of the run of the original
    platform poses; and at the end the frame's pose of the plant, converted in numpy, is the
    one asked."""
    traj = quintic(model.home, model.home + GOAL, rate=1000.0, duration=(MOVE - 1) / 1000.0)
    q = np.vstack([traj.q[:MOVE], np.repeat(traj.q[MOVE - 1:MOVE], STEPS - MOVE, axis=0)])
    f = from_platform(model, q, frame)
    posed, dev = lockstep(model, lambda c, k: c.pose_setpoint_message(k, k / 1000.0, f[k], frame))
    converted = np.array([leg_state(model, p, np.zeros(6))[0]
                          for p in to_platform(model, f, frame)])
    legs, dev_legs = lockstep(model, lambda c, k: leg_setpoint(k, converted[k]))
    for name in ("length", "rate", "force"):
        assert bits(posed, name) == bits(legs, name), name
    assert np.array_equal(dev.plant.get_state().y, dev_legs.plant.get_state().y)
    # the frames' round trip (from_platform then to_platform) moves a length by a few ulp at
    # most; the closed loop carries that on, no more
    direct = np.array([leg_state(model, p, np.zeros(6))[0] for p in q])
    ulp = np.spacing(np.max(direct))
    assert np.max(np.abs(converted - direct)) <= 4 * ulp
    original, _ = lockstep(model, lambda c, k: leg_setpoint(k, direct[k]))
    moved = np.array([s.length for s in posed]) - np.array([s.length for s in original])
    assert np.max(np.abs(moved)) <= 16 * ulp, np.max(np.abs(moved)) / ulp
    # numpy: the commanded platform pose written in the frame is the pose sent (to rounding),
    # and where the plant put the frame is that pose to the servo's tracking error
    asked = f[-1, :3], rotation(f[-1, 3:])
    sent = in_frame(model, frame, q[-1])
    plant = in_frame(model, frame, dev.plant.outputs.q)
    assert np.max(np.abs(sent[0] - asked[0])) < 1e-15
    assert np.max(np.abs(sent[1] - asked[1])) < 1e-14
    off = np.max(np.abs(plant[0] - asked[0])), np.max(np.abs(plant[1] - asked[1]))
    print(f"\n[pose {frame}] lengths round trip {np.max(np.abs(converted - direct)) / ulp:.0f} "
          f"ulp, LEG_STATE {np.max(np.abs(moved)) / ulp:.0f} ulp; the frame's position off "
          f"{off[0]:.3g} m, rotation {off[1]:.3g} after 0.35 s held")
    assert off[0] < 1e-5 and off[1] < 1e-4
    assert np.max(np.abs(dev.plant.outputs.q - q[0])) > 1e-3        # and it moved


def in_frame(model, frame: str, p) -> tuple[np.ndarray, np.ndarray]:
    """numpy: (position, rotation) of `frame` at platform pose p, in its fixed frame (N, or
    the user frame)."""
    fr = model.frames
    t = {"platform": np.zeros(6), "pivot": np.r_[fr.pivot, 0, 0, 0]}.get(frame, fr.tool_pose)
    w = np.asarray(fr.user, dtype=float) if frame == "user" else np.zeros(6)
    Rw, R = rotation(w[3:]), rotation(p[3:])
    return Rw.T @ (p[:3] + R @ t[:3] - w[:3]), Rw.T @ R @ rotation(t[3:])


# --------------------------------------------------------------------------- with rates


def held_move(model):
    """The quintic of test_a_pose_in_a_frame_drives_the_legs_as_its_leg_setpoint with its exact
    rates: (q, qd) over STEPS steps, the end held at rest."""
    traj = quintic(model.home, model.home + GOAL, rate=1000.0, duration=(MOVE - 1) / 1000.0)
    rest = STEPS - MOVE
    q = np.vstack([traj.q[:MOVE], np.repeat(traj.q[MOVE - 1:MOVE], rest, axis=0)])
    qd = np.vstack([traj.qd[:MOVE], np.zeros((rest, 6))])
    return q, qd


def leg_rate_setpoint(k: int, lengths, rates):
    return ms.MAVLink_leg_setpoint_message(k * 1000, k, [float(v) for v in lengths],
                                           [float(v) for v in rates],
                                           ms.STEWART_SETPOINT_FLAG_RATE_VALID)


def tracking(model, states, q) -> float:
    """m, the largest |measured - commanded| leg length over the run, each LEG_STATE against
    the leg lengths of the platform pose at its own time (numpy inverse kinematics)."""
    worst = 0.0
    for s in states:
        k = min(int(round(s.time_usec / 1000)), len(q) - 1)
        ref = inverse_kinematics(model, q[k], with_cond=False).lengths
        worst = max(worst, float(np.max(np.abs(np.array(s.length) - ref))))
    return worst


@pytest.mark.parametrize("frame", ["user", "tool"])
def test_a_pose_with_rates_drives_the_legs_as_its_leg_setpoint_with_rates(model, frame):
    """Lockstep: the quintic written in `frame` with its exact rates (motion_from_platform),
    sent as POSE_SETPOINTs with RATE_VALID, moves the plant bit for bit as the LEG_SETPOINTs
    of the lengths and rates of its platform motion (motion_to_platform, the core's leg_state:
    what a host converting itself sends), and within the frames' round trip as those of the
    original platform motion; with the rates it tracks closer than the same poses without."""
    q, qd = held_move(model)
    f, fd, _ = motion_from_platform(model, q, qd, None, frame)
    posed, dev = lockstep(model, lambda c, k: c.pose_setpoint_message(k, k / 1000.0, f[k],
                                                                      frame, rate=fd[k]))
    back_q, back_qd, _ = motion_to_platform(model, f, fd, None, frame)
    converted = [leg_state(model, back_q[k], back_qd[k])[:2] for k in range(STEPS)]
    legs, dev_legs = lockstep(model, lambda c, k: leg_rate_setpoint(k, *converted[k]))
    for name in ("length", "rate", "force"):
        assert bits(posed, name) == bits(legs, name), name
    assert np.array_equal(dev.plant.get_state().y, dev_legs.plant.get_state().y)
    # the frames' round trip of the motion moves a leg rate by a few ulp of the largest
    direct = [leg_state(model, q[k], qd[k])[:2] for k in range(STEPS)]
    dl = np.array([c[0] - d[0] for c, d in zip(converted, direct)])
    dr = np.array([c[1] - d[1] for c, d in zip(converted, direct)])
    l_ulp = np.spacing(max(np.max(np.abs(d[0])) for d in direct))
    r_ulp = np.spacing(max(np.max(np.abs(d[1])) for d in direct))
    assert np.max(np.abs(dl)) <= 4 * l_ulp and np.max(np.abs(dr)) <= 16 * r_ulp
    original, _ = lockstep(model, lambda c, k: leg_rate_setpoint(k, *direct[k]))
    moved = np.array([s.length for s in posed]) - np.array([s.length for s in original])
    assert np.max(np.abs(moved)) <= 16 * l_ulp, np.max(np.abs(moved)) / l_ulp
    # the same poses without their rates: the legs follow with a zero rate reference
    plain, _ = lockstep(model, lambda c, k: c.pose_setpoint_message(k, k / 1000.0, f[k], frame))
    with_rates, without = tracking(model, posed, q), tracking(model, plain, q)
    print(f"\n[pose+rate {frame}] lengths {np.max(np.abs(dl)) / l_ulp:.0f} ulp, rates "
          f"{np.max(np.abs(dr)) / r_ulp:.0f} ulp off the platform motion's, LEG_STATE "
          f"{np.max(np.abs(moved)) / l_ulp:.0f} ulp; tracking error {with_rates:.3g} m with "
          f"rates, {without:.3g} m without")
    # no force feed-forward, so the legs' inertia still lags: the rate reference takes about a
    # quarter off the peak error (0.290 mm against 0.385 mm in either frame, ratio 0.755)
    assert with_rates < 0.8 * without
    assert np.max(np.abs(dev.plant.outputs.q - q[0])) > 1e-3        # and it moved


def test_a_pose_without_rates_is_todays_frame_and_setpoint(model):
    """A sender that leaves the rate out (an older one, or rate=None) sends the frame of the
    message without the field (MAVLink 2 trims the payload's trailing zeros: the extension's
    zeros, here also flags 0), packed independently below, and the device makes the
    LEG_SETPOINT it made before: the lengths of the platform pose, no rate, flags 0."""
    from hil.pose_setpoint import leg_setpoint as to_legs
    f = from_platform(model, np.asarray(model.home) + GOAL, "user")
    msg = Client(None).pose_setpoint_message(3, 0.003, f, "user")
    mav = host_mav(None)
    frame = bytes(msg.pack(mav))
    # the payload before the extension: time_usec, x..thz, sequence, frame, flags (wire order)
    today = struct.pack("<Q6dIBB", 3000, *map(float, f), 3, ms.STEWART_FRAME_USER, 0)
    today = today.rstrip(b"\0")
    assert frame[1] == len(today) and frame[10:-2] == today
    why, leg, _ = to_legs(mav.decode(bytearray(frame)), model, 3.0, 100.0)
    assert why is None and leg.flags == 0 and list(leg.rate) == [0.0] * 6
    lengths = leg_state(model, to_platform(model, f, "user"), np.zeros(6))[0]
    assert struct.pack("<6d", *leg.length) == struct.pack("<6d", *lengths)


def test_rates_are_refused_with_their_reason(model):
    """Non-finite rates, rates past pose_rate_max, and finite ones within it whose legs' rates
    pass the capability's setpoint_rate (the LEG_SETPOINT's own check): one STATUSTEXT each,
    nothing moves."""
    dev0 = Device(model)
    leg_rate = dev0.capability.setpoint_rate
    cond_max = dev0.settings.cond_max
    home = from_platform(model, model.home, "tool")
    move, turn = pose_rate_max(leg_rate, cond_max, model.characteristic_length,
                               frame_change(model, "tool"), home[4])
    c = Client(None)

    def rated(i, v):
        r = np.zeros(6)
        r[i] = v
        return c.pose_setpoint_message(1, 0.001, home, "tool", rate=r)
    cases = [(rated(0, np.nan), "non-finite rate dx"),
             (rated(5, np.inf), "non-finite rate dthz"),
             (rated(3, 1e300), "rate dthx 1e+300 rad/s in frame tool, bound "),
             (rated(2, -2 * move), f"rate dz {-2 * move:.4g} m/s in frame tool, bound "
                                   f"{move:.4g} m/s"),
             (rated(4, 1.5 * turn), f"rate dthy {1.5 * turn:.4g} rad/s"),
             (rated(1, 10 * leg_rate), legs_too_fast(model, home, 10 * leg_rate, leg_rate))]
    assert 10 * leg_rate < move          # the last: within the pose's bound, not the legs'
    # a tool pose whose platform pose is at gimbal lock: no Euler rates of the platform give
    # the frame's motion (motion_to_platform refuses; no reachable pose is there)
    locked = from_platform(model, np.r_[model.home[:3], 0.0, np.pi / 2, 0.0], "tool")
    cases.append((c.pose_setpoint_message(1, 0.001, locked, "tool", rate=[0, 0, 0, 0.1, 0, 0]),
                  "rate in frame tool: sample 0: the tool frame's conversion meets gimbal lock"))
    for msg, why in cases:
        dev, said, moved = _refused(model, msg)
        assert len(said) == 1 and said[0].startswith(f"refused: {why}"), (said, why)
        assert dev.counters.setpoints_refused == 1 and dev.counters.handler_errors == 0
        assert dev.counters.setpoints_accepted == 0 and moved < 1e-12


def legs_too_fast(model, home, dy: float, leg_rate: float) -> str:
    """The LEG_SETPOINT rate check's reason for the tool frame's pose `home` moving at `dy`
    (its leg rates from the platform's motion, the first fastest leg)."""
    q, qd, _ = motion_to_platform(model, home, np.r_[0.0, dy, 0, 0, 0, 0], None, "tool")
    rates = leg_state(model, q, qd)[1]
    i = int(np.argmax(np.abs(rates)))
    assert abs(rates[i]) > leg_rate
    return f"leg {i + 1} rate {rates[i]:.3g} m/s, bound {leg_rate:.3g}"


def test_the_rate_bound_holds_every_rate_legs_within_the_capability_give(model):
    """numpy: at random poses of cond(J) <= SP_COND_MAX and leg rates within setpoint_rate,
    the twist nu = J^-1 ldot (J in numpy), written in each frame, is within pose_rate_max."""
    dev = Device(model)
    leg_rate, cond_max = dev.capability.setpoint_rate, dev.settings.cond_max
    rng = np.random.default_rng(11)
    lc = model.characteristic_length
    checked = 0
    for _ in range(300):
        q = np.asarray(model.home) + rng.uniform(-1, 1, 6) * [0.02, 0.02, 0.02, 0.2, 0.2, 0.2]
        R = rotation(q[3:])
        arms = np.array([R @ p for p in model.platform_joints])
        legs = q[:3] + arms - np.asarray(model.base_joints)
        u = legs / np.linalg.norm(legs, axis=1)[:, None]
        J = np.hstack([u, np.cross(arms, u)])
        if np.linalg.cond(np.hstack([u, np.cross(arms, u) / lc])) > cond_max:
            continue
        ldot = rng.uniform(-1, 1, 6) * leg_rate
        v_om = np.linalg.solve(J, ldot)
        # Euler rates of the platform's angles: omega = E thd, E = [Rz Ry e_x, Rz e_y, e_z]
        cy, sy, cz, sz = np.cos(q[4]), np.sin(q[4]), np.cos(q[5]), np.sin(q[5])
        E = np.array([[cz * cy, -sz, 0], [sz * cy, cz, 0], [-sy, 0, 1]])
        qd = np.r_[v_om[:3], np.linalg.solve(E, v_om[3:])]
        for frame in FRAME_NAMES:
            f, fd, _ = motion_from_platform(model, q, qd, None, frame)
            move, turn = pose_rate_max(leg_rate, cond_max, lc, frame_change(model, frame), f[4])
            assert np.max(np.abs(fd[:3])) <= move and np.max(np.abs(fd[3:])) <= turn, frame
        checked += 1
    assert checked > 200


# --------------------------------------------------------------------------- the same checks


def _refused(model, msg):
    w = Wire(model)
    w.send(arm())
    l0 = w.dev.plant.outputs.lengths.copy()
    out = w.send(msg)
    for _ in range(50):
        w.dev.tick()
    moved = np.max(np.abs(w.dev.plant.outputs.lengths - l0))
    return w.dev, texts(out), moved


@pytest.mark.parametrize("frame", ["user", "tool", "pivot"])
@pytest.mark.parametrize("offset, limit, where, cone, radius", [
    (YAWED, "platform_cone", "leg 1", 0.6, 0.004), (CROSSED, "leg_clearance", "legs ", 1.2, 0.009)])
def test_a_pose_past_a_cone_or_a_clearance_is_refused_naming_it(tmp_path, frame, offset, limit,
                                                                where, cone, radius):
    """The poses of tests/hil/test_device_reach.py, written in a frame."""
    model = scene(tmp_path, f"\n[joints]\nbase_cone = {cone!r}\nplatform_cone = {cone!r}\n"
                            f"\n[clearance]\nleg_radius = {radius!r}\n")
    q = np.asarray(model.home) + offset
    m = Reference(tomllib_load(MICRO), cone, radius).margins(q[None])
    # numpy: this limit is the one violated, the other geometric limits hold
    others = {"base_cone", "platform_cone", "leg_clearance"} - {limit}
    assert m[limit][0] < 0 and min(m[k][0] for k in others) > 0
    f = from_platform(model, q, frame)
    dev, said, moved = _refused(model, Client(None).pose_setpoint_message(1, 0.001, f, frame))
    assert len(said) == 1 and said[0].startswith(f"refused: {limit} at {where}"), said
    assert dev.counters.setpoints_refused == 1 == dev.drive_status().setpoints_refused
    assert dev.counters.setpoints_accepted == 0 and moved < 1e-12
    # the same pose in the same frame, the scene without [joints] and [clearance]: followed
    dev, said, moved = _refused(scene(tmp_path), Client(None).pose_setpoint_message(1, 0.001, f,
                                                                                      frame))
    assert said == [] and dev.counters.setpoints_accepted == 1 and moved > 1e-3


@pytest.mark.parametrize("field", range(6))
def test_garbage_is_refused_with_its_reason(model, field):
    name = ("x", "y", "z", "thx", "thy", "thz")[field]
    reach = pose_position_max(model, frame_change(model, "user"))
    home = from_platform(model, model.home, "user")
    c = Client(None)

    def pose(value, frame=ms.STEWART_FRAME_USER, flags=0):
        p = home.copy()
        p[field] = value
        msg = c.pose_setpoint_message(1, 0.001, p, "user")
        msg.frame, msg.flags = frame, flags     # what no client of ours sends
        return msg

    big = 2 * reach if field < 3 else 4.0     # past the bound, finite
    cases = [(pose(np.nan), f"non-finite pose {name}"),
             (pose(-np.inf), f"non-finite pose {name}"),
             (pose(1e300), f"pose {name} 1e+300 "),
             (pose(big), f"pose {name} {big:.4g} "),
             (pose(0.0, frame=4), "frame 4 unknown"),
             (pose(0.0, frame=255), "frame 255 unknown"),
             (pose(0.0, flags=ms.STEWART_SETPOINT_FLAG_FORCE_VALID),
              "flags 0x04: unknown bits 0x04"),   # LEG_SETPOINT's bit, not POSE_SETPOINT's
             (pose(0.0, flags=0x80 | ms.STEWART_POSE_SETPOINT_FLAG_HOLD),
              "flags 0x82: unknown bits 0x80")]
    for msg, why in cases:
        dev, said, moved = _refused(model, msg)
        assert len(said) == 1 and said[0].startswith(f"refused: {why}"), (said, why)
        assert dev.counters.setpoints_refused == 1 and dev.counters.handler_errors == 0
        assert moved < 1e-12


@pytest.mark.parametrize("frame", ["user", "tool", "pivot"])
def test_a_pose_past_the_stroke_is_refused_naming_the_leg(model, frame):
    """A bounded, finite pose whose legs leave the stroke: the LEG_SETPOINT's own check."""
    q = np.asarray(model.home) + [0.01, 0.0, 0.07, 0.0, 0.0, 0.0]
    lengths = inverse_kinematics(model, q, with_cond=False).lengths
    sp_len_max = Device(model).params["SP_LEN_MAX"].get()    # the parameter a host reads
    over = np.flatnonzero(lengths > sp_len_max)
    assert len(over) > 0
    f = from_platform(model, q, frame)
    dev, said, moved = _refused(model, Client(None).pose_setpoint_message(1, 0.001, f, frame))
    assert said == [f"refused: leg {over[0] + 1} at {lengths[over[0]]:.4g} m, stroke max "
                    f"{sp_len_max:.4g}"]
    assert dev.counters.setpoints_refused == 1 and moved < 1e-12


def test_the_position_bound_is_where_a_frame_can_be(model):
    """No pose of the platform with every leg in the stroke puts a frame's origin past it."""
    rng = np.random.default_rng(5)
    q = np.asarray(model.home) + rng.uniform(-1, 1, (20000, 6)) * [0.06, 0.06, 0.06, 0.6, 0.6, 0.6]
    l = inverse_kinematics(model, q, with_cond=False).lengths
    q = q[np.all((l >= model.leg_min) & (l <= model.leg_max), axis=1)]
    assert len(q) > 1000
    for frame in FRAME_NAMES:
        f = from_platform(model, q, frame)
        bound = pose_position_max(model, frame_change(model, frame))
        assert np.max(np.abs(f[:, :3])) < bound, frame


def test_hold_holds_and_ignores_the_pose(model):
    w = Wire(model)
    w.send(arm())
    c = w.client
    target = from_platform(model, np.asarray(model.home) + GOAL * 0.2, "tool")
    assert w.send(c.pose_setpoint_message(1, 0.001, target, "tool")) == []
    for _ in range(100):
        w.dev.tick()
    held = w.dev.plant.outputs.lengths.copy()
    assert w.send(c.pose_setpoint_message(2, 0.101, [np.nan] * 6, "tool", hold=True)) == []
    assert w.dev.counters.setpoints_accepted == 2 and np.array_equal(w.dev.l_ref, held)


def test_the_client_refuses_an_unknown_frame_name(model):
    with pytest.raises(StewartError, match="frame 'world': unknown frame"):
        Client(None).pose_setpoint_message(1, 0.0, np.zeros(6), "world")


# --------------------------------------------------------------------------- signing, pymavlink


def host_mav(key: bytes | None):
    mav = ms.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return mav


def test_signing_applies_as_to_leg_setpoints(model):
    dev = Device(model, signing_key=KEY)
    good = host_mav(KEY)
    dev.feed(bytes(arm().pack(good)))
    assert dev.armed
    pose = Client(None).pose_setpoint_message(1, 0.001, from_platform(
        model, np.asarray(model.home) + GOAL * 0.2, "user"), "user")
    assert dev.feed(bytes(pose.pack(host_mav(None)))) == []
    assert dev.feed(bytes(pose.pack(host_mav(bytes(32))))) == []
    assert dev.counters.signing_rejected == 2 and dev.counters.setpoints_accepted == 0
    assert dev.feed(bytes(pose.pack(good))) == [] and dev.counters.setpoints_accepted == 1


def test_a_pymavlink_script_in_lockstep_over_udp(model):
    """A lab script: pymavlink's mavutil (our dialect attached), pose_setpoint_send in the
    user frame and LOCKSTEP over loopback UDP; the LEG_STATEs are those of the in-process run
    bit for bit."""
    f = from_platform(model, np.asarray(model.home) + GOAL, "user")
    over_udp(model, lambda c, k: c.pose_setpoint_message(k, k / 1000.0, f, "user"),
             lambda host, k: host.mav.pose_setpoint_send(k * 1000, k, *map(float, f),
                                                         ms.STEWART_FRAME_USER, 0))


def test_a_pymavlink_script_with_rates_in_lockstep_over_udp(model):
    """As above, the quintic's first 20 steps in the user frame with their rates: the script
    passes the extension field `rate` and the RATE_VALID flag."""
    q, qd = held_move(model)
    f, fd, _ = motion_from_platform(model, q, qd, None, "user")
    over_udp(model, lambda c, k: c.pose_setpoint_message(k, k / 1000.0, f[k], "user",
                                                         rate=fd[k]),
             lambda host, k: host.mav.pose_setpoint_send(
                 k * 1000, k, *map(float, f[k]), ms.STEWART_FRAME_USER,
                 ms.STEWART_POSE_SETPOINT_FLAG_RATE_VALID, [float(v) for v in fd[k]]))


def over_udp(model, message, send, steps: int = 20) -> None:
    """The LEG_STATEs of `steps` lockstep steps whose setpoints pymavlink sends over loopback
    UDP (`send(host, k)`) are, bit for bit, those of the in-process run of `message(client,
    k)`."""
    w = Wire(model, lockstep=True)
    w.send(arm())
    direct = [w.send(message(w.client, k), ms.MAVLink_lockstep_message(0, k))[-2]
              for k in range(steps)]
    dev = Device(model, lockstep=True)
    server = udp_server("127.0.0.1", 0)
    thread, stop, result = serve_in_thread(dev, server, realtime=False, poll=0.01)
    host = dialect.connection(f"udpout:127.0.0.1:{server.address[1]}", source_system=255,
                              source_component=190)
    try:
        host.mav.command_long_send(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        assert host.recv_match(type="COMMAND_ACK", blocking=True, timeout=10) is not None
        got = []
        for k in range(steps):
            send(host, k)
            host.mav.lockstep_send(0, k)
            m = host.recv_match(type="LEG_STATE", blocking=True, timeout=10)
            assert m is not None and m.step == k
            got.append(m)
    finally:
        stop.set()
        thread.join(5)
        host.close()
        server.close()
    assert not thread.is_alive() and dev.counters.setpoints_accepted == steps
    assert dev.counters.setpoints_refused == 0
    for name in ("length", "rate", "force"):
        assert bits(got, name) == bits(direct, name)
