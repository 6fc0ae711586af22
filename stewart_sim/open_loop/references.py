"""Smooth reference trajectories in the `inverse` format: what `stewart-sim trajectory SCENE
(--waypoints W.csv | --move demo|run|quintic) --out T.csv [--rate HZ] [--duration S]` writes
(stewart_sim.commands.trajectory).

The trajectories are those the controller builds (controller.trajectory, controller.moves),
with exact rates and accelerations:

* `--waypoints W.csv`: a C2 cubic spline through the poses of W.csv (columns t,x,y,z,thx,thy,thz;
  further columns, e.g. a whole trajectory file's rates, are ignored), at rest at the first
  and last waypoint, sampled at --rate from the first to the last waypoint time.
* `--move demo`: the raised-cosine six-axis move of `demo` (controller.moves.demo_trajectory).
* `--move run`: the reference `run` tracks: a quintic move out (30 % of the duration), a hold
  (20 %), the move back and a second hold (controller.moves.move_and_hold).
* `--move quintic`: one minimum-jerk move from rest at home to the demo goal (home plus a
  third of the stroke margin, up to 0.1 rad), over the whole duration.

Every sample is checked by inverse kinematics (stroke, singularity: leg_references) before the
file is written (atomically). The output has the contract's columns (stewart_fmu.io
TRAJECTORY_COLUMNS) and feeds `stewart-sim inverse` as it is. With `--frame F` the waypoints
are F's poses (converted to C's before the spline) and the file holds F's motion
(stewart_fmu.frames.motion_from_platform), which `inverse --frame F` reads.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from controller.config import ControllerConfig
from controller.moves import DEMO_RATE, RUN_HOLD, RUN_MOVE, demo_trajectory, move_and_hold
from controller.trajectory import Trajectory, leg_references, waypoints
from stewart_fmu import io
from stewart_fmu.budget import BudgetError
from stewart_fmu.errors import StewartError
from stewart_fmu.frames import motion_from_platform, to_platform
from stewart_fmu.io import POSE, writing
from stewart_fmu.model import Model

MOVES = ("demo", "run", "quintic")
WAYPOINT_COLUMNS = ("t", *POSE)


def move(model: Model, name: str, duration: float, rate: float | None = None,
         controller: ControllerConfig | None = None) -> Trajectory:
    """The named move of the scene (MOVES), sampled at `rate` (None: the default; for "run",
    the rate of `controller`, the scene's [controller] table, when it has one)."""
    if name == "demo":
        rate = rate or DEMO_RATE
        return Trajectory(*demo_trajectory(model, duration, rate))
    if name == "run":
        if rate is None:
            rate = DEMO_RATE if controller is None else controller.rate
        return move_and_hold(model, rate, RUN_MOVE * duration, RUN_HOLD * duration, back=True)
    if name == "quintic":
        return move_and_hold(model, rate or DEMO_RATE, duration, 0.0)
    raise StewartError(f"trajectory: move '{name}' unknown: one of {', '.join(MOVES)}")


def waypoint_trajectory(path: Path, rate: float, model: Model | None = None,
                        frame: str = "platform") -> Trajectory:
    """controller.trajectory.waypoints through the poses of a waypoint CSV, given in `frame`
    (of `model`'s [frames]; the spline runs through their poses of C)."""
    times, poses = read_waypoints(path)
    if frame != "platform":
        poses = to_platform(model, poses, frame)
    try:
        return waypoints(times, poses, rate)
    except BudgetError as exc:     # the samples its times ask for: name the file
        raise BudgetError(f"{path}: {exc}") from None


def read_waypoints(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """t (N,) and poses (N, 6) of a CSV whose header starts with t,x,y,z,thx,thy,thz."""
    data = io.read_samples(path, WAYPOINT_COLUMNS, "waypoints", prefix=True, min_rows=2)
    return data[:, 0].copy(), data[:, 1:].copy()


def checked(model: Model, traj: Trajectory) -> Trajectory:
    """Every sample inside the stroke and away from singularities (KinematicsError names the
    first bad sample and its time)."""
    leg_references(model, traj)
    return traj


def write_trajectory(traj: Trajectory, out: Path, model: Model | None = None,
                     frame: str = "platform") -> Path:
    """The trajectory (C's motion) in the contract's columns, as `frame`'s motion (of `model`'s
    [frames]), atomically."""
    q, qd, qdd = traj.q, traj.qd, traj.qdd
    if frame != "platform":
        q, qd, qdd = motion_from_platform(model, q, qd, qdd, frame)
    with writing(out):
        return io.write_csv(out, io.trajectory_table(traj.t, q, qd, qdd))
