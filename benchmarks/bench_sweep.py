"""Sweep throughput: points per second of an inverse-dynamics sweep, locally (a LocalCluster of
1 and 2 worker processes, as `stewart-sim sweep --workers N`) and on a loopback Dask cluster
(a scheduler and N `dask worker` processes on 127.0.0.1, as `--scheduler tcp://...`).

    .venv/bin/python benchmarks/bench_sweep.py [--points N] [--closed-loop N]

Cluster start-up is excluded (the rate is over the evaluation); each configuration writes into
a fresh directory. Compare rows of one run: the machine's speed drifts, and others share it.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from stewart_sim.sweep.grid import grid_from_dict
from stewart_sim.sweep.run import run_sweep

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
BIN = Path(sys.executable).parent


def inverse_grid(points: int) -> str:
    """A Latin hypercube over payload, leg masses, gear ratio and friction (1 s demo move)."""
    return f"""evaluation = "inverse"
method = "lhs"
samples = {points}
seed = 1
[trajectory]
duration = 1.0
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

        self.procs.append(subprocess.Popen(
            [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
             "--dashboard-address", ":0"], stderr=subprocess.DEVNULL))
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
        s = run_sweep(SCENE, grid_from_dict(tomllib.loads(grid_text)), out, **where)
        return s.rate, s.computed, s.wall
    finally:
        shutil.rmtree(out, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=4000, help="inverse-dynamics points per row")
    ap.add_argument("--closed-loop", type=int, default=0, help="closed-loop points per row (0: skip)")
    args = ap.parse_args()
    grids = [("inverse", inverse_grid(args.points))]
    if args.closed_loop:
        grids.append(("closed_loop", closed_loop_grid(args.closed_loop)))
    print("| evaluation | where | workers | points | wall (s) | points/s | vs 1 worker |")
    print("|---|---|---|---|---|---|---|")
    for name, text in grids:
        measure(text.replace(f"samples = {args.points}", "samples = 20"), workers=1)  # warm caches
        for where in ("local", "loopback"):
            base = None
            for n in (1, 2):
                if where == "local":
                    rate, pts, wall = measure(text, workers=n)
                else:
                    with LoopbackCluster(n) as c:
                        rate, pts, wall = measure(text, scheduler=c.address)
                base = base or rate
                print(f"| {name} | {where} | {n} | {pts} | {wall:.2f} | {rate:.0f} | "
                      f"{rate / base:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
