"""Sweep throughput and memory: points per second of the sweep's two grids (inverse dynamics,
closed loop) in a plain in-process loop (evaluate.evaluate_batch over every point, no Dask),
in N plain loops in N processes started together (each over every N-th point: what this
machine gives N processes that share nothing, the ceiling of N workers), on a LocalCluster of N
worker processes (as `stewart-sim sweep --workers N`) and on a loopback Dask cluster (a
scheduler and N `dask worker` processes on 127.0.0.1, as `--scheduler tcp://...`); then the
peak memory of sweeps of growing size.

    .venv/bin/python benchmarks/bench_sweep.py [--points N] [--closed-loop N] [--workers 1,2,16]
                                               [--repeats R] [--memory 1e4,1e5,1e6]

The configurations run in turn, R rounds of them (a shared machine's speed drifts by tens of
per cent over seconds: a ratio is taken between runs of one round, and the table gives the
medians over the rounds). Printed per grid: the per-point overhead ratio (one worker's points/s
over the in-process loop's: what tasks, scheduling and chunk files cost), each worker count's
speed-up over one worker next to N parallel loops' over one loop, and the sweep process's CPU a
point (the client: sending tasks, checking and writing rows; with a local cluster, also its
scheduler), the serial part that bounds how many workers one client can feed. The cluster's
start and close are excluded (the rate is over the evaluation); each sweep writes into a fresh
directory; the dashboard address of each cluster goes to stderr. `--memory` runs a sweep of each
size in a fresh process (the cheapest evaluation: inverse dynamics along a 10 ms move, a full
grid of payload x gear ratio, 2 workers) and prints the peak RSS of the sweep's process and of
its largest worker. The load average is printed before and after.
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
import statistics
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

from stewart_sim.studies.sweep.cluster import dask_environment
from stewart_sim.studies.sweep.dask_run import eval_spec, run_sweep
from stewart_sim.studies.sweep.evaluate import evaluate_batch
from stewart_sim.studies.sweep.grid import grid_from_dict

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
BIN = Path(sys.executable).parent
WAIT = 600.0   # s: the bound on one sweep of the benchmark
LOOPS_START = 4.0   # s given parallel_loops' processes to import and warm up before they start


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

        env = {**os.environ, **dask_environment()}   # as docs/guides/sweeps-and-sizing.md advises
        self.procs.append(subprocess.Popen(
            [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
             "--dashboard-address", ":0"], stderr=subprocess.DEVNULL, env=env))
        for _ in range(self.workers):
            self.procs.append(subprocess.Popen(
                [str(BIN / "dask"), "worker", self.address, "--nthreads", "1", "--nworkers", "1",
                 "--host", "127.0.0.1"], stderr=subprocess.DEVNULL, env=env))
        with Client(self.address, timeout=60) as c:
            c.wait_for_workers(self.workers, timeout=60)
        return self

    def __exit__(self, *exc) -> None:
        for p in reversed(self.procs):
            p.terminate()
        for p in self.procs:
            p.wait(timeout=30)


@dataclass(frozen=True)
class Run:
    """One measurement: points/s, points, wall s and the sweep process's CPU s a point (its
    client and a local cluster's scheduler; None for the loops)."""

    rate: float
    points: int
    wall: float
    client: float | None = None


def measure(grid_text: str, **where) -> Run:
    """One sweep into a fresh directory."""
    out = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        s = run_sweep(SCENE, grid_from_dict(tomllib.loads(grid_text)), out, timeout=WAIT,
                      dashboard=_dashboard, **where)
        return Run(s.rate, s.computed, s.wall, s.cpu / max(s.computed, 1))
    finally:
        shutil.rmtree(out, ignore_errors=True)


def _dashboard(link: str) -> None:
    print(f"  (Dask dashboard at {link})", file=sys.stderr, flush=True)


def in_process(grid_text: str, limit: int | None = None) -> Run:
    """A plain loop over the same points (the first `limit`), in this process."""
    grid = grid_from_dict(tomllib.loads(grid_text))
    spec, points = eval_spec(SCENE, grid), grid.points()[:limit]
    start = time.perf_counter()
    evaluate_batch(spec, points)
    wall = time.perf_counter() - start
    return Run(len(points) / wall, len(points), wall)


def parallel_loops(grid: str, points: int, n: int) -> Run:
    """n plain loops in n processes started together, each over every n-th point: what this
    machine gives n processes with nothing to share (the ceiling of n workers' speed-up)."""
    start = time.monotonic() + LOOPS_START + 0.2 * n     # each child imports and warms up first
    procs = [subprocess.Popen([sys.executable, __file__, "--loop-child", grid, str(points),
                               str(k), str(n), repr(start)], stdout=subprocess.PIPE, text=True)
             for k in range(n)]
    got = []
    for proc in procs:
        out, _ = proc.communicate(timeout=WAIT)
        if proc.returncode != 0:
            raise SystemExit(f"a loop process failed (exit {proc.returncode})")
        got.append(json.loads(out.strip().splitlines()[-1]))
    late = max(g["late"] for g in got)
    if late > 0:
        print(f"  (a loop process started {late:.2f} s late: raise LOOPS_START)", file=sys.stderr)
    wall = max(g["end"] for g in got) - start
    total = sum(g["points"] for g in got)
    return Run(total / wall, total, wall)


