"""hil.gcs: PI's GCS 2.0 in front of the one emulated device, on the device's simulated clock
(the controller's step and the device's tick called in turn; no wall clock, no sockets but the
server test's loopback ones). The pose map is checked against scipy's rotations, the moves
against the plant's own pose, the data recorder against what the device publishes itself."""
from __future__ import annotations

import math
import random
import socket
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")
from scipy.spatial.transform import Rotation  # noqa: E402

from hil.device import Device  # noqa: E402
from hil.gcs import errors as E  # noqa: E402
from hil.gcs import parser as P  # noqa: E402
from hil.gcs.axes import Frame  # noqa: E402
from hil.gcs.command_set import COMMANDS, execute  # noqa: E402
from hil.gcs.controller import ONT_TOLERANCE, GcsController, Session  # noqa: E402
from hil.gcs.tcp_transport import GcsLink  # noqa: E402
from hil.gcs.server import MAX_LINE, GcsServer  # noqa: E402
from hil.operating_mode import Mode  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


class Keep:
    """An observer that keeps every snapshot the device publishes (hil.observe's interface)."""

    def __init__(self) -> None:
        self.by_tick = {}

    def publish(self, snap) -> None:
        self.by_tick[snap.tick] = snap


def twin(model):
    d = Device(model)
    return d, GcsController(d), Session()


@pytest.fixture(scope="module")
def idle(model):
    """One unreferenced twin for the tests that must leave it as it was."""
    return twin(model)


def run(c: GcsController, ticks: int) -> None:
    for _ in range(ticks):
        c.step()
        c.device.tick()


def ask(c, s, line):
    out = execute(c, s, line)
    return out if out is None or isinstance(out, str) else "".join(out)


def err(c, s) -> int:
    return int(ask(c, s, "ERR?"))


def on_target(c, s, rounds: int = 1000) -> bool:
    """Run the twin 10 ticks at a time until ONT? says every axis is on target (at most
    `rounds` times); whether they all are."""
    for _ in range(rounds):
        run(c, 10)
        if ask(c, s, "ONT?").count("=1") == 6:
            return True
    return False


def referenced(model):
    d, c, s = twin(model)
    assert ask(c, s, "FRF") is None and err(c, s) == 0
    assert ask(c, s, "#7") == chr(176) + "\n"          # busy while referencing
    for _ in range(2000):
        run(c, 10)
        if c.referenced:
            break
    assert c.referenced and d.mode is Mode.ARMED and ask(c, s, "#7") == chr(177) + "\n"
    return d, c, s


# --- the pose map --------------------------------------------------------------------------

def test_pose_map_is_pis_rotation_order_and_round_trips():
    """R = R_home Rx(U) Ry(V) Rz(W) (intrinsic X, Y', Z'': PI's axes move with the platform),
    and the contract's angles are extrinsic X, Y, Z: checked against scipy, both directions."""
    rng = np.random.default_rng(38)
    home = np.array([0.01, -0.02, 0.12, 0.05, -0.03, 0.2])
    frame = Frame(home)
    r_home = Rotation.from_euler("xyz", home[3:]).as_matrix()   # lower case: extrinsic
    for _ in range(200):
        g = np.r_[rng.uniform(-50, 50, 3), rng.uniform(-80, 80, 3)]
        q = frame.to_pose(g)
        r_pi = Rotation.from_euler("XYZ", np.radians(g[3:])).as_matrix()   # intrinsic
        r_q = Rotation.from_euler("xyz", q[3:]).as_matrix()
        np.testing.assert_allclose(r_q, r_home @ r_pi, atol=1e-13)
        np.testing.assert_allclose(q[:3], home[:3] + g[:3] / 1000.0, atol=1e-15)
        np.testing.assert_allclose(frame.from_pose(q), g, atol=1e-9)


def test_pose_map_with_a_pivot_keeps_the_pivot_where_xyz_say():
    rng = np.random.default_rng(1)
    home = np.array([0.0, 0.0, 0.12, 0.0, 0.0, 0.0])
    pivot = np.array([0.01, 0.02, 0.03])
    frame = Frame(home, pivot)
    for _ in range(50):
        g = np.r_[np.zeros(3), rng.uniform(-30, 30, 3)]   # rotations only: the pivot stays
        q = frame.to_pose(g)
        r = Rotation.from_euler("xyz", q[3:]).as_matrix()
        np.testing.assert_allclose(q[:3] + r @ pivot, home[:3] + pivot, atol=1e-15)
        np.testing.assert_allclose(frame.from_pose(q), g, atol=1e-9)


# --- the parser ----------------------------------------------------------------------------

@pytest.mark.parametrize("word", ["nan", "inf", "-inf", "1_0", "0x10", "1e", "--1", "", "1.2.3",
                                  "1" * 41, "1e99999"])
def test_numbers_that_are_not_gcs_numbers_are_syntax_errors(word):
    with pytest.raises(E.GcsError) as exc:
        P.number(word)
    assert exc.value.code == E.PARAM_SYNTAX


def test_number_overflow_is_infinite_and_answers_end_as_pi_does():
    assert P.number("1e999") == math.inf and P.number("-.5") == -0.5 and P.number("+2.") == 2.0
    assert P.answer(["X=1", "Y=2"]) == "X=1 \nY=2\n"


# --- commands on the simulated clock ---------------------------------------------------------

def test_identification_axes_help(idle):
    d, c, s = idle
    assert ask(c, s, "*IDN?").split(", ")[1] == "STEWART-SIM-TWIN"
    assert ask(c, s, "SAI?") == "X \nY \nZ \nU \nV \nW\n"
    assert ask(c, s, "CSV?") == "2.0\n"
    lines = ask(c, s, "HLP?").splitlines()
    listed = {line.split()[0] for line in lines[1:-1]}
    assert listed == set(COMMANDS)
    assert ask(c, s, "POS? X Z") == "X=0.0 \nZ=0.0\n"
    assert ask(c, s, "SPA? 1 0x0E000200") == f"1 0x0E000200={d.dt}\n"
    assert err(c, s) == 0


