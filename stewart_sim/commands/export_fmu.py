"""`stewart-sim export-fmu SCENE -o PLANT.fmu [--fmi-version 2|3]`: the scene's plant as an FMI
co-simulation FMU (stewart_fmu.fmu.export)."""
from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub, help_text: str) -> None:
    """Register `export-fmu` on the command line's subparsers."""
    p = sub.add_parser("export-fmu", help=help_text,
                       description="Build a self-contained FMI 2.0 or 3.0 co-simulation FMU of "
                                   "the scene's plant: the C core and FMI layer compiled with "
                                   "this machine's C compiler (cc, gcc or clang; $CC first), "
                                   "its sources inside for other platforms. The FMU needs no "
                                   "Python, only the platform's C library.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("-o", "--out", required=True, metavar="PLANT.fmu", help="the FMU to write")
    p.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="FMI version of the FMU (default 2)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Export; -o names the file, a directory is refused (the FMU's name is the user's choice,
    not ours)."""
    from stewart_fmu.errors import StewartError
    from stewart_fmu.fmu.export import export_fmu
    from stewart_fmu.io import writing
    from stewart_sim.scene_load import load

    out = Path(args.out)
    if out.is_dir():
        raise StewartError(f"-o {out} is a directory: give the FMU's file name, e.g. "
                           f"{out / 'StewartPlant.fmu'}")
    load(args.scene)   # the scene checked (file, keys) before the compiler runs
    with writing(out):
        export_fmu(args.scene, out, args.fmi_version)
    print(f"wrote {out}")
