"""`stewart-sim export-ssp SCENE -o LOOP.ssp [--duration S]`: `run`'s closed loop as an SSP 1.0
archive: the plant FMU, the controller FMU carrying `run`'s reference move, their connections
and parameter sets (controller.ssp)."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.shell.argtypes import positive_seconds

from .constants import literals

MAX_MOVE_SAMPLES = 20_000   # the move is compiled into the controller FMU (18 numbers a sample)


def add_parser(sub, help_text: str) -> None:
    """Register `export-ssp` on the command line's subparsers."""
    duration, = literals("controller.moves", "DEMO_DURATION")
    p = sub.add_parser("export-ssp", help=help_text,
                       description="Write `run`'s closed loop as an SSP 1.0 archive: the plant "
                                   "FMU and the controller FMU (FMI 2.0, built with this "
                                   "machine's C compiler), the controller carrying `run`'s "
                                   "reference move and feedforward, the wires plant.l, "
                                   "plant.ldot -> controller, controller.tau -> plant, and a "
                                   "parameter set per FMU. Runs in FMPy's simulate_ssp and "
                                   "libcosim; their exchange after every step delays the "
                                   "torque by one controller period: the SSP is `run` of the "
                                   "scene with controller.delay = 1.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [controller] table")
    p.add_argument("-o", "--out", required=True, metavar="LOOP.ssp", help="the SSP to write")
    p.add_argument("--duration", type=positive_seconds, metavar="SECONDS", default=duration,
                   help=f"length of the move (default {duration:g} s, as `run`)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Export; -o names the file, a directory is refused."""
    from controller.moves import run_reference
    from controller.ssp import export_ssp
    from stewart_fmu.errors import StewartError
    from stewart_fmu.io import writing
    from stewart_fmu.scene import parse_scene_bytes, read_scene_bytes, scene_from_dict
    from stewart_sim.scene.load import scene_of

    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the SSP's file name, e.g. "
                           f"{out / 'loop.ssp'}")
    text = read_scene_bytes(args.scene)
    model = scene_from_dict(parse_scene_bytes(text, args.scene), source=str(args.scene))
    scene = scene_of(model)
    config = scene.require_controller()
    if scene.has_solver:
        raise StewartError("export-ssp: the scene's [solver] sets the in-process plant's "
                           "integrator; the plant FMU integrates with its own: remove [solver]")
    samples = args.duration * config.rate
    if samples > MAX_MOVE_SAMPLES:
        raise StewartError(f"--duration {args.duration:g} s is {samples:.0f} samples at "
                           f"{config.rate:g} Hz: the controller FMU carries at most "
                           f"{MAX_MOVE_SAMPLES} (use --duration "
                           f"{MAX_MOVE_SAMPLES / config.rate:g} or less)")
    traj = run_reference(model, config, args.duration)
    if config.delay == 0:
        print(f"note: {args.scene} has controller.delay = 0; SSP importers step every FMU before "
              f"passing outputs on, which adds one period of actuation delay: the SSP equals "
              f"`run` with controller.delay = 1")
    with writing(out):
        export_ssp(model, text, config, traj, out)
    print(f"wrote {out}")
