"""`stewart-sim export-fmu SCENE -o PLANT.fmu [--fmi-version 2|3] [--controller]`: the scene's
plant as an FMI co-simulation FMU (stewart_fmu.fmu.export), or with --controller its per-axis
controllers (controller.fmu)."""
from __future__ import annotations

import argparse
from pathlib import Path

from .constants import literals


def add_parser(sub, help_text: str) -> None:
    """Register `export-fmu` on the command line's subparsers."""
    p = sub.add_parser("export-fmu", help=help_text,
                       description="Build a self-contained FMI 2.0 or 3.0 co-simulation FMU of "
                                   "the scene's plant: the C core and FMI layer compiled with "
                                   "this machine's C compiler (cc, gcc or clang; $CC first), "
                                   "with mingw-w64 also into a Windows DLL, "
                                   "its sources inside for other platforms. The FMU needs no "
                                   "Python, only the platform's C library.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("-o", "--out", required=True, metavar="PLANT.fmu", help="the FMU to write")
    versions, default = literals("stewart_fmu.fmu.export", "FMI_VERSIONS", "DEFAULT_FMI_VERSION")
    p.add_argument("--fmi-version", type=int, choices=versions, default=default,
                   help=f"FMI version of the FMU (default {default})")
    p.add_argument("--controller", action="store_true",
                   help="export the scene's [controller] instead: the six PIDs with anti-windup "
                        "and the motor currents (axis.c, as the closed loop), leg references, "
                        "feedforward voltage and measured leg lengths and rates in, motor "
                        "torques out, at the controller rate (with the scene's "
                        "[controller] delay = 1 a period late: parameter delay)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Export; -o names the file, a directory is refused (the FMU's name is the user's choice,
    not ours)."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.fmu.export import export_model
    from stewart_fmu.io import writing
    from stewart_fmu.scene import parse_scene_bytes, read_scene_bytes, scene_from_dict
    from stewart_sim.scene.load import scene_of

    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the FMU's file name, e.g. "
                           f"{out / 'StewartPlant.fmu'}")
    # The file read once: its bytes go into the FMU, its one Model gives the variables.
    text = read_scene_bytes(args.scene)
    model = scene_from_dict(parse_scene_bytes(text, args.scene), source=str(args.scene))
    scene = scene_of(model)   # every table checked before the compiler runs
    if args.controller:
        from controller.fmu import export_controller

        config = scene.require_controller()
        with writing(out):
            export_controller(model, config, out, args.fmi_version)
    else:
        with writing(out):
            export_model(model, text, out, args.fmi_version)
    print(f"wrote {out}")
