"""`stewart-sim trajectory SCENE (--waypoints W.csv | --move demo|run|quintic) --out T.csv
[--rate HZ] [--duration S] [--frame NAME]`: a smooth reference trajectory in the `inverse`
format (stewart_sim.open_loop.references), in a frame of the scene's [frames]."""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.commands.constants import literals
from stewart_sim.commands.frame_option import add_frame
from stewart_sim.shell.argtypes import positive_rate, positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `trajectory` on the command line's subparsers."""
    duration, rate = literals("controller.moves", "DEMO_DURATION", "DEMO_RATE")
    (moves,) = literals("stewart_sim.open_loop.references", "MOVES")
    p = sub.add_parser(
        "trajectory", help=help_text,
        description="Write a smooth trajectory with exact rates and accelerations, checked by "
                    "inverse kinematics, in the format `inverse` reads (t, x..thz, dx..dthz, "
                    "ddx..ddthz): a spline through waypoints, or one of the project's moves "
                    "(demo: raised cosines; run: quintic out, hold, back, hold; quintic: one "
                    "minimum-jerk move to the demo goal).")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--waypoints", metavar="W.csv",
                      help="columns t,x,y,z,thx,thy,thz (m, rad): a C2 spline through them, at "
                           "rest at both ends")
    what.add_argument("--move", choices=moves, help="one of the project's moves from rest at home")
    p.add_argument("--out", required=True, metavar="T.csv", help="trajectory to write (atomically)")
    p.add_argument("--rate", type=positive_rate, default=None, metavar="HZ",
                   help=f"sample rate (default {rate:g} Hz; --move run: the scene's "
                        "controller rate if it has a [controller] table)")
    p.add_argument("--duration", type=positive_seconds, default=None, metavar="S",
                   help=f"length of the move (default {duration:g} s; not with --waypoints, "
                        "whose times set it)")
    add_frame(p, "the waypoints are given in and T.csv is written in (its poses, rates and "
                 "accelerations)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run `trajectory`; StewartError subclasses for bad input."""
    from controller.moves import DEMO_DURATION, DEMO_RATE
    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_sim.open_loop.references import (checked, move, waypoint_trajectory,
                                                  write_trajectory)
    from stewart_sim.scene.load import load

    scene = load(args.scene)
    model = scene.model
    frame = chosen_frame(model, args.frame)
    if args.waypoints is not None:
        if args.duration is not None:
            raise StewartError("trajectory: --duration applies to --move only (the waypoint "
                               "times set the length)")
        traj = waypoint_trajectory(Path(args.waypoints), args.rate or DEMO_RATE, model, frame)
        what = f"spline through {args.waypoints}"
    else:
        traj = move(model, args.move, args.duration or DEMO_DURATION, args.rate, scene.controller)
        what = f"{args.move} move"
    checked(model, traj)
    out = Path(args.out)
    write_trajectory(traj, out, model, frame)
    rate = (traj.t.size - 1) / (traj.t[-1] - traj.t[0])
    print(f"wrote {out}: {what}, {traj.t.size} samples over {traj.t[-1] - traj.t[0]:g} s "
          f"at {rate:g} Hz, {frame} frame")
