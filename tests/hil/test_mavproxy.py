"""A real ground station against the device: MAVProxy (console only) through a scripted run.

MAVProxy is installed for this test only, without its GUI dependencies: ``pip install --no-deps
--target <pytest cache>/mavproxy-<version> MAVProxy==<version>`` (the console modules used here,
link, param, cmdlong and arm, need only pymavlink, pyserial and numpy, which the project
installs). It runs with the project's interpreter through ``mavproxy_stewart.py`` (our dialect
registered as ``--dialect=stewart``). The test is skipped, saying why, only when that install
fails (no package index). Each step waits (bounded) for MAVProxy's answer before the next one;
what is asserted is what the device must do, not how fast: no loss in MAVProxy's link
statistics, all parameters fetched, one set, arm, return to launch, disarm.
"""
from __future__ import annotations

import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("pymavlink")

from controller.config import controller_config  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.link import udp_server  # noqa: E402
from hil.serve import serve_in_thread  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
WRAPPER = Path(__file__).with_name("mavproxy_stewart.py")
MAVPROXY_VERSION = "1.8.75"
STEP_TIMEOUT = 20.0   # s: the longest wait for one answer (a bound, not a measurement)


@pytest.fixture(scope="module")
def mavproxy_path(request, tmp_path_factory) -> Path:
    cache = getattr(request.config, "cache", None)   # pytest's cache, kept between runs
    target = (Path(cache.mkdir(f"mavproxy-{MAVPROXY_VERSION}")) if cache is not None
              else tmp_path_factory.mktemp(f"mavproxy-{MAVPROXY_VERSION}"))
    if not (target / "MAVProxy" / "mavproxy.py").is_file():
        cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--upgrade",
               "--target", str(target), f"MAVProxy=={MAVPROXY_VERSION}"]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        if proc.returncode != 0 or not (target / "MAVProxy" / "mavproxy.py").is_file():
            pytest.skip(f"MAVProxy {MAVPROXY_VERSION} cannot be installed "
                        f"(pip install --no-deps failed): {proc.stderr.strip()[-500:]}")
    return target


class Console:
    """MAVProxy's console over pipes: send a command, wait (bounded) for a pattern."""

    def __init__(self, argv: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, env=env)
        self.text = ""
        self._pos = 0

    def send(self, line: str) -> None:
        self.proc.stdin.write(line.encode() + b"\n")
        self.proc.stdin.flush()

    def expect(self, pattern: str, timeout: float = STEP_TIMEOUT) -> re.Match:
        rx = re.compile(pattern)
        deadline = time.monotonic() + timeout
        while True:
            m = rx.search(self.text, self._pos)
            if m:
                self._pos = m.end()
                return m
            left = deadline - time.monotonic()
            if left <= 0 or self.proc.poll() is not None:
                raise AssertionError(f"MAVProxy: no {pattern!r} within {timeout:g} s; "
                                     f"output:\n{self.text[-3000:]}")
            ready, _, _ = select.select([self.proc.stdout], [], [], min(left, 0.1))
            if ready:
                chunk = os.read(self.proc.stdout.fileno(), 65536)
                self.text += chunk.decode(errors="replace")

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.send("exit")
            except OSError:
                pass
            self.proc.stdin.close()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self.proc.stdout.close()


def test_mavproxy_scripted_run(mavproxy_path, tmp_path):
    model = load_scene(SCENE)
    device = Device(model, controller_config(model))
    server = udp_server("127.0.0.1", 0)
    thread, stop, result = serve_in_thread(device, server, poll=0.01)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(mavproxy_path), str(ROOT)]))
    argv = [sys.executable, str(WRAPPER), f"--master=udpout:127.0.0.1:{server.address[1]}",
            "--default-modules=link,param,cmdlong,arm", f"--state-basedir={tmp_path}",
            "--nodtr"]
    con = Console(argv, env)
    try:
        con.expect(r"online system 1")
        con.send("param fetch")
        n = int(con.expect(r"Received (\d+) parameters").group(1))
        assert n == len(device.params)
        con.send("param set SR_LEG_STATE 200")
        deadline = time.monotonic() + STEP_TIMEOUT
        while True:   # MAVProxy shows its cache: ask until the device's PARAM_VALUE is in it
            con.send("param show SR_LEG_STATE")
            if float(con.expect(r"SR_LEG_STATE\s+([-\d.]+)").group(1)) == 200.0:
                break
            assert time.monotonic() < deadline, "the new SR_LEG_STATE never came back"
            time.sleep(0.1)
        assert device.rates["LEG_STATE"] == 200.0
        con.send("arm throttle")
        con.expect(r"COMPONENT_ARM_DISARM: ACCEPTED")
        con.expect(r"ARMED")
        assert device.armed
        con.send("long NAV_RETURN_TO_LAUNCH")
        con.expect(r"NAV_RETURN_TO_LAUNCH: ACCEPTED")
        con.expect(r"AP: homing")
        con.send("disarm")
        con.expect(r"COMPONENT_ARM_DISARM: ACCEPTED")
        con.expect(r"DISARMED")
        assert not device.armed
        con.send("link")
        m = con.expect(r"link 1 OK \((\d+) packets, \d+ bytes, [\d.]+s delay, (\d+) lost, "
                       r"([\d.]+)% loss")
        packets, lost, loss = int(m.group(1)), int(m.group(2)), float(m.group(3))
        print(f"\nMAVProxy: {packets} packets, {lost} lost ({loss}%), "
              f"{n} parameters, armed, homed, disarmed")
        assert packets > 0 and lost == 0 and loss == 0.0
    finally:
        con.close()
        stop.set()
        thread.join(5)
        server.close()
    assert not thread.is_alive()
    c = device.counters
    assert c.params_set == 1 and c.commands >= 3 and c.commands_refused == 0
    assert device.link_errors == 0
