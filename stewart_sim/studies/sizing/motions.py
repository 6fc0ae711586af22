"""The motions a drive is sized for, read from their files, the format told by the header:

- a platform trajectory, the `inverse` command's input (columns t,x,y,z,thx,thy,thz, their
  rates d*, accelerations dd*: stewart_fmu.io.TRAJECTORY_COLUMNS), `cue`'s trajectory.csv as it is;
- a vehicle motion (t,fx,fy,fz,wx,wy,wz: stewart_sim/cueing/motion.py, scenes/motions/), cued
  here with the scene's [cueing] classical washout into the platform trajectory `cue` writes
  (the same function, so `cue`'s trajectory.csv and this cue are the same numbers).

Each motion keeps the name it was given on the command line: report rows and peaks name it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from stewart_fmu.errors import TrajectoryError
from stewart_fmu.frames import motion_to_platform
from stewart_fmu.io import TRAJECTORY_COLUMNS, csv_header, read_trajectory
from stewart_sim.cueing.motion import MOTION_COLUMNS, read_motion
from stewart_sim.cueing.washout import classical_washout
from stewart_sim.scene.load import Scene

KINDS = ("platform", "vehicle")   # a platform trajectory, a vehicle motion cued here


class MotionFileError(TrajectoryError):
    """A motion file of `size` is neither format, or is given twice."""


@dataclass(frozen=True)
class Motion:
    """One platform trajectory to fly, in the contract's pose coordinates."""

    name: str          # the file as given
    kind: str          # one of KINDS
    t: np.ndarray      # (N,) s
    q: np.ndarray      # (N, 6) m, rad
    qd: np.ndarray     # (N, 6) their rates (Euler-angle rates)
    qdd: np.ndarray    # (N, 6)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


def motion_kind(path: Path) -> str:
    """'platform' or 'vehicle' by the file's header; MotionFileError for any other header (the
    reading errors of stewart_fmu.io for a file that cannot be read)."""
    header = csv_header(path, "motion")
    if header[:len(TRAJECTORY_COLUMNS)] == TRAJECTORY_COLUMNS:
        return "platform"
    if header[:len(MOTION_COLUMNS)] == MOTION_COLUMNS:
        return "vehicle"
    shown = ",".join(header[:8]) + (",..." if len(header) > 8 else "") if header else "(empty)"
    raise MotionFileError(
        f"{path}: header {shown} is neither a platform trajectory "
        f"({','.join(TRAJECTORY_COLUMNS[:4])},...) nor a vehicle motion "
        f"({','.join(MOTION_COLUMNS)})")


def read_motions(scene: Scene, paths: Sequence[str], frame: str = "platform"
                 ) -> tuple[Motion, ...]:
    """Every motion file read (a platform trajectory given in `frame` of the scene's [frames],
    converted to C's; a vehicle motion cued), in the order given; a file given twice is
    refused."""
    seen: set[Path] = set()
    motions = []
    for name in paths:
        path = Path(name)
        key = path.resolve()
        if key in seen:
            raise MotionFileError(f"{name}: given twice")
        seen.add(key)
        motions.append(read_one(scene, path, name, frame))
    return tuple(motions)


def read_one(scene: Scene, path: Path, name: str, frame: str = "platform") -> Motion:
    """One motion file as a platform trajectory (given in `frame`, converted to C's; a vehicle
    motion cued by the scene's [cueing] classical washout, as `cue` does)."""
    kind = motion_kind(path)
    if kind == "platform":
        t, q, qd, qdd = read_trajectory(path)
        if t.size < 2:      # a peak has a time, an RMS a duration
            raise MotionFileError(f"{path}: need two or more samples, got {t.size}")
        return Motion(name, kind, t, *motion_to_platform(scene.model, q, qd, qdd, frame))
    vehicle = read_motion(path)
    model = scene.model
    cue = classical_washout(scene.cueing, vehicle, np.asarray(model.home, dtype=float),
                            np.asarray(model.gravity, dtype=float))
    return Motion(name, kind, cue.t, cue.q, cue.qd, cue.qdd)
