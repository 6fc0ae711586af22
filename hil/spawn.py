"""The emulated device as a process of its own (`stewart-sim device`), as the hardware would be.

A device served in a thread of the host's process shares the GIL with the host's loop, so in real
time each side's stalls show up as the other's latency; in its own process it keeps its 1 kHz
clock the way the real micro-manipulator does. The device prints where it listens on its first
line (``udp 127.0.0.1:PORT`` or the pseudo-terminal's path); `device_process` reads that line,
yields it, and stops the device with SIGINT (then SIGKILL) when the block ends.
"""
from __future__ import annotations

import contextlib
import select
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Iterator

from hil.errors import LinkError
from hil.serve import loopback_address

START_TIMEOUT = 60.0   # s: a first run after install compiles the kernels
STOP_TIMEOUT = 5.0


def device_command(scene: str | Path, link: str, lockstep: bool) -> list[str]:
    """argv of `stewart-sim device SCENE (--udp 127.0.0.1:0 | --pty) [--lockstep]`."""
    argv = [sys.executable, "-c", "import sys; from stewart_fmu.cli import main; sys.exit(main())",
            "device", str(scene)]
    argv += ["--udp", "127.0.0.1:0"] if link == "udp" else ["--pty"]
    return argv + (["--lockstep"] if lockstep else [])


@contextlib.contextmanager
def device_process(scene: str | Path, link: str, lockstep: bool = False,
                   start_timeout: float = START_TIMEOUT) -> Iterator[str]:
    """Run the device for `scene` over `link` ("udp" or "serial"); yield its first line."""
    if link not in ("udp", "serial"):
        raise LinkError(f"device_process: link must be 'udp' or 'serial', got {link!r}")
    proc = subprocess.Popen(device_command(scene, link, lockstep), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        yield _first_line(proc, start_timeout)
    finally:
        _stop(proc)


def _first_line(proc: subprocess.Popen, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.1)
        if ready:
            line = proc.stdout.readline().strip()
            if line:
                return line
        if proc.poll() is not None:
            raise LinkError(f"the device exited with status {proc.returncode} before it listened: "
                            f"{proc.stderr.read().strip()[-2000:]}")
    raise LinkError(f"the device did not say where it listens within {timeout:g} s")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(STOP_TIMEOUT)
    for stream in (proc.stdout, proc.stderr):
        stream.close()


def parse_udp(line: str) -> tuple[str, int]:
    """("127.0.0.1", PORT) from the device's first line ``udp 127.0.0.1:PORT``."""
    kind, _, address = line.partition(" ")
    if kind != "udp":
        raise LinkError(f"expected 'udp HOST:PORT' from the device, got {line!r}")
    return loopback_address(address)
