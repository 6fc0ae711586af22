"""`stewart-sim simulate SCENE --forces F.csv --out DIR [--integrator M] [--frame NAME]`:
open-loop forward dynamics from rack forces (stewart_sim.open_loop.forward)."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame


def add_parser(sub, help_text: str) -> None:
    """Register `simulate` on the command line's subparsers."""
    compiled, scipy = literals("stewart_fmu.integrators", "COMPILED", "SCIPY")
    p = sub.add_parser(
        "simulate", help=help_text,
        description="Simulate the scene's plant open loop from rack forces (a CSV with columns "
                    "t,sigma1..sigma6 in N, held over each interval; the platform starts at "
                    "rest at home). The plant's stroke, singularity and stability checks apply: "
                    "a refused step ends the run with its error and writes nothing. Writes "
                    "DIR/motion.csv (t, x..thz, dx..dthz, l1..l6) and DIR/motion.png.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--forces", required=True, metavar="F.csv",
                   help="columns t,sigma1..sigma6 (further columns ignored: `inverse` output works)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--integrator", choices=compiled + scipy, default=None,
                   help="plant integrator (default: the scene's [solver] method, else "
                        "stability.default_options: rk4 with a stiffness-aware max step)")
    add_frame(p, "motion.csv's poses and rates (and motion.png's) are written in")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run `simulate`; StewartError subclasses for bad input or a refused step."""
    from stewart_fmu.frames import chosen_frame, table_from_platform
    from stewart_sim.open_loop.forward import FILES, read_forces, simulate, write_motion
    from stewart_sim.scene.load import load

    scene = load(args.scene)
    model = scene.model
    frame = chosen_frame(model, args.frame)
    t, sigma = read_forces(Path(args.forces))
    table = simulate(model, t, sigma, args.integrator, options=scene.solver)
    out = Path(args.out)
    write_motion(model, table_from_platform(model, table, frame), out,
                 f"{model.name}: open loop from {Path(args.forces).name}, {frame} frame")
    print(f"simulated {t[-1] - t[0]:g} s ({t.size} samples) open loop; poses in the {frame} "
          "frame")
    for name in FILES:
        print(f"wrote {out / name}")
