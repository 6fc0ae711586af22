"""`stewart-sim modes SCENE --pose x,y,z,thx,thy,thz --out DIR`: the small oscillations about the
static equilibrium at a pose (DIR/modes.csv, first columns mode,frequency_hz, ascending), the
stiffness at the pivot (DIR/stiffness.csv) and the mode shapes animated (DIR/view.html), from
the scene's [stiffness] (stewart_sim.studies.modes)."""
from __future__ import annotations

import argparse

from stewart_sim.commands.frame_option import add_frame


def add_parser(sub, help_text: str) -> None:
    """Register `modes` on the command line's subparsers."""
    p = sub.add_parser("modes", help=help_text, description=(
        "Natural frequencies, mode shapes and damping ratios of the platform on its elastic legs "
        "([stiffness]) at a pose, and its stiffness along each axis at a point of the platform."))
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [stiffness] table")
    p.add_argument("--pose", metavar="x,y,z,thx,thy,thz",
                   help="the pose (m, rad; default: the scene's home)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="result directory: modes.csv, stiffness.csv, stiffness_matrix.csv (map.csv)")
    p.add_argument("--payload", metavar="MASS|FILE|KEYS",
                   help="a payload in place of the scene's: a mass in kg (a point mass at C's "
                        "origin), a TOML file ([payload] mass, com, inertia) or those keys inline "
                        "('mass = 50, com = [0, 0, 0.3], inertia = [2, 2, 3]')")
    p.add_argument("--modes", type=int, default=6, metavar="N", help="modes written (1-6; default 6)")
    p.add_argument("--pivot", metavar="x,y,z", default="0,0,0",
                   help="the point of the stiffness table, in C (m; default C's origin)")
    p.add_argument("--map", metavar="GRID", help="map over poses, e.g. 'x=-0.01:0.01:11,z=0.11:0.13:5' "
                   "(start:stop:count per pose component, the others at --pose): DIR/map.csv with the "
                   "lowest frequency and the weakest translational stiffness and its direction, "
                   "and their slices through the first two axes as PNG")
    add_frame(p, "--pose and --map's grid are given in")
    p.add_argument("--no-view", action="store_true",
                   help="do not write the 3D view (by default DIR/view.html: each mode shape "
                        "animated, one cycle per second, its frequency in the title)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Check every input, compute, write the set, print the summary."""
    from stewart_sim.scene.load import load

    scene = load(args.scene)        # a bad scene file fails before the heavy imports
    import numpy as np

    from stewart_sim.studies.modes import report, study

    model = scene.model
    if args.payload is not None:
        model = study.with_payload(model, study.payload_from(args.payload, model))
    from stewart_fmu.frames import chosen_frame, from_platform, to_platform

    frame = chosen_frame(model, args.frame)     # an unknown frame name: one line, exit 2
    given = from_platform(model, model.home, frame) if args.pose is None \
        else study.parse_numbers(args.pose, 6, "--pose")
    q = to_platform(model, np.asarray(given, dtype=float), frame)
    pivot = study.parse_numbers(args.pivot, 3, "--pivot")
    grid = study.parse_grid(args.map, np.asarray(given, dtype=float)) if args.map else None
    result = study.compute(model, q, pivot, args.modes)
    mapped = study.compute_map(model, grid, pivot, frame) if grid is not None else None
    report.write(args.out, result, mapped, grid, view=not args.no_view)
    print(report.summary(result))