@pytest.mark.parametrize("line, code", [
    ("FOO", E.UNKNOWN_COMMAND), ("MOV X 1", E.MOVE_WITHOUT_REF_OR_NO_SERVO),
    ("POS? Q", E.INVALID_AXIS), ("MOV X", E.PARAM_SYNTAX), ("MOV X abc", E.PARAM_SYNTAX),
    ("MOV X 1 X 2", E.DOUBLE_AXIS), ("VLS 0", E.PARAM_OUT_OF_RANGE),
    ("VLS 1e9", E.PARAM_OUT_OF_RANGE),
    ("SVO X 1 Y 0", E.CMD_NOT_ALLOWED_FOR_STAGE), ("SVO X 2", E.PARAM_SYNTAX),
    ("DRC 9 X 2", E.INVALID_RECORDER_CHAN), ("DRC 1 Q 2", E.INVALID_RECORDER_SRC_CHAN),
    ("DRC 1 X 55", E.INVALID_RECORDER_SRC_OPT), ("RTR 0", E.PARAM_OUT_OF_RANGE),
    ("STP", E.STOP), ("*IDN? X", E.PARAM_SYNTAX), ("MOV\x01 X 1", E.UNKNOWN_COMMAND),
    ("SPA 1 0x0E000200 0.5", E.READ_ONLY_PARAMETER), ("SPA? 1 0x12345", E.UNKNOWN_PARAMETER),
    ("SPA? X 0x0E000200", E.INVALID_AXIS), ("SPA? 1 zz", E.PARAM_SYNTAX),
    ("SPI Q 1", E.INVALID_AXIS), ("SPI T 1e4", E.PARAM_OUT_OF_RANGE), ("SPI T", E.PARAM_SYNTAX),
    ("SPI? X", E.INVALID_AXIS), ("VMO? X nan", E.PARAM_SYNTAX), ("TRA? X 0", E.PARAM_OUT_OF_RANGE),
    ("TRA? U 1 W 1", E.PARAM_OUT_OF_RANGE), ("TRA? X 1e400", E.PARAM_OUT_OF_RANGE)])
def test_a_refused_line_sets_pis_error_answers_nothing_and_changes_nothing(idle, line, code):
    d, c, s = idle
    before = (c.target.copy(), c.velocity, c.servo, c.referenced, d.mode, d.counters.commands)
    assert ask(c, s, line) is None
    assert err(c, s) == code
    assert err(c, s) == 0                       # ERR? clears
    after = (c.target.copy(), c.velocity, c.servo, c.referenced, d.mode, d.counters.commands)
    assert np.array_equal(before[0], after[0]) and before[1:] == after[1:]


def test_reference_move_wait_read_back_and_the_plant_agrees(model):
    d, c, s = referenced(model)
    assert ask(c, s, "FRF?") == "X=1 \nY=1 \nZ=1 \nU=1 \nV=1 \nW=1\n"
    assert ask(c, s, "MOV X 2 Y -1 Z 0.5 U 0.3 V -0.2 W 1") is None and err(c, s) == 0
    assert int(ask(c, s, "#5"), 16) == 0x3F
    for _ in range(400):
        run(c, 10)
        if all(ask(c, s, "ONT?").replace(" ", "").split("\n")[i].endswith("=1")
               for i in range(6)):
            break
    goal = np.array([2, -1, 0.5, 0.3, -0.2, 1.0])
    pos = np.array([float(x.split("=")[1]) for x in ask(c, s, "POS?").split("\n") if x])
    assert np.all(np.abs(pos - goal) <= ONT_TOLERANCE)
    # the plant's own pose, read independently: C's origin and R from scipy's composition
    q = np.asarray(d.snapshot().q)
    np.testing.assert_allclose(q[:3], model.home[:3] + goal[:3] / 1000, atol=ONT_TOLERANCE / 1e3)
    r = Rotation.from_euler("xyz", q[3:]).as_matrix()
    r_goal = Rotation.from_euler("XYZ", np.radians(goal[3:])).as_matrix()
    assert np.degrees(np.linalg.norm(Rotation.from_matrix(r @ r_goal.T).as_rotvec())) \
        <= 2 * ONT_TOLERANCE
    assert d.counters.setpoints_refused == 0 and d.counters.watchdog_trips == 0
    # relative move from the target, and the refusal of one out of the travel range
    assert ask(c, s, "MVR Z -1") is None and err(c, s) == 0
    assert ask(c, s, "MOV? Z") == "Z=-0.5\n"
    high = float(ask(c, s, "PLM? X").split("=")[1])
    assert ask(c, s, f"MOV X {high + 1}") is None and err(c, s) == E.POS_OUT_OF_LIMITS
    assert ask(c, s, "MOV? Z") == "Z=-0.5\n"


def test_stop_brakes_within_the_stroke_and_holds(model):
    d, c, s = referenced(model)
    ask(c, s, "VLS 40")
    ask(c, s, "MOV Z 25")
    run(c, 300)                                # mid-move, fast
    assert c.mover.moving
    assert ask(c, s, "STP") is None and err(c, s) == E.STOP
    assert not c.mover.moving
    lo, hi = d.leg_min, d.leg_max
    for _ in range(600):
        c.step()
        d.tick()
        snap = d.snapshot()
        assert all(lo <= x <= hi for x in snap.lengths)
    here = np.asarray(ask(c, s, "MOV?").replace(" ", "").replace("\n", "=").split("=")[1::2],
                      dtype=float)
    pos = c.position()
    assert np.all(np.abs(pos - here) < 0.05)   # holds where it braked (mm, deg)
    assert d.counters.faults == 0 and d.counters.watchdog_trips == 0 and d.armed


