"""The emulated device as a process of its own (`stewart-sim device`), as the hardware would be.

A device served in a thread of the host's process shares the GIL with the host's loop, so in real
time each side's stalls show up as the other's latency; in its own process it keeps its 1 kHz
clock the way the real micro-manipulator does. The device prints where it listens on its first
line (``udp 127.0.0.1:PORT`` or the pseudo-terminal's path); `device_process` reads that line,
yields it, and stops the device with SIGINT (then SIGKILL) when the block ends. The device warms
every path it will run (`hil.warmup`) before it prints that line, so the first setpoint and the
first ticks after it cost what later ones do. With a truth scene (`--truth TRUE.toml`,
hil.truth) the device's plant is the truth's and its sensors are the truth's [sensors] table
(hil.sensors); without one, the scene's [sensors] table.
"""
from __future__ import annotations

import argparse
import contextlib
import gc
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Iterator

from controller.config import ControllerConfig, controller_config
from hil.device import Device
from hil.address import host_port
from hil.errors import LinkError
from hil.link import pty_pair, udp_server
from hil.observe import Latest
from hil.sensors import SensorConfig, sensor_config
from hil.serve import loopback_address, serve
from hil.warmup import warm_up
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model
from stewart_fmu.scene import load_scene

START_TIMEOUT = 60.0   # s: a first run after install compiles the kernels
STOP_TIMEOUT = 5.0
WATCHDOG = 0.2       # s: default safe-stop time without a valid setpoint while armed


def device_command(scene: str | Path, link: str, lockstep: bool,
                   truth: str | Path | None = None) -> list[str]:
    """argv of `python -m hil.spawn SCENE (--udp 127.0.0.1:0 | --pty | --gcs 127.0.0.1:0)
    [--lockstep] [--truth TRUE.toml]` (what `stewart-sim device` runs)."""
    argv = [sys.executable, "-m", "hil.spawn", str(scene)]
    argv += {"udp": ["--udp", "127.0.0.1:0"], "gcs": ["--gcs", "127.0.0.1:0"]}.get(link, ["--pty"])
    argv += ["--truth", str(truth)] if truth is not None else []
    return argv + (["--lockstep"] if lockstep else [])


