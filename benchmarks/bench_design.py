"""`design`'s cost: a candidate's evaluation in a plain in-process loop (the search's grid and
the dense check's), and the whole search of a design.toml on a LocalCluster of N workers (as
`stewart-sim design --workers N`): its wall time, the candidates per second, and the ratio to
the plain loop over the same number of candidates (what the tasks, NSGA-II and the dense check
add, and what N workers take off).

    .venv/bin/python benchmarks/bench_design.py [DESIGN.toml] [--workers 1,2] [--population N]
                                                [--generations N]

The cluster's start and close are excluded. The load average is printed before and after.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "design" / "positioning_hexapod.toml"


def plain_loop(spec, names, n: int, points: int) -> float:
    """Seconds a candidate, n random candidates (seed 0) evaluated in this process."""
    from stewart_sim.studies.design.candidate import evaluate

    rng = np.random.default_rng(0)
    lo = np.array([p.low for p in spec.free])
    hi = np.array([p.high for p in spec.free])
    X = lo + rng.random((n, len(lo))) * (hi - lo)
    t = time.perf_counter()
    for x in X:
        evaluate(spec, x, names, points=points)
    return (time.perf_counter() - t) / n


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("design", nargs="?", default=str(EXAMPLE))
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--population", type=int)
    ap.add_argument("--generations", type=int)
    args = ap.parse_args()
    from stewart_sim.studies.design import search
    from stewart_sim.studies.design.candidate import requirement_names
    from stewart_sim.studies.design.spec import load, with_search
    from stewart_sim.studies.sweep.cluster import dask_client

    print(f"load average {os.getloadavg()}")
    spec = with_search(load(args.design), population=args.population,
                       generations=args.generations)
    names = requirement_names(spec)
    ws = spec.workspace
    search_cost = plain_loop(spec, names, 200, ws.search_points)
    dense_cost = plain_loop(spec, names, 50, ws.check_points)
    print(f"a candidate, plain loop: {search_cost * 1e3:.2f} ms ({ws.search_points} points an "
          f"axis), {dense_cost * 1e3:.2f} ms dense ({ws.check_points})")
    n = spec.search.population * spec.search.generations
    print(f"{'workers':>7} {'search s':>9} {'cand/s':>8} {'plain loop s':>13} {'ratio':>6}  chosen")
    for w in (int(v) for v in args.workers.split(",")):
        with dask_client(None, w) as client:
            r = search.run(spec, client, w, progress=lambda line: None)
        plain = n * search_cost
        chosen = "none" if r.chosen is None else \
            f"base radius {r.chosen.values['base_radius'] * 1e3:.1f} mm, least " \
            f"{r.chosen.least.name} {r.chosen.least.relative:+.1%}"
        print(f"{w:>7} {r.seconds:>9.2f} {n / r.seconds:>8.0f} {plain:>13.2f} "
              f"{r.seconds / plain:>6.2f}  {chosen}")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
