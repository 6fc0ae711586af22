"""The live loop's cost per tick under hostile telemetry timing (`cue-live`'s worst tick).

    python benchmarks/bench_live_hostile.py [--seconds S] [--seed N]

Scene scenes/motion_simulator.toml (1 kHz ticks, the classical washout at 100 Hz). Each pattern
feeds the session (stewart_sim.live.session.LiveSession) S seconds of ticks, its datagrams put
in an in-process queue before each tick, the setpoints going out through the real DeviceOut
(MAVLink packed, sent over loopback UDP to a socket nobody answers). The session runs on its
own time (tick k at k / 1000 s, as run_realtime gives it) with no waits between ticks; the
receiver's drain budget runs on the wall clock, as in `cue-live`. Printed per pattern: the
CPU time of `LiveSession.tick` (time.thread_time: the tick's own work, without the waits for
a core that a shared machine adds) p50 / p99 / max, the wall time's max beside it, the washout
steps one tick took at most and the CPU time of the ticks that took that many (p50, max), the
samples accepted and refused (ahead / out of order,
duplicate and the rest) and the re-anchored ones. The tick period is 1 ms: the CPU max must
stay under it; the wall max is the machine's (its scheduler's stalls) as much as the loop's.
The hostile datagrams start after the first clean sample (the stream has its time line).

Patterns (a clean 100 Hz stream underneath unless said):
  clean             the stream alone
  future once       one datagram 1e6 s past the stream, after 1 s
  future stream     a datagram 1e6 s past the newest one every tick
  creeping ahead    every tick a datagram just inside the line's lead (the fastest a sender
                    may run: the most steps a sample can make without re-anchoring)
  backwards         every tick a datagram 1e3 s behind
  duplicates        every sample repeated 50 times
  bursts            255 valid samples a tick at spread times (newest wins)
  flood             256 garbage datagrams a tick, the clean sample amid them
  gap 0.099 s       the stream with a sample every 0.099 s (just inside the loss timeout)
  worst             the designed worst tick: 256 garbage datagrams every tick, a sample every
                    0.099 s as far ahead as the line allows (the most steps the default loss
                    timeout lets one sample take) before them
  gap 10 steps      --loss-timeout 1: a sample every 0.1 s, each MAX_STEPS (10) washout steps
  random            seeded mix of all the above, per tick
The first tick of each run (its lazy set-up) is left out of the statistics.
"""
from __future__ import annotations

import argparse
import socket
import time
from pathlib import Path

import numpy as np

from hil.client import Client, connect_udp
from hil.timing import gc_frozen
from stewart_sim.live.cue_stream import CueStream
from stewart_sim.live.device_out import DeviceOut
from stewart_sim.live.receiver import AHEAD, TelemetryReceiver
from stewart_sim.live.session import LOSS_TIMEOUT, make_session
from stewart_sim.live.vehicle_datagrams import TelemetrySample, encode
from stewart_sim.scene.load import load
from tests.app.datagrams import Queue

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "motion_simulator.toml"
TELEMETRY_RATE = 100.0


def datagram(t: float, k: int = 0) -> bytes:
    """A valid sample at time t (a gentle push, so the washout has work to do)."""
    return encode(TelemetrySample(t, (1.5 * np.sin(0.5 * t), 0.5, 9.81),
                                  (0.05 * np.cos(0.3 * t), 0.0, 0.02)))


def clean(k: int, rate: float) -> list[bytes]:
    return [datagram(k / rate)] if k % int(rate / TELEMETRY_RATE) == 0 else []


def pattern(name: str, k: int, rate: float, session, rng) -> list[bytes]:
    """The datagrams before tick k."""
    t = k / rate
    base = clean(k, rate)
    newest = session.receiver.last_t
    if name == "clean" or newest is None:
        return base
    if name == "future once":
        return base + ([datagram(newest + 1e6)] if k == int(rate) else [])
    if name == "future stream":
        return base + [datagram(newest + 1e6)]
    if name == "creeping ahead":
        line = session.receiver.line(t)
        return [datagram((line if np.isfinite(line) else t) + AHEAD * 0.999)]
    if name == "backwards":
        return base + [datagram(t - 1e3)]
    if name == "duplicates":
        return base * 50
    if name == "bursts":
        return [datagram(t - 0.01 + 0.01 * i / 255) for i in range(255)] + base
    if name == "flood":
        return [b"\x00garbage"] * 128 + base + [b"\x00garbage"] * 128
    if name == "gap 0.099 s":
        return [datagram(t)] if k % 99 == 0 else []
    if name == "worst":
        line = session.receiver.line(t)
        return ([datagram(line + AHEAD * 0.999)] if k % 99 == 0 else []) + [b"\x00garbage"] * 256
    if name == "gap 10 steps":
        return [datagram(t)] if k % 100 == 0 else []
    if name == "random":
        pick = ("clean", "future stream", "creeping ahead", "backwards", "duplicates",
                "bursts", "flood", "worst")[int(rng.integers(8))]
        return pattern(pick, k, rate, session, rng)
    raise ValueError(name)


