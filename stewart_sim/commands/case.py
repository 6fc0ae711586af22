"""`stewart-sim case SCENE [--duration S]`: a shipped stiff or extreme scene's [case] against
the outcome it expects (stewart_sim.studies.cases.report; exit status 1 on a mismatch)."""
from __future__ import annotations

import argparse

from stewart_sim.shell.argtypes import positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `case` on the command line's subparsers."""
    p = sub.add_parser(
        "case", help=help_text,
        description="Run the [case] of a scene (scenes/stiff, scenes/extreme: a hold, a move or "
                    "a closed loop) and report its outcome (ok, or the typed error that ended "
                    "it, with where) against the outcome the case expects, with its figures. "
                    "Exit status 0 when they agree, 1 when they do not.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [case] table")
    p.add_argument("--duration", type=positive_seconds, default=None, metavar="S",
                   help="run this long instead of the case's duration (e.g. a short look at "
                        "the hour-long hold)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the case, print the report; exit status 1 (SystemExit) on a mismatch, else 0."""
    from stewart_sim.scene.load import load
    from stewart_sim.studies.cases.outcome import run_case
    from stewart_sim.studies.cases.report import MISMATCH_STATUS, agrees, report

    scene = load(args.scene)
    model, case = scene.model, scene.require_case()
    result = run_case(model, case, scene.controller, duration=args.duration)
    print(report(model.name, case, result, args.duration))
    if not agrees(case, result):
        raise SystemExit(MISMATCH_STATUS)
    return 0
