"""The live view of the emulated device (stewart_sim.view.live_server, `stewart-sim device --view`):
loopback only, the page and /state with their content types, /state following the device as
setpoints arrive, the command's lines, port checks and its stop on SIGINT. Every wait is
bounded; nothing asserts a wall-clock time."""
from __future__ import annotations

import http.client
import json
import select
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.observe import Latest, Snapshot  # noqa: E402
from stewart_fmu.kinematics import condition_number, inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from stewart_sim.cli import main  # noqa: E402
from stewart_sim.scene.load import scene_of  # noqa: E402
from stewart_sim.view.live_server import (  # noqa: E402
    LiveView, ViewError, live_page, state_document)
from tests.helpers import ROOT  # noqa: E402
from tests.hil.test_device import SCENE, arm, setpoint  # noqa: E402

OFFSET = np.array([0.001, -0.0005, 0.001, 0.01, -0.01, 0.02])   # m, rad: inside the stroke


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def get(port: int, path: str, host: str = "127.0.0.1", headers: dict | None = None
        ) -> tuple[int, str, bytes]:
    """(status, content type, body) of GET http://host:port/path."""
    conn = http.client.HTTPConnection(host, port, timeout=5)
    try:
        conn.request("GET", path, headers=headers or {})
        r = conn.getresponse()
        return r.status, r.getheader("Content-Type"), r.read()
    finally:
        conn.close()


def state(port: int) -> dict:
    status, kind, body = get(port, "/state")
    assert status == 200 and kind == "application/json"
    return json.loads(body)


def other_addresses() -> set[str]:
    """This machine's IPv4 addresses that are not loopback (the interface a default route
    leaves by, and the host name's addresses); empty on a machine without a network."""
    found = set()
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(("192.0.2.1", 9))           # TEST-NET: no packet is sent by a UDP connect
        found.add(probe.getsockname()[0])
    except OSError:
        pass
    finally:
        probe.close()
    try:
        found.update(i[4][0] for i in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET))
    except OSError:
        pass
    return {a for a in found if not a.startswith("127.") and a != "0.0.0.0"}


def refused(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=2):
            return False
    except OSError:
        return True


def test_answers_on_127_0_0_1_only(model):
    with LiveView(live_page(model, scene_of(model).controller), Latest(), 0) as view:
        view.start()
        host, port = view.address
        assert host == "127.0.0.1" and view.url == f"http://127.0.0.1:{port}/"
        assert get(port, "/")[0] == 200
        # another loopback address of this machine: bound to 127.0.0.1, not to a wildcard
        assert refused("127.0.0.2", port)
        for address in other_addresses():
            assert refused(address, port), address
        kept = http.client.HTTPConnection("127.0.0.1", port, timeout=5)   # a page's keep-alive
        kept.request("GET", "/state")
        assert kept.getresponse().read()
    assert refused("127.0.0.1", port)            # closed with the block
    assert kept.sock.recv(1) == b""              # and the open connection ended (EOF)
    kept.close()


def test_page_state_and_refusals_have_their_content_types(model):
    with LiveView(live_page(model, scene_of(model).controller), Latest(), 0) as view:
        view.start()
        port = view.address[1]
        status, kind, body = get(port, "/")
        assert (status, kind) == (200, "text/html; charset=utf-8")
        assert b"/state" in body                  # the page polls the state
        assert get(port, "/index.html")[:2] == (200, "text/html; charset=utf-8")
        doc = state(port)
        assert doc["t"] is None and doc["q"] is None    # before the device's first snapshot
        assert get(port, "/nothing")[0] == 404
        # a page elsewhere reaching 127.0.0.1 through its own host name (DNS rebinding)
        assert get(port, "/state", headers={"Host": f"example.com:{port}"})[0] == 403
        assert get(port, "/", headers={"Host": f"localhost:{port}"})[0] == 200


def test_state_follows_the_device_as_setpoints_arrive(model):
    """The device ticked by hand (device time): /state is its newest snapshot, the reference
    pose appears with the setpoint and the platform's pose converges to it; lengths and cond
    are those of the published pose."""
    dev = Device(model, watchdog=2.0)
    latest = Latest()
    dev.observe(latest, hz=100.0)
    target = np.asarray(model.home, dtype=float) + OFFSET
    with LiveView(live_page(model, scene_of(model).controller), latest, 0) as view:
        view.start()
        port = view.address[1]
        s0 = state(port)
        assert s0["t"] == 0.0 and s0["q_ref"] is None and s0["armed"] is False
        assert np.allclose(s0["q"], model.home, atol=1e-12)
        dev.receive(arm())
        dev.receive(setpoint(0, inverse_kinematics(model, target).lengths))
        for _ in range(20):
            dev.tick()
        s1 = state(port)
        assert s1["t"] == pytest.approx(0.02) and s1["armed"] is True
        assert np.max(np.abs(np.array(s1["q_ref"]) - target)) < 1e-9
        moved = np.max(np.abs(np.array(s1["q"]) - model.home))
        assert moved > 0.1 * np.max(np.abs(OFFSET))              # on its way
        for _ in range(980):
            dev.tick()
        s2 = state(port)
        assert s2["t"] == pytest.approx(1.0)
        assert np.max(np.abs(np.array(s2["q"]) - target)) < 1e-6   # arrived
        q = np.array(s2["q"])
        assert np.allclose(s2["lengths"], inverse_kinematics(model, q).lengths, rtol=0, atol=1e-12)
        assert s2["cond"] == pytest.approx(condition_number(model, q), rel=1e-12)
        assert len(s2["forces"]) == 6 and all(np.isfinite(s2["forces"]))


