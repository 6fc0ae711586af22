"""What one sample of the delivered specific force at the head costs (a live cueing loop's
snapshot): stewart_sim.cueing.vestibular.delivered_at timed call by call, at the origin and at
a head offset, against delivered_motion on one row.

    python benchmarks/bench_delivered_at.py [--calls N]

Prints the median, p99 and p99.9 per call in microseconds. Wall-clock figures: measured here,
never asserted in tests.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from stewart_sim.cueing.vestibular import delivered_at, delivered_motion

GRAVITY = np.array([0.0, 0.0, -9.81])
HEAD = np.array([0.1, 0.0, 0.9])     # m: a seated pilot's head over the platform's centre


def _times(call, n: int) -> np.ndarray:
    out = np.empty(n)
    for k in range(n):
        start = time.perf_counter_ns()
        call()
        out[k] = time.perf_counter_ns() - start
    return out / 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=20000, help="calls per case")
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    q, qd, qdd = (0.1 * rng.standard_normal(6) for _ in range(3))
    t1 = np.zeros(1)
    cases = {
        "delivered_at, head at the origin": lambda: delivered_at(q, qd, qdd, GRAVITY),
        "delivered_at, head offset": lambda: delivered_at(q, qd, qdd, GRAVITY, HEAD),
        "delivered_motion, 1 row, head offset":
            lambda: delivered_motion(t1, q[None], qd[None], qdd[None], GRAVITY, HEAD),
    }
    print(f"{'case':40s} {'p50 us':>8s} {'p99 us':>8s} {'p99.9 us':>9s}")
    for name, call in cases.items():
        _times(call, 1000)                       # warm-up
        us = _times(call, args.calls)
        p50, p99, p999 = np.percentile(us, [50, 99, 99.9])
        print(f"{name:40s} {p50:8.1f} {p99:8.1f} {p999:9.1f}")


if __name__ == "__main__":
    main()
