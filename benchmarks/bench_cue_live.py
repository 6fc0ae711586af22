"""End-to-end latency of the live motion simulator: telemetry sent -> setpoint frame on the
device's side of the link, at 1 kHz, with the device (`stewart-sim device`) and `cue-live` in
processes of their own, as they run for a user. A wall-clock figure: measured here, never
asserted in tests.

    python benchmarks/bench_cue_live.py [--minutes M] [--busy] [--scene SCENE]

The bench sends native telemetry at 1 kHz from this process; each sample's time field is the
monotonic clock (system-wide on Linux) just before it is sent, so the record of `cue-live`
(--record: the telemetry time each setpoint was computed from) names the send time of the
sample behind every setpoint. Between `cue-live` and the device sits a tap: a relay process
that forwards every datagram both ways and stamps each LEG_SETPOINT frame (its sequence
number) on the monotonic clock as it reaches the device's side. The latency of a sample is
the tap's stamp of the first setpoint computed from it less its send time: the socket's wait
for the next tick, the drain, the washout, the envelope, the MAVLink packing and the loopback
hop. Samples a newer one superseded within a tick are counted, not timed. With --busy two
processes spin for the whole run (both cores of the reference machine kept busy).

The vehicle: a gentle forward and lateral specific force (0.5 m/s^2 at 0.2 and 0.13 Hz) with a
small yaw rate, well inside the envelope, so the path measured is the one every sample takes.
"""
from __future__ import annotations

import argparse
import csv
import math
import multiprocessing as mp
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hil import mavlink_stewart as ms
from hil.spawn import device_process, parse_udp
from stewart_sim.live.vehicle_datagrams import TelemetrySample, encode

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "motion_simulator.toml"
RATE = 1000.0               # Hz: telemetry
SEQ_OFFSET = struct.calcsize("<Q6d6d")   # LEG_SETPOINT's sequence in its payload
MAX_TAPS = 2_000_000        # tap stamps kept (33 min at 1 kHz)
START_TIMEOUT = 60.0        # s for cue-live to say it runs


def _tap(device: tuple[str, int], ready, stop, out_path: str) -> None:
    """The relay: host side on a free loopback port (sent back through `ready`), device side
    connected to the device; LEG_SETPOINT frames stamped (sequence, monotonic s)."""
    host = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    host.bind(("127.0.0.1", 0))
    dev = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    dev.connect(device)
    ready.send(host.getsockname()[1])
    peer = None
    stamps = np.zeros((MAX_TAPS, 2))
    n = 0
    while not stop.is_set():
        r, _, _ = select.select([host, dev], [], [], 0.05)
        if host in r:
            data, peer = host.recvfrom(4096)
            now = time.monotonic()
            if (len(data) > 10 and data[0] == 0xFD and n < MAX_TAPS
                    and data[7] | data[8] << 8 | data[9] << 16 == ms.MAVLINK_MSG_ID_LEG_SETPOINT):
                payload = data[10:10 + data[1]] + bytes(SEQ_OFFSET + 4)
                stamps[n] = struct.unpack_from("<I", payload, SEQ_OFFSET)[0], now
                n += 1
            dev.send(data)
        if dev in r:
            data = dev.recv(4096)
            if peer is not None:
                host.sendto(data, peer)
    np.save(out_path, stamps[:n])


