"""Sweep throughput and memory: points per second of the sweep's two grids (inverse dynamics,
closed loop) in a plain in-process loop (evaluate.evaluate_batch over every point, no Dask),
on a LocalCluster of N worker processes (as `stewart-sim sweep --workers N`) and on a loopback
Dask cluster (a scheduler and N `dask worker` processes on 127.0.0.1, as `--scheduler
tcp://...`); then the peak memory of sweeps of growing size.

    .venv/bin/python benchmarks/bench_sweep.py [--points N] [--closed-loop N] [--workers 1,2,16]
                                               [--memory 1e4,1e5,1e6]

Printed per grid: the per-point overhead ratio (one worker's points/s over the in-process
loop's: what tasks, scheduling and chunk files cost) and each worker count's speed-up over one
worker. Cluster start-up is excluded (the rate is over the evaluation); each configuration
writes into a fresh directory. `--memory` runs a sweep of each size in a fresh process (the
cheapest evaluation: inverse dynamics along a 10 ms move, a full grid of payload x gear ratio,
2 workers) and prints the peak RSS of the sweep's process and of its largest worker. Compare rows of one run: the machine's speed
drifts, and others share it (the load average is printed before and after).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from stewart_sim.sweep.evaluate import evaluate_batch
from stewart_sim.sweep.grid import grid_from_dict
from stewart_sim.sweep.run import eval_spec, run_sweep

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
BIN = Path(sys.executable).parent
WAIT = 600.0   # s: the bound on one sweep of the benchmark


def inverse_grid(points: int, duration: float = 1.0) -> str:
    """A Latin hypercube over payload, leg masses, gear ratio and friction (1 s demo move)."""
    return f"""evaluation = "inverse"
method = "lhs"
samples = {points}
seed = 1
[trajectory]
duration = {duration}
[axes]
"platform.mass" = {{min = 0.2, max = 4.0}}
"legs.upper_mass" = {{min = 0.02, max = 0.2}}
"legs.lower_mass" = {{min = 0.02, max = 0.2}}
"drive.gear_ratio" = {{min = 5.0, max = 50.0, log = true}}
"friction.viscous" = {{min = 0.0, max = 10.0}}
"""


def closed_loop_grid(points: int) -> str:
    """Gear ratio x payload, the `run` move out and back (1 s) with Kane feedforward."""
    side = max(1, round(points ** 0.5))
    return f"""evaluation = "closed_loop"
[trajectory]
kind = "run"
duration = 1.0
[axes]
"drive.gear_ratio" = {{min = 5.0, max = 40.0, points = {side}, log = true}}
"platform.mass" = {{min = 0.25, max = 2.0, points = {side}}}
"""


class LoopbackCluster:
    """`dask scheduler` and `dask worker` processes on 127.0.0.1 (context manager)."""

    def __init__(self, workers: int, port: int = 8799):
        self.address = f"tcp://127.0.0.1:{port}"
        self.workers, self.port, self.procs = workers, port, []

    def __enter__(self) -> "LoopbackCluster":
        from distributed import Client

        self.procs.append(subprocess.Popen(   # as the README advises for a sweep's scheduler
            [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
             "--dashboard-address", ":0"], stderr=subprocess.DEVNULL,
            env={**os.environ, "DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "inf"}))
        for _ in range(self.workers):
            self.procs.append(subprocess.Popen(
                [str(BIN / "dask"), "worker", self.address, "--nthreads", "1", "--nworkers", "1",
                 "--host", "127.0.0.1"], stderr=subprocess.DEVNULL))
        with Client(self.address, timeout=60) as c:
            c.wait_for_workers(self.workers, timeout=60)
        return self

    def __exit__(self, *exc) -> None:
        for p in reversed(self.procs):
            p.terminate()
        for p in self.procs:
            p.wait(timeout=30)


def measure(grid_text: str, **where) -> tuple[float, int, float]:
    """(points/s, points, wall s) of one sweep into a fresh directory."""
    out = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        s = run_sweep(SCENE, grid_from_dict(tomllib.loads(grid_text)), out, timeout=WAIT,
                      dashboard=lambda link: print(f"  (Dask dashboard at {link})", flush=True),
                      **where)
        return s.rate, s.computed, s.wall
    finally:
        shutil.rmtree(out, ignore_errors=True)


def in_process(grid_text: str, limit: int | None = None) -> tuple[float, int, float]:
    """(points/s, points, wall s) of a plain loop over the same points (the first `limit`), in
    this process."""
    grid = grid_from_dict(tomllib.loads(grid_text))
    spec, points = eval_spec(SCENE, grid), grid.points()[:limit]
    start = time.perf_counter()
    evaluate_batch(spec, points)
    wall = time.perf_counter() - start
    return len(points) / wall, len(points), wall


def throughput(name: str, text: str, workers: list[int]) -> None:
    """The table rows of one grid, then its overhead ratio and speed-ups."""
    in_process(text, limit=10)   # warm caches
    rate0, pts, wall = in_process(text)
    print(f"| {name} | in-process loop | - | {pts} | {wall:.2f} | {rate0:.0f} | 1.00 | - |",
          flush=True)
    for where in ("local", "loopback"):
        rates = {}
        for n in workers:
            if where == "local":
                rate, pts, wall = measure(text, workers=n)
            else:
                with LoopbackCluster(n) as c:
                    rate, pts, wall = measure(text, scheduler=c.address)
            rates[n] = rate
            base = rates.get(1)
            print(f"| {name} | {where} | {n} | {pts} | {wall:.2f} | {rate:.0f} | "
                  f"{rate / rate0:.2f} | {'-' if base is None else f'{rate / base:.2f}x'} |",
                  flush=True)
        summary = [f"{name}, {where}:"]
        if 1 in rates:
            summary.append(f"per-point overhead ratio (1 worker / in-process) {rates[1] / rate0:.2f}")
            summary += [f"{n} workers {rates[n] / rates[1]:.2f}x" for n in workers if n != 1]
        print("  " + " ".join(summary[:1]) + " " + ", ".join(summary[1:]), flush=True)


def memory_child(points: int) -> None:
    """One sweep of `points` cheap points (2 workers); prints its figures as JSON. A full
    grid (points decoded from their ids): a Latin hypercube would add its unit sample."""
    side = 10 ** (len(str(points)) // 2)
    text = f"""evaluation = "inverse"