def loop_child(grid: str, points: int, k: int, n: int, start: float) -> None:
    """One of parallel_loops' processes: warm up, wait for `start`, run its points; prints
    its figures as JSON."""
    grid_text = GRIDS[grid](points)
    in_process(grid_text, limit=10)
    g = grid_from_dict(tomllib.loads(grid_text))
    spec, mine = eval_spec(SCENE, g), g.points()[k::n]
    late = time.monotonic() - start
    time.sleep(max(0.0, -late))
    evaluate_batch(spec, mine)
    print(json.dumps({"points": len(mine), "end": time.monotonic(), "late": late}))


def throughput(name: str, points: int, workers: list[int], repeats: int) -> None:
    """`repeats` rounds, each running every configuration once in turn (the machine's speed
    drifts between rounds: a ratio is taken within a round); then the table rows of the grid
    (medians over the rounds) and its summary line."""
    text = GRIDS[name](points)
    in_process(text, limit=10)   # warm caches
    configs = [("in-process loop", 1)] + [("parallel loops", n) for n in workers if n > 1]
    configs += [(where, n) for where in ("local", "loopback") for n in workers]
    runs: dict[tuple[str, int], list[Run]] = {c: [] for c in configs}
    for r in range(repeats):
        for where, n in configs:
            runs[where, n].append(_run(where, n, name, points, text))
        print(f"  ({name}: round {r + 1} of {repeats}, load average "
              f"{os.getloadavg()[0]:.2f})", file=sys.stderr, flush=True)
    base = runs["in-process loop", 1]

    def ratio(a: list[Run], b: list[Run]) -> float:
        return statistics.median(x.rate / y.rate for x, y in zip(a, b))

    for where, n in configs:
        got = runs[where, n]
        rates = [x.rate for x in got]
        one = runs.get((where, 1)) if where in ("local", "loopback") else base
        ceiling = runs.get(("parallel loops", n))
        client = [x.client for x in got if x.client is not None]
        print(f"| {name} | {where} | {n} | {got[0].points} | {statistics.median(rates):,.0f} | "
              f"{min(rates):,.0f}-{max(rates):,.0f} | {ratio(got, base):.2f} | "
              f"{'-' if one is None or one is got else f'{ratio(got, one):.2f}x'} | "
              f"{'-' if ceiling is None or where == 'parallel loops' else f'{ratio(got, ceiling):.2f}'} | "
              f"{f'{statistics.median(client) * 1e6:.0f}' if client else '-'} |", flush=True)
    for where in ("local", "loopback"):
        line = [f"per-point overhead ratio (1 worker / in-process loop) "
                f"{ratio(runs[where, 1], base):.2f}"] if 1 in workers else []
        for n in workers:
            if n > 1 and 1 in workers:
                line.append(f"{n} workers {ratio(runs[where, n], runs[where, 1]):.2f}x "
                            f"({n} parallel loops {ratio(runs['parallel loops', n], base):.2f}x)")
        print(f"  {name}, {where}: " + ", ".join(line), flush=True)


def _run(where: str, n: int, name: str, points: int, text: str) -> Run:
    if where == "in-process loop":
        return in_process(text)
    if where == "parallel loops":
        return parallel_loops(name, points, n)
    if where == "local":
        return measure(text, workers=n)
    with LoopbackCluster(n) as c:
        return measure(text, scheduler=c.address)


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


GRIDS = {"inverse": inverse_grid, "closed_loop": closed_loop_grid}


def _counts(text: str) -> list[int]:
    return [int(float(v)) for v in text.split(",") if v]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=8000, help="inverse-dynamics points (0: skip)")
    ap.add_argument("--closed-loop", type=int, default=400, help="closed-loop points (0: skip)")
    ap.add_argument("--workers", type=_counts, default=[1, 2], help="worker counts, e.g. 1,2,16")
    ap.add_argument("--repeats", type=int, default=3, help="rounds of every configuration")
    ap.add_argument("--memory", type=_counts, default=[], help="sweep sizes, e.g. 1e4,1e5,1e6")
    ap.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--loop-child", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        memory_child(args.memory_child)
        return
    if args.loop_child:
        grid, points, k, n, start = args.loop_child
        loop_child(grid, int(points), int(k), int(n), float(start))
        return
    print(f"load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    grids = [(name, n) for name, n in (("inverse", args.points),
                                       ("closed_loop", args.closed_loop)) if n]
    if grids:
        print(f"\nMedians of {args.repeats} rounds; ratios taken within each round.\n")
        print("| grid | where | workers | points | points/s | range | vs in-process loop | "
              "vs 1 worker | vs N parallel loops | client CPU (us/point) |")
        print("|---|---|---|---|---|---|---|---|---|---|")
    for name, n in grids:
        throughput(name, n, args.workers, max(1, args.repeats))
    if args.memory:
        memory(args.memory)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
