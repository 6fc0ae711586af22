"""Real-time factor of the in-process closed loop at 1 kHz: the C loop (controller/native/axis.c
around the plant's C core) and, for comparison, main's numba loop, in one process.

    python benchmarks/bench_closed_loop.py [--runs N] [--duration S] [--ref GIT-REF]

Scene scenes/micro_manipulator.toml, the `run` reference (controller.moves.run_reference, 4 s
by default), feedforward "kane". The real-time factor is simulated time / the loop's wall time
(Summary.realtime_factor: the per-sample loop only; a numba kernel's compilation is excluded by
its warm-up call). The numba loop is main's controller package as `git show REF:controller/...`
writes it into a temporary package (it imports the same stewart_fmu). Prints the best and the
median of N runs of each, the end-to-end time of run_closed_loop (design, references and
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


def _measure(label, cosim, config_mod, moves, model, duration, runs):
    config = dataclasses.replace(config_mod.controller_config(model), feedforward="kane")
    assert config.rate == 1000.0, config.rate
    traj = moves.run_reference(model, config, duration)
    start = time.perf_counter()
    first = cosim.run_closed_loop(model, config, traj)      # loads / compiles the loop
    cold = time.perf_counter() - start
    factors, ends = [], []
    for _ in range(runs):
        start = time.perf_counter()
        res = cosim.run_closed_loop(model, config, traj)
        ends.append(time.perf_counter() - start)
        factors.append(res.summary.realtime_factor)
    best, median = max(factors), statistics.median(factors)
    print(f"{label:<16} {best:>9.0f}x {median:>9.0f}x {1e6 * duration / best / len(traj.t):>10.2f}"
          f" {statistics.median(ends):>10.3f} {cold:>9.2f}")
    return first, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--duration", type=float, default=4.0)
    parser.add_argument("--ref", default="main", help="git ref of the numba loop (default main)")
    args = parser.parse_args()
    model = load_scene(SCENE)
    print(f"closed loop at 1 kHz, {SCENE.name}, run reference {args.duration:g} s, feedforward "
          f"kane, {args.runs} runs")
    print(f"{'loop':<16} {'best RTF':>10} {'median RTF':>10} {'us/sample':>10} {'end-to-end':>10}"
          f" {'cold (s)':>9}")
    c_res, c_best = _measure("C (this tree)", controller.cosim, controller.config,
                             controller.moves, model, args.duration, args.runs)
    with tempfile.TemporaryDirectory() as tmp:
        numba_loop = _git_package(args.ref, Path(tmp), "_bench_main_controller")
        if numba_loop is None:
            print(f"numba loop: not measured (no numba loop at git ref {args.ref!r})")
        else:
            n_res, n_best = _measure(f"numba ({args.ref})", *numba_loop, model, args.duration,
                                     args.runs)
            diff = max(float(np.max(np.abs(c_res.table[k] - n_res.table[k])))
                       for k in c_res.table.dtype.names)
            print(f"C / numba: {c_best / n_best:.2f}x; largest difference of the recorded "
                  f"signals: {diff:.3g}")
    print(f"target >= {TARGET:.0f}x: {'met' if c_best >= TARGET else 'NOT met'} "
          f"({c_best:.0f}x)")


if __name__ == "__main__":
    main()
