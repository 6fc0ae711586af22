"""Jitter and deadline misses of both real-time loops, and the tracking error, quiet and loaded.

    python benchmarks/bench_realtime_jitter.py [--runs N] [--busy K] [--view [HZ]]

Each run starts the device in its own process (`python -m hil.spawn SCENE --udp 127.0.0.1:0`,
what `run --link udp --mode realtime` does), runs `hil.client.run_realtime` over UDP (0.5 s out
and back, setpoints and states at 1 kHz) and stops the device with SIGINT; the device prints the
lateness of its ticks over its whole life (hil.timing.Lateness) on stderr when it stops. The
host's lateness is that of its setpoints (LinkSummary.send_late). A deadline miss is a tick or a
setpoint that started one period (1 ms) or more after its due time. "loaded" runs K busy loops
(default: one per core) in child processes for the duration of the runs, then stops them.
With --view every run is made twice, alternating, through `stewart-sim device` (`python -m
stewart_sim device`): without and with `--view 0`, a child process polling the view's /state at
HZ (default 30, a page's poll) over one keep-alive connection; the table gets the snapshots per
second the poller saw change (the live update rate).
Wall-clock figures: measured here, never asserted in tests.
"""
from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing as mp
import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from controller.config import controller_config
from controller.moves import move_and_hold
from hil.client import Client, connect_device, link_reference, run_realtime
from hil.spawn import device_command
from stewart_fmu import load_scene

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"
DEVICE_RE = re.compile(r"late p50 (\d+) us, p99 (\d+) us, p99\.9 (\d+) us, max (\d+) us, "
                       r"(\d+) deadline misses of (\d+)")


def _busy(until: float) -> None:
    x = 0
    while time.monotonic() < until:
        x += 1


def _poll_view(port: int, hz: float, stop, seen) -> None:
    """GET /state at `hz` until `stop`; seen[0]: distinct snapshots, seen[1]: their time span."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    ticks, first, last = set(), None, None
    while not stop.wait(1.0 / hz):
        conn.request("GET", "/state")
        doc = json.loads(conn.getresponse().read())
        ticks.add(doc["tick"])
        first = doc["t"] if first is None else first
        last = doc["t"]
    conn.close()
    seen[0], seen[1] = len(ticks), (last or 0.0) - (first or 0.0)


def one_run(ref, argv: list[str] | None = None, poll: float = 0.0) -> dict:
    proc = subprocess.Popen(argv or device_command(SCENE, "udp", False), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    poller, stop, seen = None, mp.Event(), mp.Array("d", 2)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 60)
        first = proc.stdout.readline().strip()
        if poll > 0:
            port = int(proc.stdout.readline().strip().rsplit(":", 1)[1].rstrip("/"))
            poller = mp.Process(target=_poll_view, args=(port, poll, stop, seen), daemon=True)
            poller.start()
            time.sleep(0.5)     # the poller's connection is up before the run
        client = Client(connect_device("udp", first)[0])
        try:
            s = run_realtime(client, ref).summary
        finally:
            client.close()
    finally:
        if poller is not None:
            stop.set()
            poller.join(5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    m = DEVICE_RE.search(err)
    dev = [float(x) for x in m.groups()] if m else [np.nan] * 6
    return {"dev": dev, "host": [x * 1e6 for x in s.send_late] + [s.deadline_misses, s.sent],
            "rms": s.rms * 1e6, "max": s.max * 1e6, "lost": s.lost,
            "updates": seen[0] / seen[1] if seen[1] > 0 else np.nan}


def view_runs(ref, runs: int, hz: float) -> list[str]:
    """Alternating runs of `stewart-sim device` without and with --view (the /state poller)."""
    base = [sys.executable, "-m", "stewart_sim", "device", str(SCENE), "--udp", "127.0.0.1:0"]
    rows: dict[str, list[dict]] = {"device": [], "device --view": []}
    for _ in range(runs):
        rows["device"].append(one_run(ref, base))
        rows["device --view"].append(one_run(ref, base + ["--view", "0"], hz))
    out = []
    for name, rs in rows.items():
        for r in rs:
            d = r["dev"]
            upd = "" if np.isnan(r["updates"]) else f"{r['updates']:.1f}"
            out.append(f"| {name} | {d[0]:.0f} | {d[1]:.0f} | {d[2]:.0f} | {d[3]:.0f} "
                       f"| {d[4]:.0f} / {d[5]:.0f} | {r['rms']:.1f} | {upd} |")
    med = {n: np.median([r["dev"][:2] for r in rs], axis=0) for n, rs in rows.items()}
    ratio = med["device --view"] / med["device"]
    out.append(f"| ratio of medians | {ratio[0]:.2f} | {ratio[1]:.2f} | | | | | |")
    return out


def condition(name: str, ref, runs: int, busy: int) -> list[str]:
    procs = []
    if busy:
        until = time.monotonic() + 60.0 * runs   # bounded even if this process dies
        procs = [mp.Process(target=_busy, args=(until,), daemon=True) for _ in range(busy)]
        for p in procs:
            p.start()
    rows = []
    try:
        for _ in range(runs):
            rows.append(one_run(ref))
    finally:
        for p in procs:
            p.terminate()
            p.join(5)
    out = []
    for r in rows:
        d, h = r["dev"], r["host"]
        out.append(f"| {name} | device ticks | {d[0]:.0f} | {d[1]:.0f} | {d[2]:.0f} | {d[3]:.0f} "
                   f"| {d[4]:.0f} / {d[5]:.0f} | {r['rms']:.1f} | {r['max']:.1f} |")
        out.append(f"| {name} | host setpoints | {h[0]:.0f} | {h[1]:.0f} | {h[2]:.0f} | {h[3]:.0f} "
                   f"| {h[4]:.0f} / {h[5]:.0f} | | |")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--busy", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--view", nargs="?", type=float, const=30.0, default=None, metavar="HZ",
                        help="compare device ticks without and with --view (poll /state at HZ)")
    args = parser.parse_args()
    model = load_scene(SCENE)
    config = controller_config(model)
    ref = link_reference(model, config, move_and_hold(model, config.rate, 0.2, 0.05, back=True,
                                                      fraction=0.2))
    if args.view is not None:
        print(f"{os.cpu_count()} cores; {args.runs} runs each, alternating; /state polled at "
              f"{args.view:g} Hz")
        print("| device | tick late p50 (us) | p99 (us) | p99.9 (us) | max (us) | misses / count "
              "| RMS err (um) | view updates (1/s) |")
        print("|---|---|---|---|---|---|---|---|")
        for line in view_runs(ref, args.runs, args.view):
            print(line)
        return
    print(f"{os.cpu_count()} cores; {args.runs} runs per condition; loaded: {args.busy} busy loops")
    print("| load | loop | p50 (us) | p99 (us) | p99.9 (us) | max (us) | misses / count "
          "| RMS err (um) | max err (um) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for line in condition("quiet", ref, args.runs, 0) + condition("loaded", ref, args.runs,
                                                                  args.busy):
        print(line)


if __name__ == "__main__":
    main()
