"""`stewart-sim sweep SCENE --grid GRID.toml --out DIR [--scheduler tcp://HOST:PORT |
--workers N] [--adaptive N] [--no-plots]`: a design sweep on Dask (stewart_sim.studies.sweep.files),
resumable."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stewart_sim.shell.argtypes import number

_workers = number(int, "an integer", lambda v: 1 <= v <= 1024, "1 to 1024")
# the bound is stewart_sim.studies.sweep.adaptive.MAX_ADDED (not imported: --help stays fast)
_adaptive = number(int, "an integer", lambda v: 0 <= v <= 1_000_000, "an integer from 0 to 1000000")


def add_parser(sub, help_text: str) -> None:
    """Register `sweep` on the command line's subparsers."""
    p = sub.add_parser("sweep", help=help_text,
                       description="Evaluate every point of GRID.toml (inverse dynamics, closed "
                                   "loop or workspace force envelope at scene and controller "
                                   "values) on all local cores, or on a Dask cluster with "
                                   "--scheduler; one row per point in DIR/sweep.csv, plots "
                                   "beside it. A rerun into the same DIR resumes where the last "
                                   "one stopped.")
    p.add_argument("scene", metavar="SCENE", help="the base scene file (TOML)")
    p.add_argument("--grid", required=True, metavar="GRID.toml",
                   help="evaluation, trajectory or pose grid, and the [axes] to vary "
                        "(docs/guides/sweeps-and-sizing.md)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (resumable)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run on this Dask distributed scheduler's workers")
    where.add_argument("--workers", type=_workers, metavar="N",
                       help="local worker processes (default: one per core)")
    p.add_argument("--adaptive", type=_adaptive, default=0, metavar="N",
                   help="then N more points where the outcome changes: the grid's [adaptive] "
                        "target (default: feasibility) crossing its threshold; the table's "
                        "column `refinement` gives each point's round (0: the grid)")
    p.add_argument("--no-plots", action="store_true", help="write the table only")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run the sweep, print its figures and the files."""
    from stewart_sim.scene.load import load

    load(args.scene)    # every table of the base scene checked before the cluster starts
    from stewart_sim.studies.sweep.files import run_sweep_files  # dask: only for this command

    args.kept = (f"the points finished so far are kept in {args.out} (its chunk files), "
                 "the same command resumes from there")
    summary, written = run_sweep_files(Path(args.scene), Path(args.grid), Path(args.out),
                                       args.scheduler, args.workers, not args.no_plots,
                                       lambda line: print(f"stewart-sim: {line}",
                                                          file=sys.stderr), args.adaptive,
                                       lambda link: print(f"sweep: Dask dashboard at {link}",
                                                          flush=True))
    where = args.scheduler or "local cluster"
    refused = (f", {summary.refused} chunk files refused and their points computed again"
               if summary.refused else "")
    added = f" ({summary.added} added by refinement)" if args.adaptive else ""
    print(f"sweep: {summary.points} points{added}, {summary.resumed} already done, "
          f"{summary.computed} "
          f"computed on {summary.workers} workers ({where}) in {summary.wall:.3g} s "
          f"({summary.rate:.4g} points/s); {summary.failed} failed{refused}")
    for path in written:
        print(f"wrote {path}")