def ticks(session, q: Queue, name: str, seconds: float, seed: int):
    """Tick the session through the pattern: each tick's CPU and wall time, washout steps."""
    rate = session.rate
    rng = np.random.default_rng(seed)
    costs, walls, steps = [], [], []
    with gc_frozen():     # as run_realtime ticks
        for k in range(int(seconds * rate)):
            q.q.extend(pattern(name, k, rate, session, rng))
            before = session.cue.steps
            w0, t0 = time.perf_counter(), time.thread_time()
            session.tick(k / rate)
            costs.append(time.thread_time() - t0)
            walls.append(time.perf_counter() - w0)
            steps.append(session.cue.steps - before)
            q.q.clear()          # what a tick's drain left is the next tick's backlog: not kept
    return costs, walls, steps


def run(scene, name: str, seconds: float, seed: int) -> dict:
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    device = DeviceOut(Client(connect_udp(*sink.getsockname())))
    q = Queue()
    session = make_session(scene, TelemetryReceiver(q, "native", time.perf_counter), device,
                           TELEMETRY_RATE, loss_timeout=1.0 if name == "gap 10 steps"
                           else LOSS_TIMEOUT, device_timeout=float("inf"))
    try:
        costs, walls, steps = ticks(session, q, name, seconds, seed)
    finally:
        device.close()
        sink.close()
    c = np.array(costs[1:]) * 1e3
    most = np.array(steps[1:]) == max(steps[1:])       # the ticks of the most washout steps
    rx = session.receiver.counts
    cue = session.cue
    return {"pattern": name, "p50": np.percentile(c, 50), "p99": np.percentile(c, 99),
            "max": c.max(), "most p50": np.percentile(c[most], 50), "most max": c[most].max(),
            "wall": max(walls[1:]) * 1e3, "steps": max(steps), "accepted": rx.accepted,
            "ahead": rx.refused.get("ahead", 0), "order": rx.refused["out_of_order"],
            "dup": rx.refused["duplicate"], "other": rx.refused_total
            - rx.refused.get("ahead", 0) - rx.refused["out_of_order"] - rx.refused["duplicate"],
            "reanchored": getattr(cue, "reanchored", 0) if isinstance(cue, CueStream) else 0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    seconds = min(max(args.seconds, 1.5), 600.0)
    scene = load(SCENE)
    names = ("clean", "future once", "future stream", "creeping ahead", "backwards",
             "duplicates", "bursts", "flood", "gap 0.099 s", "worst", "gap 10 steps", "random")
    print(f"{seconds:g} s of 1 kHz ticks per pattern; a tick's CPU time (and wall max) in ms")
    print(f"{'pattern':<16} {'p50':>7} {'p99':>7} {'max':>7} {'wall max':>8} {'steps/tick':>10} "
          f"{'its p50':>7} {'its max':>7} "
          f"{'accepted':>8} {'ahead':>7} {'order':>7} {'dup':>7} {'other':>7} {'re-anch':>7}")
    worst = (0.0, "")
    for name in names:
        r = run(scene, name, seconds, args.seed)
        worst = max(worst, (r["max"], name))
        print(f"{r['pattern']:<16} {r['p50']:>7.3f} {r['p99']:>7.3f} {r['max']:>7.3f} "
              f"{r['wall']:>8.3f} {r['steps']:>10} {r['most p50']:>7.3f} {r['most max']:>7.3f} "
              f"{r['accepted']:>8} {r['ahead']:>7} {r['order']:>7} {r['dup']:>7} "
              f"{r['other']:>7} {r['reanchored']:>7}")
    print(f"worst tick: {worst[0]:.3f} ms of CPU ({worst[1]}); the tick period is 1 ms")


if __name__ == "__main__":
    main()