def test_recorder_table_is_the_devices_own_record(model):
    d, c, s = referenced(model)
    keep = Keep()
    d.observe(keep, hz=d.rate)
    for line in ("DRC 1 X 2 2 1 2 3 1 100 4 X 8 5 Z 1", "RTR 2", "DRT 0 1 0"):
        assert ask(c, s, line) is None and err(c, s) == 0
    assert ask(c, s, "MOV X 1 Z -1") is None
    run(c, 600)
    n = int(ask(c, s, "DRL? 1").split("=")[1])
    assert n == 300
    text = ask(c, s, "DRR? 1 300 1 2 3 4 5")
    head, data = text.split("# END_HEADER \n")
    assert "# NDATA = 300" in head and "# SAMPLE_TIME = 0.002" in head
    rows = np.array([[float(v) for v in line.split()] for line in data.splitlines()])
    assert rows.shape == (300, 5)
    for x, leg, force, t, z_cmd in rows:
        snap = keep.by_tick[round(t * d.rate)]
        assert x == pytest.approx((snap.q[0] - model.home[0]) * 1e3, abs=1e-12)
        assert leg == pytest.approx(snap.lengths[0] * 1e3, abs=1e-12)
        assert force == snap.forces[0]
    assert np.all(np.diff(rows[:, 3]) == pytest.approx(0.002))
    assert rows[-1, 4] < 0 and rows[0, 4] == pytest.approx(0.0, abs=1e-3)   # the reference
    assert ask(c, s, "DRR? 250 100 1") is not None and err(c, s) == E.NOT_ENOUGH_RECORDED_DATA


def test_servo_off_and_a_device_fault_refuse_moves(model):
    d, c, s = referenced(model)
    ask(c, s, "SVO X 0")
    assert ask(c, s, "SVO?").startswith("X=0") and not d.armed
    assert ask(c, s, "MOV X 1") is None and err(c, s) == E.MOVE_WITHOUT_REF_OR_NO_SERVO
    ask(c, s, "SVO X 1 Y 1 Z 1 U 1 V 1 W 1")
    assert d.armed and ask(c, s, "MOV X 1") is None and err(c, s) == 0
    run(c, 5)
    c.command(0 + 400, 0.0)        # MAV_CMD_COMPONENT_ARM_DISARM 0: as if the device faulted
    run(c, 2)
    assert not c.servo and err(c, s) == E.MOTION_ERROR


# --- hostile input ---------------------------------------------------------------------------

def _hostile_lines(rng: random.Random, n: int) -> list[bytes]:
    """n seeded hostile lines (no LF in them): random words of the command set and absurd
    arguments, random bytes, huge moves, floods of the same few lines. None starts with FRF:
    referencing is the one command that may move an unreferenced twin (to its home)."""
    words = [b"MOV", b"MVR", b"SVO", b"FRF", b"VLS", b"DRC", b"DRT", b"RTR", b"DRR?", b"POS?",
             b"X", b"Y", b"W", b"Q", b"1e308", b"-1e308", b"nan", b"inf", b"99999", b"-0",
             b"0.5", b"\x00", b"\xff\xfe", b"*IDN?", b"ERR?", b"HLP?", b"STP", b"#", b"0", b"1",
             b"SPI", b"SPI?", b"VMO?", b"TRA?", b"R", b"T", b"KSW", b"KST", b"KEN", b"KLN",
             b"KLT?", b"KET?", b"ZERO"]
    out = []
    for _ in range(n):
        kind = rng.random()
        if kind < 0.4:
            out.append(b" ".join(rng.choice(words) for _ in range(rng.randint(1, 8))))
        elif kind < 0.7:
            out.append(bytes(rng.randrange(256) for _ in range(rng.randint(1, 60))).replace(
                b"\n", b""))
        elif kind < 0.8:
            out.append(b"MOV X " + str(rng.uniform(-1e6, 1e6)).encode())
        else:
            out.append(rng.choice([b"FOO", b"mov x 1", b"SVO X 1", b"DRR? 1 99999999",
                                   b"MOV " + b"X 1 " * 50, b"RTR 99999"]))
        if out[-1].lstrip(b" ").upper().startswith(b"FRF"):
            out[-1] = b"FR" + out[-1].lstrip(b" ")[3:]
    return out


def test_fuzz_hostile_lines_set_pis_errors_and_never_move_or_fault(model):
    """Seeded, bounded: 3000 hostile lines to an unreferenced twin (the servo may be switched
    on by them, but nothing may move it): only PI's codes, the plant where it was, no fault."""
    d, c, s = twin(model)
    rng = random.Random(38)
    q0 = np.asarray(d.snapshot().q)
    codes = {}
    allowed = set(E.TEXTS) - {E.CONTROLLER_ERROR, E.MOTION_ERROR}
    for i, line in enumerate(_hostile_lines(rng, 3000)):
        execute(c, s, line.decode("latin-1"))
        code = s.error
        s.error = 0
        codes[code] = codes.get(code, 0) + 1
        assert code in allowed, (line, code)
        if i % 10 == 0:
            run(c, 1)
    assert c.internal_errors == 0 and not c.referenced
    assert np.allclose(np.asarray(d.snapshot().q), q0, atol=1e-9)
    assert d.counters.faults == 0 and d.counters.numeric_faults == 0
    assert codes.get(E.UNKNOWN_COMMAND, 0) > 500 and codes.get(E.PARAM_SYNTAX, 0) > 50
    print("fuzz codes", sorted(codes.items(), key=lambda kv: -kv[1]),
          "moved", float(np.max(np.abs(np.asarray(d.snapshot().q) - q0))))


def _serve(link, device, ticks):
    for _ in range(ticks):
        link.recv(0.0)
        device.tick()


