"""Real-time factor of the in-process closed loop at 1 kHz: the C loop (controller/native/axis.c
around the plant's C core) and, for comparison, main's numba loop, in one process.

    python benchmarks/bench_closed_loop.py [--runs N] [--duration S] [--ref GIT-REF]

Scene scenes/micro_manipulator.toml, the `run` reference (controller.moves.run_reference, 4 s
by default), feedforward "kane". The real-time factor is simulated time / the loop's wall time
(Summary.realtime_factor: the per-sample loop only; a numba kernel's compilation is excluded by
its warm-up call). The numba loop is main's controller package as `git show REF:controller/...`
writes it into a temporary package (it imports the same stewart_fmu). Prints the best and the
median of N interleaved runs of each, the end-to-end time of run_closed_loop (design, references and
feedforward included), and the largest difference between the two loops' recorded signals.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import controller.config
import controller.cosim
import controller.moves
from stewart_fmu import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
TARGET = 300.0


def _git_package(ref: str, into: Path, name: str):
    """main's (ref's) controller package written to into/name and imported; None when git or
    the ref is unavailable, or when that package has no numba loop."""
    try:
        files = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", f"{ref}:controller"],
                               check=True, capture_output=True, text=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        return None
    pkg = into / name
    pkg.mkdir()
    for f in files:
        if f.endswith(".py"):
            text = subprocess.run(["git", "-C", str(ROOT), "show", f"{ref}:controller/{f}"],
                                  check=True, capture_output=True, text=True).stdout
            (pkg / f).write_text(text)
    if "_loop_kernel" not in (pkg / "cosim.py").read_text():
        return None
    sys.path.insert(0, str(into))
    return importlib.import_module(f"{name}.cosim"), importlib.import_module(f"{name}.config"), \
        importlib.import_module(f"{name}.moves")


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
    parser.add_argument("--ref", default="main", help="git ref of the numba loop (default main)")
    args = parser.parse_args()
    model = load_scene(SCENE)
    print(f"closed loop at 1 kHz, {SCENE.name}, run reference {args.duration:g} s, feedforward "
          f"kane, {args.runs} runs of each, interleaved")
    with tempfile.TemporaryDirectory() as tmp:
        loops = [_Loop("C (this tree)", controller.cosim, controller.config, controller.moves,
                       model, args.duration)]
        numba_loop = _git_package(args.ref, Path(tmp), "_bench_main_controller")
        if numba_loop is not None:
            loops.append(_Loop(f"numba ({args.ref})", *numba_loop, model, args.duration))
        for _ in range(args.runs):
            for loop in loops:
                loop.once()
        print(f"{'loop':<16} {'best RTF':>10} {'median RTF':>10} {'us/sample':>10} "
              f"{'end-to-end':>10} {'cold (s)':>9}")
        best = [loop.row(args.duration) for loop in loops]
        if numba_loop is None:
            print(f"numba loop: not measured (no numba loop at git ref {args.ref!r})")
        else:
            a, b = loops[0].first.table, loops[1].first.table
            diff = max(float(np.max(np.abs(a[k] - b[k]))) for k in a.dtype.names)
            print(f"C / numba (best): {best[0] / best[1]:.2f}x; largest difference of the "
                  f"recorded signals: {diff:.3g}")
    print(f"target >= {TARGET:.0f}x: {'met' if best[0] >= TARGET else 'NOT met'} ({best[0]:.0f}x)")


if __name__ == "__main__":
    main()