def test_state_carries_the_specific_forces_at_the_head_when_published(model):
    """f_vehicle and f_delivered: null before the first snapshot and when a snapshot has none
    (the device alone), the published vectors as they are otherwise, a non-finite one null;
    /state serves them."""
    assert state_document(None)["f_vehicle"] is None
    assert state_document(None)["f_delivered"] is None
    home = tuple(float(v) for v in model.home)
    plain = Snapshot(tick=1, t=0.001, q=home, q_ref=None, lengths=(0.1,) * 6,
                     forces=(0.0,) * 6, cond=2.0, armed=True)
    doc = state_document(plain)
    assert doc["f_vehicle"] is None and doc["f_delivered"] is None
    cued = Snapshot(tick=2, t=0.002, q=home, q_ref=None, lengths=(0.1,) * 6, forces=(0.0,) * 6,
                    cond=2.0, armed=True, f_vehicle=(1.5, -0.25, 9.81),
                    f_delivered=(0.75, float("nan"), 9.5))
    doc = state_document(cued)
    assert doc["f_vehicle"] == [1.5, -0.25, 9.81]
    assert doc["f_delivered"] == [0.75, None, 9.5]
    latest = Latest()
    latest.publish(cued)
    with LiveView(live_page(model, scene_of(model).controller), latest, 0) as view:
        view.start()
        served = state(view.address[1])
    assert served["f_vehicle"] == [1.5, -0.25, 9.81] and served["f_delivered"] == [0.75, None, 9.5]


def test_a_taken_port_is_one_line_and_status_2(model, capsys):
    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    holder.bind(("127.0.0.1", 0))
    holder.listen(1)
    port = holder.getsockname()[1]
    try:
        with pytest.raises(ViewError, match=f"127.0.0.1:{port}"):
            LiveView(live_page(model, scene_of(model).controller), Latest(), port)
        assert main(["device", str(SCENE), "--udp", "127.0.0.1:0", "--view", str(port)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"--view: cannot listen on 127.0.0.1:{port}" in err[0], err
    finally:
        holder.close()


@pytest.mark.parametrize("bad", ["70000", "-1", "http", "1.5"])
def test_a_bad_port_is_a_usage_error(bad, capsys):
    assert main(["device", str(SCENE), "--udp", "127.0.0.1:0", "--view", bad]) == 2
    assert "--view" in capsys.readouterr().err


def _line(proc: subprocess.Popen, timeout: float = 60) -> str:
    assert select.select([proc.stdout], [], [], timeout)[0], "the device printed nothing"
    return proc.stdout.readline().strip()


def test_cli_device_view_prints_its_address_follows_setpoints_and_stops_on_sigint(model):
    # `python -m stewart_sim` from the tree under test (the console script's twin)
    proc = subprocess.Popen([sys.executable, "-m", "stewart_sim", "device", str(SCENE), "--udp",
                             "127.0.0.1:0", "--watchdog", "5", "--view", "0"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    link = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        first, second = _line(proc), _line(proc)
        assert first.startswith("udp 127.0.0.1:")
        assert second.startswith("view: http://127.0.0.1:") and second.endswith("/")
        port = int(second.rsplit(":", 1)[1].rstrip("/"))
        status, kind, _ = get(port, "/")
        assert (status, kind) == (200, "text/html; charset=utf-8")
        s0 = state(port)
        assert np.allclose(s0["q"], model.home, atol=1e-12) and s0["q_ref"] is None
        link.connect(("127.0.0.1", int(first.rsplit(":", 1)[1])))
        mav = ms.MAVLink(None, srcSystem=255, srcComponent=190)
        target = np.asarray(model.home, dtype=float) + OFFSET
        link.send(bytes(arm().pack(mav)))
        link.send(bytes(setpoint(0, inverse_kinematics(model, target).lengths).pack(mav)))
        seen, deadline = s0, time.monotonic() + 20
        while time.monotonic() < deadline:
            seen = state(port)
            if (seen["q_ref"] is not None
                    and np.max(np.abs(np.array(seen["q"]) - target)) < 1e-6):
                break
            time.sleep(0.05)
        assert seen["armed"] and np.max(np.abs(np.array(seen["q_ref"]) - target)) < 1e-9
        assert np.max(np.abs(np.array(seen["q"]) - target)) < 1e-6, seen
        assert seen["t"] > s0["t"]
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
        assert proc.returncode == 0, err           # the device command's status, view or not
        assert "device stopped" in err and "Traceback" not in err
        assert refused("127.0.0.1", port)          # the view went with the device
    finally:
        link.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        for stream in (proc.stdout, proc.stderr):
            stream.close()
