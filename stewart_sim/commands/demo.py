"""`stewart-sim demo SCENE --out DIR [--duration S] [--no-view]`: what `make demo` runs
(stewart_sim.studies.paper.demonstration.run_demo) into DIR, all or nothing."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.shell.argtypes import positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `demo` on the command line's subparsers."""
    duration, rate = literals("controller.moves", "DEMO_DURATION", "DEMO_RATE")
    p = sub.add_parser("demo", help=help_text,
                       description="A smooth six-axis demonstration move, its forces and plot, "
                                   "and the paper rerun into DIR/paper/.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", type=positive_seconds, default=duration, metavar="SECONDS",
                   help=f"length of the demonstration move (default {duration:g} s, "
                        f"sampled at {rate:g} Hz)")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html and "
                        "DIR/paper/view.html)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Write the demonstration set, print the paper's verdicts and the files."""
    from controller.moves import DEMO_RATE
    from stewart_sim.scene.load import load
    from stewart_sim.shell.outputs import result_set, written_in
    from stewart_sim.shell.run_length import check_samples
    from stewart_sim.studies.paper.demonstration import run_demo
    from stewart_sim.studies.paper.files import print_verdicts

    scene = load(args.scene)
    model = scene.model
    check_samples("--duration", args.duration, DEMO_RATE)
    out = Path(args.out)
    with result_set(out) as stage:
        written, results = run_demo(model, scene.controller, stage, args.duration,
                                    view=not args.no_view)
    if results is not None:
        print_verdicts(results)
    for path in written_in(stage, out, written):
        print(f"wrote {path}")