@contextlib.contextmanager
def device_process(scene: str | Path, link: str, lockstep: bool = False,
                   start_timeout: float = START_TIMEOUT,
                   truth: str | Path | None = None) -> Iterator[str]:
    """Run the device for `scene` (its plant: `truth`'s when given) over `link` ("udp",
    "serial" or "gcs"); yield its first line."""
    if link not in ("udp", "serial", "gcs"):
        raise LinkError(f"device_process: link must be 'udp', 'serial' or 'gcs', got {link!r}")
    proc = subprocess.Popen(device_command(scene, link, lockstep, truth), stdout=subprocess.PIPE,
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


def parse_gcs(line: str) -> tuple[str, int]:
    """("127.0.0.1", PORT) from the device's first line ``gcs 127.0.0.1:PORT``."""
    kind, _, address = line.partition(" ")
    if kind != "gcs":
        raise LinkError(f"expected 'gcs HOST:PORT' from the device, got {line!r}")
    return gcs_address(address)


def gcs_address(text: str) -> tuple[str, int]:
    """`--gcs HOST:PORT`: a loopback IPv4 address, port 0 for any free one."""
    return host_port(text, "--gcs", loopback_only="the GCS server listens on loopback only")


def signing_key(text: str | None) -> bytes | None:
    """The 32-byte MAVLink 2 signing key from 64 hex digits (None: unsigned)."""
    if text is None:
        return None
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != 32:
        raise LinkError("--signing-key must be 64 hex digits (32 bytes)")
    return key


def serve_device(model: Model, config: ControllerConfig, udp: str | None,
                 watchdog: float = WATCHDOG,
                 lockstep: bool = False, key_hex: str | None = None, *,
                 observer: Latest | None = None,
                 ready: Callable[[], None] | None = None,
                 truth: Model | None = None, sensors: SensorConfig | None = None,
                 gcs: str | None = None, pty: bool = False) -> None:
    """Serve the emulated device for `model` (its [controller] table: `config`) on loopback UDP
    (`udp`, "127.0.0.1:PORT") or, with udp None, a pseudo-terminal (with `gcs`: only when `pty`
    is True), until SIGINT or SIGTERM. The first line on stdout says where it
    listens; a summary goes to stderr when it stops. With `observer` the device publishes its
    snapshots there (`Device.observe`, hil.observe); `ready` is called once that first line is
    out, just before the loop starts (the caller announces what it serves beside the device).
    `truth`: the hidden true scene of the plant (hil.truth); `sensors`: what the device reports
    (hil.sensors; None: ideal). With `gcs` ("127.0.0.1:PORT") the device also speaks PI's GCS
    2.0 on that loopback TCP port (hil.gcs), in real time: beside the MAVLink link when `udp` is
    given or `pty` is True, alone otherwise; its line ``gcs 127.0.0.1:PORT`` follows the MAVLink
    one (or is the first, alone)."""
    key = signing_key(key_hex)
    if gcs is not None and lockstep:
        raise LinkError("--gcs runs the device in real time: not with --lockstep")
    gcs_at = gcs_address(gcs) if gcs is not None else None
    address = loopback_address(udp) if udp is not None else None
    device = Device(model, config, watchdog=watchdog, signing_key=key, lockstep=lockstep,
                    truth=truth, sensors=sensors)
    if observer is not None:
        device.observe(observer)
    # every path run once before the ready line (hil.warmup)
    warm = warm_up(model, config, truth=truth, sensors=sensors)
    gc.collect()
    gc.freeze()                     # what exists now is never scanned again by the collector
    keep = None  # the pty's slave end, held open so the master never sees a hang-up
    transport = None
    if address is not None:
        transport = udp_server(*address)
        first = f"udp {transport.address[0]}:{transport.address[1]}"
    elif pty or gcs_at is None:
        transport, keep = pty_pair()
        first = keep.name
    if gcs_at is not None:
        from hil.gcs.tcp_transport import gcs_link       # only for --gcs
        try:
            transport = gcs_link(device, *gcs_at, inner=transport)
        except LinkError:
            if transport is not None:
                transport.close()
            raise
        line = "gcs {}:{}".format(*transport.server.address)
        first = line if transport.inner is None else f"{first}\n{line}"
    stop = threading.Event()
    handlers = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        print(first, flush=True)
        print(f"device: {model.name}, {device.rate:g} Hz, "
              f"{'lockstep' if lockstep else 'real time'}, watchdog {watchdog:g} s"
              f"{f', plant from {truth.source}' if truth is not None else ''}"
              f"{'' if sensors is None or sensors.ideal else ', sensors per [sensors]'}"
              f"{', signed' if key else ''}, warmed in {warm:.3g} s; Ctrl-C stops",
              file=sys.stderr, flush=True)
        if ready is not None:
            ready()
        stats = serve(device, transport, not lockstep, stop)
    finally:
        for sig, old in handlers.items():
            signal.signal(sig, old)
        transport.close()
        if keep is not None:
            keep.close()
    c = device.counters
    print(f"device stopped: {stats.ticks} ticks in {stats.wall:.3g} s, {stats.overruns} overruns, "
          f"{stats.messages_in} messages in, {stats.messages_out} out, "
          f"{device.link_errors} bad frames, {c.setpoints_refused} setpoints refused, "
          f"{c.flood_dropped} flood datagrams dropped"
          + (f"; ticks {stats.late.text()}" if stats.late is not None else ""),
          file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    """The device process: `python -m hil.spawn SCENE [--udp 127.0.0.1:PORT | --pty]
    [--gcs 127.0.0.1:PORT] [--watchdog S] [--lockstep] [--signing-key HEX] [--truth TRUE.toml]`,
    one link at least (`stewart-sim device` with its help)."""
    parser = argparse.ArgumentParser(prog="python -m hil.spawn")
    parser.add_argument("scene")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--udp")
    where.add_argument("--pty", action="store_true")
    parser.add_argument("--gcs")
    parser.add_argument("--watchdog", type=float, default=WATCHDOG)
    parser.add_argument("--lockstep", action="store_true")
    parser.add_argument("--signing-key")
    parser.add_argument("--truth")
    args = parser.parse_args(argv)
    if args.udp is None and not args.pty and args.gcs is None:
        parser.error("one of --udp, --pty, --gcs is required")
    try:
        model = load_scene(args.scene)
        truth = load_scene(args.truth) if args.truth is not None else None   # checked by Device
        serve_device(model, controller_config(model), args.udp, args.watchdog, args.lockstep,
                     args.signing_key, truth=truth,
                     sensors=sensor_config(truth if truth is not None else model), gcs=args.gcs,
                     pty=args.pty)
    except StewartError as exc:
        print(f"device: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
