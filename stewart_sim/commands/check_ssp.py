"""`stewart-sim check-ssp LOOP.ssp`: an SSP archive's parameter values against the ranges it
declares, before an importer instantiates its FMUs (controller.ssp_check)."""
from __future__ import annotations

import argparse


def add_parser(sub, help_text: str) -> None:
    """Register `check-ssp` on the command line's subparsers."""
    p = sub.add_parser("check-ssp", help=help_text,
                       description="Check every parameter value of an SSP archive's parameter "
                                   "sets against its FMU's declared min and max and the range "
                                   "export-ssp annotates it with. Run it before libcosim: an "
                                   "FMU's error at initialisation aborts libcosim's process.")
    p.add_argument("ssp", metavar="LOOP.ssp", help="the SSP archive to check")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Check; one line either way (a value out of range: exit 2, naming it)."""
    from controller.ssp_check import check_ssp

    result = check_ssp(args.ssp)
    print(f"{args.ssp}: {result.parameters} parameter values of {', '.join(result.components)} "
          f"within their declared ranges")
