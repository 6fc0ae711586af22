"""`stewart-sim compare SCENE... --out DIR [--points N]`: constant-load vs Kane control over a
drive-inertia sweep (stewart_sim.studies.compare.files.run_compare) into DIR, all or nothing."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.shell.argtypes import number

_points = number(int, "an integer", lambda v: 1 <= v <= 100, "1 to 100")


def add_parser(sub, help_text: str) -> None:
    """Register `compare` on the command line's subparsers."""
    (points,) = literals("stewart_sim.studies.compare.study", "N_POINTS")
    p = sub.add_parser("compare", help=help_text,
                       description="Sweep each scene's gear ratio (m_d / m_load over "
                                   "0.1-100), re-tune the per-axis PID at every point and track "
                                   "one reference with feedforward none, constant_load and "
                                   "kane; writes comparison.csv, comparison.png and report.md.")
    p.add_argument("scenes", metavar="SCENE", nargs="+", help="scene files (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--points", type=_points, default=points, metavar="N",
                   help=f"log-spaced sweep points per scene (default {points}; the scene's own "
                        "gear ratio is added)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Write the comparison, print the files."""
    from stewart_sim.scene.load import load
    from stewart_sim.shell.outputs import result_set, written_in
    from stewart_sim.studies.compare.files import run_compare

    scenes = [load(s) for s in args.scenes]       # every scene checked before any work
    out = Path(args.out)
    with result_set(out) as stage:
        written = run_compare(scenes, stage, args.points)
    for path in written_in(stage, out, written):
        print(f"wrote {path}")
