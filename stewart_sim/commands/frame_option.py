"""`--frame NAME`, the one definition of the option every command that reads or writes poses
takes (standard library only: `--help` stays fast); stewart_fmu.frames.chosen_frame resolves
it against the scene's [frames]."""
from __future__ import annotations

import argparse

from stewart_sim.commands.constants import literals


def add_frame(parser: argparse.ArgumentParser, what: str) -> None:
    """`--frame NAME` on `parser`: `what` says which poses (e.g. "the trajectory T.csv is
    written in")."""
    (names,) = literals("stewart_fmu.reach_params", "FRAME_NAMES")
    parser.add_argument("--frame", metavar="NAME",
                        help=f"the frame {what}: {', '.join(names)} (the scene's [frames]; "
                             "default: its [frames] default, else platform, the contract's "
                             "pose of C in N)")
