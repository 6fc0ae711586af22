"""`design`'s cost: a candidate's evaluation in a plain in-process loop (the search's grid and
motion samples, and the dense check's), and the whole search of a design.toml on a LocalCluster
of N workers (as `stewart-sim design --workers N`): the candidates, how many are feasible, the
front's size, its wall time, the time a candidate, and the ratio to the plain loop over the
same number of candidates (what the tasks, NSGA-II and the dense check add, and what N workers
take off). Both shipped examples by default, at their full size.

    .venv/bin/python benchmarks/bench_design.py [DESIGN.toml ...] [--workers 1,2]
                                                [--population N] [--generations N]

The cluster's start and close are excluded. The load average is printed before and after.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = [ROOT / "scenes" / "design" / f for f in ("positioning_hexapod.toml",
                                                     "motion_simulator.toml")]


def plain_loop(spec, names, n: int, points: int, every: int | None = None
               ) -> tuple[float, float]:
    """Seconds a candidate, wall and this process's CPU (what a shared machine's load does not
    inflate), n random candidates (seed 0) evaluated in this process."""
    from stewart_sim.studies.design.candidate import evaluate

    rng = np.random.default_rng(0)
    lo = np.array([p.low for p in spec.free])
    hi = np.array([p.high for p in spec.free])
    X = lo + rng.random((n, len(lo))) * (hi - lo)
    t, cpu = time.perf_counter(), time.process_time()
    for x in X:
        evaluate(spec, x, names, points=points, every=every)
    return (time.perf_counter() - t) / n, (time.process_time() - cpu) / n


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("design", nargs="*", default=[str(e) for e in EXAMPLES])
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--population", type=int)
    ap.add_argument("--generations", type=int)
    args = ap.parse_args()
    from stewart_sim.studies.design import search
    from stewart_sim.studies.design.candidate import requirement_names
    from stewart_sim.studies.design.spec import load, with_search
    from stewart_sim.studies.sweep.cluster import dask_client

    print(f"load average {os.getloadavg()}")
    for design in args.design:
        bench(design, args, search, requirement_names, load, with_search, dask_client)
    print(f"load average {os.getloadavg()}")


def bench(design, args, search, requirement_names, load, with_search, dask_client) -> None:
    spec = with_search(load(design), population=args.population,
                       generations=args.generations)
    names = requirement_names(spec)
    ws = spec.workspace
    search_cost, search_cpu = plain_loop(spec, names, 100, ws.search_points)
    dense_cost, dense_cpu = plain_loop(spec, names, 20, ws.check_points, every=1)
    print(f"\n{Path(design).name}: a candidate, plain loop: {search_cost * 1e3:.2f} ms "
          f"({search_cpu * 1e3:.2f} ms CPU; {ws.search_points} points an axis), "
          f"{dense_cost * 1e3:.2f} ms dense ({dense_cpu * 1e3:.2f} ms CPU; {ws.check_points}, "
          "every motion sample)")
    n = spec.search.population * spec.search.generations
    print(f"{'workers':>7} {'candidates':>10} {'feasible':>8} {'front':>5} {'search s':>9} "
          f"{'ms/cand':>8} {'plain loop s':>13} {'ratio':>6} {'total s':>8}  chosen")
    for w in (int(v) for v in args.workers.split(",")):
        with dask_client(None, w) as client:
            t = time.perf_counter()
            r = search.run(spec, client, w, progress=lambda line: None)
            total = time.perf_counter() - t
        plain = n * search_cost
        feasible = int(np.sum(np.all(r.margins >= 0, axis=1)))
        chosen = "none" if r.chosen is None else \
            f"base radius {r.chosen.values['base_radius'] * 1e3:.1f} mm, least " \
            f"{r.chosen.least.name} {r.chosen.least.relative:+.1%}"
        if r.chosen is not None and spec.drive(r.chosen.values) is not None:
            chosen += f", drive {spec.drive(r.chosen.values).name}"
        print(f"{w:>7} {len(r.X):>10} {feasible:>8} {len(r.front):>5} {r.seconds:>9.2f} "
              f"{r.seconds / len(r.X) * 1e3:>8.2f} {plain:>13.2f} {r.seconds / plain:>6.2f} "
              f"{total:>8.2f}  {chosen}")


if __name__ == "__main__":
    main()
