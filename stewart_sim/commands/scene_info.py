"""`stewart-sim scene-info SCENE`: the model a scene builds (stewart_sim.scene.describe), after the
checks every command makes."""
from __future__ import annotations

import argparse


def add_parser(sub, help_text: str) -> None:
    """Register `scene-info` on the command line's subparsers."""
    p = sub.add_parser("scene-info", help=help_text,
                       description="Print the model a scene file builds.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Print the description."""
    from stewart_sim.scene.load import load

    scene = load(args.scene)        # a bad scene file fails before the heavy imports
    from stewart_sim.scene.describe import describe

    print(describe(scene))
