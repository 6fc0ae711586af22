"""Real-time factor of the in-process closed loop at 1 kHz: controller/native/axis.c around the
plant's C core (one C call per chunk of samples).

    python benchmarks/bench_closed_loop.py [--runs N] [--duration S]

Scene scenes/micro_manipulator.toml, the `run` reference (controller.moves.run_reference, 4 s
by default), feedforward "kane". The real-time factor is simulated time / the loop's wall time
(Summary.realtime_factor: the per-sample loop only). Prints the best and the median of N runs,
the end-to-end time of run_closed_loop (design, references and feedforward included) and the
first (cold) run's time. For comparison, a compiled Python loop of the same arithmetic ran
148-149x in the same kind of run (the speed table of docs/tests-and-speed.md).
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import controller.config
import controller.cosim
import controller.moves
from stewart_fmu import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
TARGET = 300.0


class _Loop:
    """One loop's package, its configuration and reference, and its timings."""

    def __init__(self, label, cosim, config_mod, moves, model, duration):
        self.label, self.cosim, self.model = label, cosim, model
        self.config = dataclasses.replace(config_mod.controller_config(model), feedforward="kane")
        assert self.config.rate == 1000.0, self.config.rate
        self.traj = moves.run_reference(model, self.config, duration)
        start = time.perf_counter()
        self.first = self.run()                      # loads / compiles the loop
        self.cold = time.perf_counter() - start
        self.factors, self.ends = [], []

    def run(self):
        return self.cosim.run_closed_loop(self.model, self.config, self.traj)

    def once(self) -> None:
        start = time.perf_counter()
        res = self.run()
        self.ends.append(time.perf_counter() - start)
        self.factors.append(res.summary.realtime_factor)

    def row(self, duration: float) -> float:
        best, median = max(self.factors), statistics.median(self.factors)
        print(f"{self.label:<16} {best:>9.0f}x {median:>9.0f}x "
              f"{1e6 * duration / best / len(self.traj.t):>10.2f} "
              f"{statistics.median(self.ends):>10.3f} {self.cold:>9.2f}")
        return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9)
    parser.add_argument("--duration", type=float, default=4.0)
    args = parser.parse_args()
    model = load_scene(SCENE)
    print(f"closed loop at 1 kHz, {SCENE.name}, run reference {args.duration:g} s, feedforward "
          f"kane, {args.runs} runs")
    loop = _Loop("C loop", controller.cosim, controller.config, controller.moves, model,
                 args.duration)
    for _ in range(args.runs):
        loop.once()
    print(f"{'loop':<16} {'best RTF':>10} {'median RTF':>10} {'us/sample':>10} "
          f"{'end-to-end':>10} {'cold (s)':>9}")
    best = loop.row(args.duration)
    print(f"target >= {TARGET:.0f}x: {'met' if best >= TARGET else 'NOT met'} ({best:.0f}x)")


if __name__ == "__main__":
    main()