def _spin(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


def _vehicle(t: float) -> TelemetrySample:
    f = (0.5 * math.sin(2 * math.pi * 0.2 * t), 0.5 * math.sin(2 * math.pi * 0.13 * t), 9.81)
    return TelemetrySample(time.monotonic(), f, (0.0, 0.0, 0.05 * math.sin(2 * math.pi * 0.1 * t)))


def _send(port: int, seconds: float) -> int:
    """Native telemetry at RATE to 127.0.0.1:port for `seconds` (sleep, then spin to each due
    time); returns the datagrams sent."""
    from hil.timing import wait_until

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.connect(("127.0.0.1", port))
    start = time.monotonic()
    n = int(seconds * RATE)
    for k in range(n):
        wait_until(start + k / RATE, time.monotonic, lambda left: time.sleep(max(left, 0.0)))
        sample = _vehicle(k / RATE)
        try:
            s.send(encode(sample))
        except (BlockingIOError, ConnectionRefusedError):
            pass
    s.close()
    return n


def _free_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _read_record(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(sequence, telemetry time) of every setpoint cue-live recorded."""
    with path.open(newline="") as fh:
        rows = csv.reader(fh)
        header = next(rows)
        i, j = header.index("seq"), header.index("t_telemetry")
        data = np.array([(float(r[i]), float(r[j])) for r in rows])
    return data[:, 0], data[:, 1]


def run(minutes: float, busy: bool, scene: Path) -> None:
    seconds = 60.0 * minutes
    spinners = []
    with tempfile.TemporaryDirectory() as tmp, device_process(scene, "udp") as first:
        device = parse_udp(first)
        recv_end, send_end = mp.Pipe(duplex=False)
        stop = mp.Event()
        taps = os.path.join(tmp, "taps.npy")
        tap = mp.Process(target=_tap, args=(device, send_end, stop, taps), daemon=True)
        tap.start()
        tap_port = recv_end.recv()
        port = _free_port()
        record = Path(tmp) / "record.csv"
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        live = subprocess.Popen(
            [sys.executable, "-m", "stewart_sim", "cue-live", str(scene), "--telemetry",
             f"udp://127.0.0.1:{port}", "--device", f"udp:127.0.0.1:{tap_port}",
             "--telemetry-rate", f"{RATE:g}", "--duration", f"{seconds + 2.0:g}",
             "--record", str(record)],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True, env=env)
        try:
            ready, _, _ = select.select([live.stdout], [], [], START_TIMEOUT)
            line = live.stdout.readline() if ready else ""
            if not line.startswith("cue-live:"):
                raise SystemExit(f"cue-live did not start: {line!r} {live.stderr.read()[-2000:]}")
            if busy:
                spinners = [mp.Process(target=_spin, args=(seconds + 10.0,), daemon=True)
                            for _ in range(2)]
                for p in spinners:
                    p.start()
            time.sleep(0.5)
            sent = _send(port, seconds)
            out, err = live.communicate(timeout=seconds + 120.0)
        finally:
            if live.poll() is None:
                live.send_signal(signal.SIGINT)
                live.wait(30)
            for p in spinners:
                p.terminate()
                p.join(5)
            stop.set()
            tap.join(30)
        if live.returncode != 0:
            raise SystemExit(f"cue-live exited {live.returncode}: {err[-2000:]}")
        stamps = np.load(taps)
        seq, t_tel = _read_record(record)
    # the first setpoint computed from each sample: where t_telemetry changes
    by_seq = dict(zip(stamps[:, 0].astype(np.int64).tolist(), stamps[:, 1].tolist()))
    new = np.flatnonzero(np.isfinite(t_tel) & (np.diff(t_tel, prepend=np.nan) != 0))
    lat = np.array([by_seq[int(seq[i])] - t_tel[i] for i in new if int(seq[i]) in by_seq])
    p = np.percentile(lat, [50, 99, 99.9]) * 1e3
    print(f"cue-live end-to-end latency, {minutes:g} min at {RATE:g} Hz"
          f"{' with both cores busy' if busy else ' quiet'}: {sent} samples sent, "
          f"{len(lat)} timed (the rest superseded within a tick or lost)")
    print("| p50 | p99 | p99.9 | max |")
    print("|---:|---:|---:|---:|")
    print(f"| {p[0]:.3f} ms | {p[1]:.3f} ms | {p[2]:.3f} ms | {lat.max() * 1e3:.3f} ms |")
    for line in out.splitlines():
        if line.startswith(("telemetry:", "latency", "ticks:", "envelope:", "device:")):
            print(f"  {line}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--busy", action="store_true")
    parser.add_argument("--scene", type=Path, default=SCENE)
    args = parser.parse_args()
    run(args.minutes, args.busy, args.scene)


if __name__ == "__main__":
    main()
