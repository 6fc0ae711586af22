"""`stewart-sim paper [SCENE] --out DIR [--no-view]`: the paper's Section 3 rerun
(stewart_sim.studies.paper.files.run_paper) into DIR, all or nothing."""
from __future__ import annotations

import argparse
from pathlib import Path

DEFAULT_SCENE = Path("scenes") / "micro_manipulator.toml"


def add_parser(sub, help_text: str) -> None:
    """Register `paper` on the command line's subparsers."""
    p = sub.add_parser("paper", help=help_text,
                       description="Rerun the paper's Section 3 experiments and write the report.")
    p.add_argument("scene", metavar="SCENE", nargs="?",
                   help=f"scene file (default: {DEFAULT_SCENE}, from the current directory or "
                        "the source checkout)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html: the six moves)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Rerun, write the report, print the verdicts."""
    from stewart_sim.scene.load import load
    from stewart_sim.shell.outputs import result_set
    from stewart_sim.studies.paper.files import print_verdicts, run_paper

    scene = load(resolve_scene(args.scene))
    out = Path(args.out)
    with result_set(out) as stage:
        report, results = run_paper(scene.model, scene.controller, stage, view=not args.no_view)
    print_verdicts(results)
    print(f"wrote {out / report.relative_to(stage)}")


def resolve_scene(scene: str | None) -> Path:
    """The scene given, else DEFAULT_SCENE here, else the one in the source checkout."""
    from stewart_fmu.errors import SceneError

    if scene is not None:
        return Path(scene)
    if DEFAULT_SCENE.is_file():
        return DEFAULT_SCENE
    checkout = Path(__file__).resolve().parents[2] / DEFAULT_SCENE
    if checkout.is_file():
        return checkout
    raise SceneError("<file>", f"no scene given, and no {DEFAULT_SCENE} in the current directory "
                               f"({Path.cwd()}) or at {checkout}")