def test_server_bounds_lines_connections_and_floods(model):
    d = Device(model)
    c = GcsController(d)
    server = GcsServer(c, "127.0.0.1", 0, max_clients=2, idle_timeout=3600)
    link = GcsLink(c, server)
    try:
        a = socket.create_connection(server.address, timeout=5)
        b = socket.create_connection(server.address, timeout=5)
        extra = socket.create_connection(server.address, timeout=5)
        _serve(link, d, 5)
        assert server.stats.accepted == 2 and server.stats.refused == 1
        assert extra.recv(16) == b""                        # closed at once
        a.sendall(b"X" * (MAX_LINE * 4) + b"\n*IDN?\nERR?\n")
        b.sendall(b"*IDN?\n" * 2000)                         # a flood of queries
        a.settimeout(5)
        got = b""
        for _ in range(2000):
            _serve(link, d, 1)
            if got.count(b"\n") < 2:
                a.setblocking(False)
                try:
                    got += a.recv(4096)
                except BlockingIOError:
                    pass
            if got.count(b"\n") >= 2 and server.stats.lines >= 2003:
                break
        assert got.split(b"\n")[1] == b"3"                 # the overlong line: error 3
        assert server.stats.overlong == 1 and server.stats.lines >= 2003
        b.setblocking(False)
        assert b.recv(1 << 20).startswith(b"stewart-sim")
        assert not d.armed and d.counters.faults == 0
    finally:
        for sock in (a, b, extra):
            sock.close()
        link.close()


def test_idle_connections_are_closed(model):
    d = Device(model)
    c = GcsController(d)
    now = [0.0]
    server = GcsServer(c, "127.0.0.1", 0, idle_timeout=5.0, clock=lambda: now[0])
    link = GcsLink(c, server)
    try:
        a = socket.create_connection(server.address, timeout=5)
        _serve(link, d, 3)
        a.sendall(b"*IDN?\n")
        _serve(link, d, 3)
        now[0] = 4.0
        _serve(link, d, 3)
        assert server.stats.closed_idle == 0 and len(server.conns) == 1
        now[0] = 10.0
        _serve(link, d, 3)
        assert server.stats.closed_idle == 1 and not server.conns
        a.settimeout(5)
        assert a.recv(1 << 16).startswith(b"stewart-sim") and a.recv(16) == b""
        a.close()
    finally:
        link.close()


def test_fuzz_hostile_bytes_over_tcp(model):
    """Seeded, bounded: two clients send 64 KiB each of hostile bytes (binary, control bytes,
    overlong lines, floods of queries and moves) in random pieces; the device ticks between
    polls. Every line gets a PI code or an answer, the server keeps serving a third client,
    the plant does not move (it is never referenced) and nothing faults."""
    d = Device(model)
    c = GcsController(d)
    server = GcsServer(c, "127.0.0.1", 0, max_clients=3, idle_timeout=3600)
    link = GcsLink(c, server)
    rng = random.Random(5038)
    q0 = np.asarray(d.snapshot().q)
    streams = []
    for _ in range(2):
        data = bytearray()
        while len(data) < 1 << 16:
            pick = rng.random()
            if pick < 0.3:
                data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 300)))
            elif pick < 0.4:
                data += b"MOV X " + b"9" * rng.randint(100, 3000) + b"\n"
            elif pick < 0.5:
                data += bytes([rng.choice([5, 7, 24])])
            else:
                data += b"\n".join(_hostile_lines(rng, 20)) + b"\n"
        streams.append(bytes(data[:1 << 16]))
    clients = [socket.create_connection(server.address, timeout=5) for _ in range(2)]
    try:
        for s in clients:
            s.setblocking(False)
        sent = [0, 0]
        for _ in range(20000):
            for i, s in enumerate(clients):
                if sent[i] < len(streams[i]):
                    piece = streams[i][sent[i]:sent[i] + rng.randint(1, 4096)]
                    try:
                        sent[i] += s.send(piece)
                    except BlockingIOError:
                        pass
                try:
                    s.recv(1 << 20)            # read and drop the answers
                except BlockingIOError:
                    pass
            _serve(link, d, 1)
            if server.stats.bytes_in == 2 << 16 and all(
                    x.stream is None and not x.out and b"\n" not in x.inbuf
                    for x in server.conns.values()):
                break
        assert sent == [1 << 16] * 2
        probe = socket.create_connection(server.address, timeout=5)
        probe.sendall(b"ERR?\nPOS? Z\n")
        got = b""
        for _ in range(1000):
            _serve(link, d, 1)
            probe.setblocking(False)
            try:
                got += probe.recv(4096)
            except BlockingIOError:
                pass
            if got.count(b"\n") >= 2:
                break
        assert got == b"0\nZ=0.0\n"
        probe.close()
    finally:
        for s in clients:
            s.close()
        link.close()
    st = server.stats
    assert st.lines > 1000 and st.errors > 500 and st.overlong > 10
    assert c.internal_errors == 0 and not c.referenced
    assert np.allclose(np.asarray(d.snapshot().q), q0, atol=1e-9)
    assert d.counters.faults == 0 and d.counters.numeric_faults == 0


def _gcs(sock: socket.socket, line: bytes, answer: bool = True, ticks_until=None) -> bytes:
    """Send a GCS line; its answer (up to an LF without a space before it), read within a
    bounded number of waits."""
    sock.sendall(line + b"\n")
    if not answer:
        return b""
    got = b""
    for _ in range(500):
        got += sock.recv(65536)
        if got.endswith(b"\n") and not got.endswith(b" \n"):
            return got
    raise AssertionError(f"no answer to {line!r}")


