"""What the live safety envelope (stewart_sim.live.envelope) costs per sample, timed one
sample at a time.

    python benchmarks/bench_envelope.py [--samples N]

For each shipped scene with drives (the micro-manipulator, the motion simulator), three cues at
1 kHz: `pass` a slow sine inside every limit (every sample goes through unchanged), `limited` a
square wave of heave too large and too sudden for the legs (the envelope flies its own state
on most samples: speed, acceleration, force and stroke limits), `brake` the emergency stop
from a motion at 90 % of the speed limit, repeated. Prints the median, p99 and max of the wall
time per sample and the process's CPU time per sample (less sensitive to a busy machine).
Wall-clock figures: measured here, never asserted in tests.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from stewart_fmu import load_scene
from stewart_sim.live.envelope import Envelope, envelope_limits
from stewart_sim.scene.load import scene_of

SCENES = Path(__file__).resolve().parents[1] / "scenes"
DT = 1e-3


def _time(calls) -> tuple[np.ndarray, float, int]:
    """(wall us per call, CPU us per call, samples not passed unchanged)."""
    wall = np.empty(len(calls))
    limited = 0
    cpu0 = time.process_time()
    for k, call in enumerate(calls):
        t0 = time.perf_counter_ns()
        out = call()
        wall[k] = (time.perf_counter_ns() - t0) / 1e3
        limited += not out.passed
    return wall, (time.process_time() - cpu0) / len(calls) * 1e6, limited


def _workloads(model, lim, n: int):
    home = np.asarray(model.home, dtype=float)
    z = np.zeros(6)
    stroke = lim.leg_max - lim.leg_min
    t = np.arange(n) * DT
    # pass: 0.5 Hz heave and roll, small
    w = 2 * np.pi * 0.5
    amp = np.array([0, 0, 0.02 * stroke, 0.01, 0, 0])
    env = Envelope(model, lim, DT)
    cue = [(home + amp * np.sin(w * tk), amp * w * np.cos(w * tk), -amp * w * w * np.sin(w * tk))
           for tk in t]
    yield "pass", [lambda c=c: env.step(*c) for c in cue]
    # limited: +-40 % of the stroke in heave, switching every 0.3 s
    env2 = Envelope(model, lim, DT)
    up, down = home + [0, 0, 0.4 * stroke, 0, 0, 0], home - [0, 0, 0.2 * stroke, 0, 0, 0]
    targets = [up if (k // 300) % 2 == 0 else down for k in range(n)]
    yield "limited", [lambda q=q: env2.step(q, z, z) for q in targets]
    # brake: 50 samples moving at 90 % of the speed limit, then 50 braking, repeated
    env3 = Envelope(model, lim, DT)
    v = 0.9 * lim.speed
    calls = []
    for k in range(n):
        if (k // 50) % 2 == 0:
            calls.append(lambda k=k: env3.step(
                env3.last.q + np.array([v * DT, 0, 0, 0, 0, 0]) * (k % 50 > 0),
                np.array([v, 0, 0, 0, 0, 0]), z))
        else:
            calls.append(env3.brake)
    yield "brake", calls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20000, help="samples per workload")
    args = parser.parse_args()
    print(f"{'scene':<20} {'cue':<8} {'limited':>8} {'median us':>10} {'p99 us':>8} "
          f"{'max us':>8} {'CPU us':>8}")
    for name in ("micro_manipulator.toml", "motion_simulator.toml"):
        model = load_scene(SCENES / name)
        lim = envelope_limits(model, scene_of(model).controller)
        for cue, calls in _workloads(model, lim, args.samples):
            wall, cpu, limited = _time(calls)
            print(f"{name[:-5]:<20} {cue:<8} {limited / len(calls):>8.0%} "
                  f"{np.median(wall):>10.1f} {np.percentile(wall, 99):>8.1f} "
                  f"{wall.max():>8.1f} {cpu:>8.1f}")


if __name__ == "__main__":
    main()
