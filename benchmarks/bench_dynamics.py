"""Speed of the plant's dynamics: batch throughput and single-call latency, one core.

Prints a table. Machines are noisy: each figure is the best of several repeats, and the ratios
within one run (levels against the full model) are more telling than the absolute numbers.
Run: .venv/bin/python benchmarks/bench_dynamics.py [--samples N]
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from stewart_fmu import forward_dynamics, inverse_dynamics, kane_terms, load_scene

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"


def smooth_trajectory(model, n: int, duration: float = 10.0):
    """Sinusoids in all six coordinates around home (exact derivatives)."""
    t = np.linspace(0.0, duration, n)[:, None]
    amp = np.array([0.01, 0.01, 0.01, 0.1, 0.1, 0.1])
    w = 2 * np.pi * np.array([0.5, 0.7, 0.9, 0.6, 0.8, 1.0])
    return (model.home + amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w**2 * np.sin(w * t))


def best_time(fn, repeats: int) -> float:
    """Best wall time of fn() over repeats (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def per_call(fn, calls: int) -> float:
    """Mean seconds per call over a loop of calls, best of 5 loops."""
    def loop():
        for _ in range(calls):
            fn()
    return best_time(loop, 5) / calls


def variants(model):
    """The scene as declared and with tables left out (the kernels skip what is absent)."""
    yield "full scene", model
    yield "without [friction]", dataclasses.replace(model, friction=None)
    yield "without [drive]", dataclasses.replace(model, drive=None)
    yield "without [legs]", dataclasses.replace(model, legs=None)
    yield "platform only", dataclasses.replace(model, legs=None, drive=None, friction=None)


def scene_table(model, Q, QD, QDD, rounds: int = 7) -> list[tuple[str, float, float]]:
    """(variant, inverse s/sample, forward s/sample) of the batch kernels: the best of `rounds`
    rounds, each timing every variant in turn (so a drift of the machine's speed hits all)."""
    calls = []
    for name, m in variants(model):
        S = inverse_dynamics(m, Q, QD, QDD)
        calls.append((name, lambda m=m: inverse_dynamics(m, Q, QD, QDD),
                      lambda m=m, S=S: forward_dynamics(m, Q, QD, S)))
    best = np.full((len(calls), 2), np.inf)
    for _ in range(rounds):
        for k, (_, inv, fwd) in enumerate(calls):
            best[k] = np.minimum(best[k], (best_time(inv, 1), best_time(fwd, 1)))
    return [(name, *(best[k] / len(Q))) for k, (name, _, _) in enumerate(calls)]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--scene", default=str(SCENE))
    args = ap.parse_args(argv)
    model = load_scene(args.scene)
    Q, QD, QDD = smooth_trajectory(model, args.samples)
    print(f"scene: {model.name}   samples: {args.samples}   (best of repeats, one core)")
    print("\nscenes compute only what they declare (batch kernels, ns per sample; ratio = "
          "full / this, > 1 is faster):")
    print(f"{'variant':<22} {'inverse':>10} {'ratio':>7} {'forward':>10} {'ratio':>7}")
    table = scene_table(model, Q, QD, QDD)
    _, inv_full, fwd_full = table[0]
    for name, inv, fwd in table:
        print(f"{name:<22} {inv * 1e9:>7,.0f} ns {inv_full / inv:>7.2f} {fwd * 1e9:>7,.0f} ns "
              f"{fwd_full / fwd:>7.2f}")
    print("[friction] and [drive] cost a few flops per leg, below this machine's timing noise; "
          "that they are skipped\n(parameters never read) is shown by tests/stewart_fmu/"
          "test_dynamics_physics.py::test_absent_effects_are_not_computed")
    S = inverse_dynamics(model, Q, QD, QDD)
    q, qd, qdd, s = Q[1], QD[1], QDD[1], S[1]
    rows = []
    t = per_call(lambda: inverse_dynamics(model, q, qd, qdd), 20_000)
    rows.append(("inverse_dynamics single call, full", 1 / t, t))
    t = per_call(lambda: forward_dynamics(model, q, qd, s), 20_000)
    rows.append(("forward_dynamics single call, full", 1 / t, t))
    t = per_call(lambda: kane_terms.actuator_forces(model, q, qd, qdd), 200)
    rows.append(("kane_terms.actuator_forces (numpy, readable form)", 1 / t, t))
    print(f"\n{'what':<52} {'per second':>14} {'per call':>16}")
    for what, rate, sec in rows:
        print(f"{what:<52} {rate:>14,.0f} {sec * 1e9:>13,.0f} ns")


if __name__ == "__main__":
    main()