def test_gcs_beside_mavlink_drives_the_same_device(model):
    """--gcs with --udp: a MAVLink peer sees the acks of the arm and home the GCS controller
    sends, and its LEG_STATE lengths are those of the pose GCS moved the device to (the
    inverse kinematics of the target, computed here)."""
    import select
    import time

    from hil import mavlink_stewart as ms
    from hil.gcs.tcp_transport import gcs_link
    from hil.link import udp_server
    from hil.serve import serve_in_thread
    from stewart_fmu.kinematics import inverse_kinematics

    d = Device(model, telemetry={"LEG_STATE": 50.0})
    link = gcs_link(d, "127.0.0.1", 0, inner=udp_server("127.0.0.1", 0))
    thread, stop, _ = serve_in_thread(d, link)
    mav_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    mav_sock.bind(("127.0.0.1", 0))
    mav_sock.connect(link.inner.address)
    host = ms.MAVLink(None, srcSystem=255, srcComponent=190)
    host.robust_parsing = True
    seen: dict[str, list] = {}

    def listen(seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if select.select([mav_sock], [], [], 0.02)[0]:
                for m in host.parse_buffer(mav_sock.recv(65536)) or []:
                    seen.setdefault(m.get_type(), []).append(m)

    try:
        mav_sock.send(host.heartbeat_encode(6, 8, 0, 0, 0).pack(host))   # become the peer
        listen(0.3)
        with socket.create_connection(link.server.address, timeout=10) as g:
            _gcs(g, b"FRF", answer=False)
            for _ in range(200):
                if _gcs(g, b"FRF? X") == b"X=1\n":
                    break
                listen(0.05)
            _gcs(g, b"MOV Z 2", answer=False)
            for _ in range(400):
                if _gcs(g, b"ONT? Z") == b"Z=1\n":
                    break
                listen(0.05)
            assert _gcs(g, b"ERR?") == b"0\n"
            seen.pop("LEG_STATE", None)
            listen(0.3)
    finally:
        stop.set()
        thread.join(10)
        link.close()
        mav_sock.close()
    acks = {(a.command, a.result) for a in seen.get("COMMAND_ACK", [])}
    assert (ms.MAV_CMD_COMPONENT_ARM_DISARM, ms.MAV_RESULT_ACCEPTED) in acks
    assert (ms.MAV_CMD_NAV_RETURN_TO_LAUNCH, ms.MAV_RESULT_ACCEPTED) in acks
    target = np.array(model.home, dtype=float) + [0, 0, 0.002, 0, 0, 0]
    expected = inverse_kinematics(model, target).lengths
    lengths = np.array(seen["LEG_STATE"][-1].length)
    assert np.all(np.abs(lengths - expected) < 2e-6)      # m: the servo's on-target window


def test_device_command_serves_mavlink_and_gcs_and_wants_a_link(capsys):
    import subprocess
    import sys

    from hil.spawn import _first_line, _stop, parse_gcs, parse_udp
    from stewart_sim import cli

    assert cli.main(["device", str(SCENE)]) == 2
    err_line = capsys.readouterr().err.strip()
    assert err_line.startswith("stewart-sim: error:") and "--gcs 127.0.0.1:PORT" in err_line
    assert cli.main(["device", str(SCENE), "--gcs", "127.0.0.1:0", "--lockstep"]) == 2
    assert "not with --lockstep" in capsys.readouterr().err
    proc = subprocess.Popen([sys.executable, "-m", "hil.spawn", str(SCENE), "--udp",
                             "127.0.0.1:0", "--gcs", "127.0.0.1:0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        udp = parse_udp(_first_line(proc, 60))
        # printed with the first line, in one write: already read into the pipe's buffer
        # (select would not see it again), or EOF if the device died
        host, port = parse_gcs(proc.stdout.readline().strip())
        assert udp[0] == host == "127.0.0.1" and port > 0
        with socket.create_connection((host, port), timeout=10) as g:
            assert _gcs(g, b"*IDN?").startswith(b"stewart-sim, STEWART-SIM-TWIN")
    finally:
        _stop(proc)
    assert proc.returncode == 0


def test_halt_comes_to_rest_smoothly_where_mov_q_says(model):
    """HLT mid-move: error 10 as PI sets it; the leg references keep a continuous rate (their
    second difference stays within what the move itself asks, unlike STP's step to rest), the
    platform rests on the move's own line, between where it was and the goal, at MOV?."""
    d, c, s = referenced(model)
    ask(c, s, "VLS 40")
    ask(c, s, "MOV Z 20")
    refs = []
    for _ in range(300):
        c.step()
        refs.append(d.l_ref.copy())
        d.tick()
    z_then = c.position()[2]
    assert ask(c, s, "HLT") is None and err(c, s) == E.STOP
    z_rest = float(ask(c, s, "MOV? Z").split("=")[1])
    assert z_then < z_rest < 20.0
    for _ in range(1500):
        c.step()
        refs.append(d.l_ref.copy())
        d.tick()
        if ask(c, s, "ONT? Z") == "Z=1\n":
            break
    assert abs(c.position()[2] - z_rest) <= ONT_TOLERANCE
    second = np.abs(np.diff(np.array(refs), n=2, axis=0))
    assert second.max() < 1e-6     # m per tick^2; the move's own: 1.1e-7, STP's step: 5.1e-5
    pos = c.position()
    assert np.all(np.abs(pos[[0, 1, 3, 4, 5]]) <= ONT_TOLERANCE)
    assert d.counters.setpoints_refused == 0 and d.counters.faults == 0


def test_travel_range_ends_where_a_leg_or_the_singularity_bound_binds(idle):
    """NLM?/PLM?: each end, reached along its own axis, is inside the device's setpoint stroke
    and condition bound, and 0.001 (mm or deg) beyond it is not (checked with the plant's own
    inverse kinematics at the contract's pose)."""
    from stewart_fmu.kinematics import inverse_kinematics

    d, c, s = idle
    b = d.capability

    def inside(g) -> bool:
        kin = inverse_kinematics(d.model, c.frame.to_pose(g))
        return bool(np.all(kin.lengths >= b.leg_min) and np.all(kin.lengths <= b.leg_max)
                    and kin.cond <= d.settings.cond_max)

    low = [float(x.split("=")[1]) for x in ask(c, s, "NLM?").split("\n") if x]
    high = [float(x.split("=")[1]) for x in ask(c, s, "PLM?").split("\n") if x]
    for i in range(6):
        for end, out in ((low[i], -1e-3), (high[i], 1e-3)):
            g = np.zeros(6)
            g[i] = end
            assert inside(g), (i, end)
            g[i] = end + out
            assert not inside(g), (i, end)


# --- the pivot point and the workspace queries -----------------------------------------------

def _values(answer: str) -> dict[str, float]:
    return {k: float(v) for k, v in (row.strip().split("=") for row in answer.splitlines())}


def test_pivot_is_set_only_while_u_v_w_are_0_and_the_platform_turns_about_it(model):
    d, c, s = referenced(model)
    assert _values(ask(c, s, "SPI?")) == {"R": 0.0, "S": 0.0, "T": 0.0}
    assert ask(c, s, "MOV X 1 Y -0.5") is None and err(c, s) == 0
    run(c, 400)
    assert ask(c, s, "SPI R 1 S -2 T 15") is None and err(c, s) == 0   # X Y Z keep their values
    assert _values(ask(c, s, "SPI? T R")) == {"T": 15.0, "R": 1.0}
    assert _values(ask(c, s, "MOV? X Y Z")) == {"X": 1.0, "Y": -0.5, "Z": 0.0}
    goal = np.array([1.0, -0.5, 0.0, 2.0, -1.5, 3.0])
    assert ask(c, s, "MOV U 2 V -1.5 W 3") is None and err(c, s) == 0
    assert on_target(c, s, 400)
    # the plant's own pose: the pivot (in C) stays where X Y Z put it, while C's origin moved
    q = np.asarray(d.snapshot().q)
    p = np.array([1.0, -2.0, 15.0]) / 1e3
    r = Rotation.from_euler("xyz", q[3:]).as_matrix()
    pivot_n = q[:3] + r @ p
    expected = model.home[:3] + p + goal[:3] / 1e3
    assert np.all(np.abs(pivot_n - expected) <= ONT_TOLERANCE / 1e3)
    assert np.linalg.norm(q[:3] - (model.home[:3] + goal[:3] / 1e3)) > 100 * ONT_TOLERANCE / 1e3
    # rotated: SPI is PI's error 9, and nothing changes
    assert ask(c, s, "SPI T 0") is None and err(c, s) == E.SET_PIVOT_NOT_POSSIBLE
    assert _values(ask(c, s, "SPI? T")) == {"T": 15.0}


def test_vmo_says_what_mov_does_and_a_refused_move_names_its_limit(model):
    d, c, s = referenced(model)
    high = _values(ask(c, s, "PLM?"))
    assert ask(c, s, "VMO? X 1 W 2") == "1\n" and err(c, s) == 0
    assert ask(c, s, f"VMO? X {high['X'] + 1}") == "0\n" and s.why == "axes X out of range"
    # inside each axis's range, not together: a leg leaves the stroke on the way
    target = f"X {0.9 * high['X']} Z {0.9 * high['Z']}"
    assert ask(c, s, f"VMO? {target}") == "0\n" and err(c, s) == 0
    why = s.why
    assert why.startswith("leg ") and "setpoint stroke on the way" in why
    assert ask(c, s, f"MOV {target}") is None and err(c, s) == E.POS_OUT_OF_LIMITS
    assert s.why == why and np.all(c.target == 0.0) and not c.mover.moving
    # the setpoint stroke binds before the mechanism's: the engine names the limit it reaches
    n = int(why.split()[1]) - 1
    kin_q = c.frame.to_pose(np.r_[0.9 * high["X"], 0.0, 0.9 * high["Z"], 0.0, 0.0, 0.0])
    from stewart_fmu.kinematics import inverse_kinematics
    lengths = inverse_kinematics(model, kin_q[None]).lengths[0]
    assert not d.capability.leg_min <= lengths[n] <= d.capability.leg_max


def _reach_step(capsys, scene, direction, frame=None) -> float:
    from stewart_sim import cli

    args = ["workspace", str(scene), "--reach", "--direction",
            ",".join(repr(float(v)) for v in direction)]
    assert cli.main(args + (["--frame", frame] if frame else [])) == 0
    out = capsys.readouterr().out
    assert out.startswith("largest step ") and "stopped by" in out
    return float(out.split()[2])


def test_tra_is_the_workspace_commands_reach_on_the_same_scene(model, capsys, tmp_path):
    """From home exactly (a fresh twin: the plant starts there), TRA? along an axis ends where
    `stewart-sim workspace --reach` does: the same engine, marched along the same line, each
    bisected to 1e-9 of its step's unit."""
    d, c, s = twin(model)
    assert np.array_equal(np.asarray(d.snapshot().q), model.home)
    tol_mm, tol_deg = 2e-9 * 1e3, math.degrees(2e-9)
    for axis, sign in (("X", 1), ("Y", -1), ("Z", 1), ("W", 1)):
        i = "XYZUVW".index(axis)
        direction = np.zeros(6)
        direction[i] = sign
        step = _reach_step(capsys, SCENE, direction)
        got = _values(ask(c, s, f"TRA? {axis} {sign}"))[axis]
        expected = sign * step * (1e3 if i < 3 else math.degrees(1.0))
        assert abs(got - expected) <= (tol_mm if i < 3 else tol_deg), axis
    # with a pivot 10 mm above C: the scene's [frames] pivot and the pivot frame
    scene = tmp_path / "pivot.toml"
    scene.write_text(SCENE.read_text() + "\n[frames]\npivot = [0.0, 0.0, 0.01]\n")
    assert ask(c, s, "SPI T 10") is None and err(c, s) == 0
    for axis in ("U", "V"):
        direction = np.zeros(6)
        direction["XYZUVW".index(axis)] = 1.0
        step = _reach_step(capsys, scene, direction, "pivot")
        got = _values(ask(c, s, f"TRA? {axis} 1"))[axis]
        assert abs(got - math.degrees(step)) <= tol_deg, axis
    # a translation and a turn together: 1 mm and 1 deg per unit step
    step = _reach_step(capsys, scene, [0.0, 0.0, -1e-3, 0.0, math.radians(1.0), 0.0], "pivot")
    got = _values(ask(c, s, "TRA? Z -1 V 1"))
    assert abs(got["Z"] + step) <= 2e-9 and abs(got["V"] - step) <= 2e-9
    assert err(c, s) == 0


# --- coordinate systems ------------------------------------------------------------------------

def test_coordinate_systems_define_link_enable_and_moves_follow_them(model):
    """KSW/KST/KLN/KEN/KET?/KLT?/KRM with PI's codes; with a work and a tool system enabled POS?
    is the tool's pose seen from the work system (checked with scipy's rotations on the plant's
    own pose), a move along X goes along the work system's X, a turn keeps the tool's origin."""
    d, c, s = referenced(model)
    assert ask(c, s, "KET?") == "ZERO=ZERO\n"
    for line in ("KSW WORK X 5 Z 2 W 30", "KST TOOL Z 10 U 5", "KST TIP X 1", "KLN TIP TOOL"):
        assert ask(c, s, line) is None and err(c, s) == 0, line
    assert _values(ask(c, s, "KLT? TIP TOOL")) == pytest.approx(
        {"X": 1.0, "Y": 0.0, "Z": 0.0, "U": 0.0, "V": 0.0, "W": 0.0}, abs=1e-12)
    tip = _values(ask(c, s, "KLT? TIP"))           # TOOL then TIP: (0, 0, 10) + Rx(5) (1, 0, 0)
    assert [tip[a] for a in "XYZUVW"] == pytest.approx([1, 0, 10, 5, 0, 0], abs=1e-12)
    for line, code in (("KLN TOOL TIP", E.CS_CYCLIC), ("KLN TIP TIP", E.CS_LINKED_TO_ITSELF),
                       ("KLN WORK TOOL", E.CS_MAY_NOT_BE_LINKED), ("KEN NONE", E.CS_DOES_NOT_EXIST),
                       ("KSW ZERO X 1", E.CS_WRITE_PROTECTED), ("KST 1BAD X 1", E.CS_INVALID_NAME),
                       ("KET? KSX", E.CS_TYPE_UNKNOWN), ("KET? KST", E.NO_CS_OF_TYPE_ENABLED),
                       ("KSW WORK V 90", E.PARAM_OUT_OF_RANGE),
                       ("KLT? TIP WORK", E.CS_NOT_SAME_CHAIN), ("KST WORK X 1", E.CS_IN_USE)):
        assert ask(c, s, line) is None and err(c, s) == code, line
    assert ask(c, s, "KEN WORK") is None and ask(c, s, "KEN TIP") is None and err(c, s) == 0
    assert ask(c, s, "KET?") == "KSW=WORK \nKST=TIP\n"
    for line, code in (("KSW WORK X 1", E.CS_IN_USE), ("KRM TOOL", E.CS_IN_USE),
                       ("SPI T 1", E.SPI_NOT_WITH_CS)):
        assert ask(c, s, line) is None and err(c, s) == code, line

    def seen_from_work(q):
        """The tip's pose in WORK from the plant's q, independently: scipy's rotations."""
        r_c = Rotation.from_euler("xyz", q[3:])               # the contract's Rz Ry Rx
        r_tip = r_c * Rotation.from_euler("XYZ", [5, 0, 0], degrees=True)
        p_tip = q[:3] + r_c.apply([0.0, 0.0, 0.01]) + r_tip.apply([0.001, 0.0, 0.0])
        r_w = Rotation.from_euler("XYZ", [0, 0, 30], degrees=True)
        p = r_w.inv().apply(p_tip - (model.home[:3] + [0.005, 0.0, 0.002])) * 1e3
        return np.r_[p, (r_w.inv() * r_tip).as_euler("XYZ", degrees=True)]

    pos = np.array(list(_values(ask(c, s, "POS?")).values()))
    assert np.all(np.abs(pos - seen_from_work(np.asarray(d.snapshot().q))) <= 1e-9)
    assert np.allclose(list(_values(ask(c, s, "MOV?")).values()), pos, atol=ONT_TOLERANCE)
    # a move along WORK's X, then a turn about the tip: on target, and the plant agrees
    for line, goal in (("MOV X 2 Y 1 Z 8 U 0 V 0 W 0", [2, 1, 8, 0, 0, 0]),
                       ("MOV U 1.5 V -1 W 2", [2, 1, 8, 1.5, -1, 2])):
        assert ask(c, s, line) is None and err(c, s) == 0, line
        assert on_target(c, s), line
        got = seen_from_work(np.asarray(d.snapshot().q))
        assert np.all(np.abs(got - goal) <= ONT_TOLERANCE), (line, got)
    assert ask(c, s, "KEN ZERO") is None and ask(c, s, "KET?") == "ZERO=ZERO\n"
    assert ask(c, s, "KRM TIP") is None and ask(c, s, "KRM TOOL") is None and err(c, s) == 0


def test_directed_system_is_a_work_and_tool_that_coincide_at_zero(model):
    """KSD D X 3 Y -2 Z 10 W 30: a point on the platform with turned axes; enabled, POS? reads 0
    at ZERO and a move is D's pose seen from where D was at ZERO, in D's axes (checked with
    scipy's rotations on the plant's own pose); it replaces an enabled work/tool and they it."""
    d, c, s = referenced(model)
    offset, turn = np.array([3.0, -2.0, 10.0]), Rotation.from_euler("z", 30, degrees=True)
    for line in ("KSD D X 3 Y -2 Z 10 W 30", "KSW WORK X 5"):
        assert ask(c, s, line) is None and err(c, s) == 0, line
    for line, code in (("KLN D WORK", E.CS_MAY_NOT_BE_LINKED), ("KSD D V 90", E.PARAM_OUT_OF_RANGE),
                       ("KSD WORK X 1", E.CS_IN_USE), ("KET? KSD", E.NO_CS_OF_TYPE_ENABLED)):
        assert ask(c, s, line) is None and err(c, s) == code, line
    assert ask(c, s, "KEN WORK") is None and ask(c, s, "KEN D") is None and err(c, s) == 0
    assert ask(c, s, "KET?") == "KSD=D\n" and ask(c, s, "KET? KSD") == "KSD=D\n"
    assert ask(c, s, "KEN?") == "D=KSD\n"
    assert ask(c, s, "KEN? D") is None and err(c, s) == E.PARAM_SYNTAX
    assert ask(c, s, "KSD D X 1") is None and err(c, s) == E.CS_IN_USE

    def seen_from_d(q):
        """D's pose from where D was at ZERO (home), in D's axes, independently: scipy."""
        r_c = Rotation.from_euler("xyz", q[3:])               # the contract's Rz Ry Rx
        p = turn.inv().apply(q[:3] + r_c.apply(offset / 1e3) - model.home[:3] - offset / 1e3)
        return np.r_[p * 1e3, (turn.inv() * r_c * turn).as_euler("XYZ", degrees=True)]

    pos = np.array(list(_values(ask(c, s, "POS?")).values()))
    assert np.all(np.abs(pos) <= 1e-9)
    assert np.all(np.abs(pos - seen_from_d(np.asarray(d.snapshot().q))) <= 1e-9)
    for line, goal in (("MOV X 2 Y 1", [2, 1, 0, 0, 0, 0]),
                       ("MOV U 1.5 V -1 W 2", [2, 1, 0, 1.5, -1, 2])):
        assert ask(c, s, line) is None and err(c, s) == 0, line
        assert on_target(c, s), line
        got = seen_from_d(np.asarray(d.snapshot().q))
        assert np.all(np.abs(got - goal) <= ONT_TOLERANCE), (line, got)
    assert ask(c, s, "MOV X 0 Y 0 U 0 V 0 W 0") is None
    on_target(c, s)
    assert ask(c, s, "KEN WORK") is None and ask(c, s, "KET?") == "KSW=WORK\n"
    assert ask(c, s, "KEN?") == "WORK=KSW\n"
    assert ask(c, s, "KEN ZERO") is None and ask(c, s, "KRM D") is None and err(c, s) == 0
    assert ask(c, s, "KEN?") == "\n"


def test_coordinate_systems_are_refused_on_a_scene_whose_home_is_rotated(model):
    import dataclasses

    tilted = dataclasses.replace(model, home=np.r_[model.home[:3], 0.02, 0.0, 0.0])
    d, c, s = twin(tilted)
    assert ask(c, s, "KSW WORK X 1") is None and err(c, s) == 0
    assert ask(c, s, "KEN WORK") is None and err(c, s) == E.CMD_NOT_ALLOWED_FOR_STAGE
    assert ask(c, s, "KET?") == "ZERO=ZERO\n"


def test_tra_in_enabled_coordinate_systems(model, capsys, tmp_path):
    """With a work system (5 mm along X, turned 30 deg about Z) and a tool 10 mm above C: TRA?
    along X and W equals `workspace --reach` in the user frame of a scene whose [frames] say the
    same; along U (about the work's X axis, not a line of the contract's angles) the end is
    where the engine's verdict turns, on the GCS line itself (sampled poses all inside, the
    end's neighbour 1e-6 deg on outside): the first limit, a band of cond(J) 1.4 deg wide at
    53.7 deg (which a march of the characteristic length / 16 steps over)."""
    from stewart_fmu.reach import Engine

    d, c, s = twin(model)
    for line in ("KSW WORK X 5 W 30", "KST TIP Z 10", "KEN WORK", "KEN TIP"):
        assert ask(c, s, line) is None and err(c, s) == 0, line
    scene = tmp_path / "frames.toml"
    scene.write_text(SCENE.read_text() + "\n[frames]\nuser = [0.005, 0.0, 0.12, 0.0, 0.0, "
                     f"{math.radians(30.0)!r}]\ntool = [0.0, 0.0, 0.01, 0.0, 0.0, 0.0]\n")
    g0 = np.array(list(_values(ask(c, s, "POS?")).values()))
    step = _reach_step(capsys, scene, [1.0, 0, 0, 0, 0, 0], "user")
    assert abs(_values(ask(c, s, "TRA? X 1"))["X"] - (g0[0] + step * 1e3)) <= 2e-9 * 1e3 + 1e-9
    step = _reach_step(capsys, scene, [0, 0, 0, 0, 0, 1.0], "user")
    assert abs(_values(ask(c, s, "TRA? W 1"))["W"] - (g0[5] + math.degrees(step))) \
        <= math.degrees(2e-9) + 1e-9
    end = _values(ask(c, s, "TRA? U 1"))["U"]
    engine = Engine(model)
    line = np.tile(g0, (201, 1))
    line[:, 3] = np.linspace(g0[3], end, 201)
    assert np.all(engine.binding(c.frame.to_pose(line)) < 0)
    beyond = g0.copy()
    beyond[3] = end + 1e-6
    assert engine.binding(c.frame.to_pose(beyond[None]))[0] >= 0
    assert 53.0 < end < 54.5
    assert err(c, s) == 0