[trajectory]
duration = 0.01
[axes]
"platform.mass" = {{min = 0.2, max = 4.0, points = {side}}}
"drive.gear_ratio" = {{min = 5.0, max = 50.0, points = {points // side}, log = true}}
"""
    out = Path(tempfile.mkdtemp(prefix="bench_sweep_mem_"))
    try:
        s = run_sweep(SCENE, grid_from_dict(tomllib.loads(text)), out, workers=2,
                      timeout=24 * 3600.0)
        size = (out / "sweep.csv").stat().st_size
    finally:
        shutil.rmtree(out, ignore_errors=True)
    kib = 1024 if sys.platform != "darwin" else 1   # ru_maxrss: KiB on Linux, bytes on macOS
    print(json.dumps({
        "points": s.points, "wall": s.wall, "rate": s.rate, "table_mb": size / 1e6,
        "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * kib / 1e6,
        "worker_rss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * kib / 1e6}))


def memory(sizes: list[int]) -> None:
    print("\n| points | wall (s) | points/s | sweep.csv (MB) | peak RSS, sweep process (MB) | "
          "peak RSS, largest worker (MB) |")
    print("|---|---|---|---|---|---|")
    for n in sizes:
        got = subprocess.run([sys.executable, __file__, "--memory-child", str(n)], check=True,
                             capture_output=True, text=True, env={**os.environ})
        r = json.loads(got.stdout.strip().splitlines()[-1])
        print(f"| {r['points']:,} | {r['wall']:.0f} | {r['rate']:.0f} | {r['table_mb']:.0f} | "
              f"{r['rss_mb']:.0f} | {r['worker_rss_mb']:.0f} |", flush=True)


def _counts(text: str) -> list[int]:
    return [int(float(v)) for v in text.split(",") if v]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=8000, help="inverse-dynamics points (0: skip)")
    ap.add_argument("--closed-loop", type=int, default=400, help="closed-loop points (0: skip)")
    ap.add_argument("--workers", type=_counts, default=[1, 2], help="worker counts, e.g. 1,2,16")
    ap.add_argument("--memory", type=_counts, default=[], help="sweep sizes, e.g. 1e4,1e5,1e6")
    ap.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        memory_child(args.memory_child)
        return
    print(f"load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    grids = [(name, text) for name, n, text in (
        ("inverse", args.points, inverse_grid(args.points)),
        ("closed_loop", args.closed_loop, closed_loop_grid(args.closed_loop))) if n]
    if grids:
        print("| grid | where | workers | points | wall (s) | points/s | vs in-process | "
              "vs 1 worker |")
        print("|---|---|---|---|---|---|---|---|")
    for name, text in grids:
        throughput(name, text, args.workers)
    if args.memory:
        memory(args.memory)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
