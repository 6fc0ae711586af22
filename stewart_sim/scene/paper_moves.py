"""The paper's six test moves (Section 3.1) on a scene's model: from rest at home, one pose
axis at a time (x, y, z, thx, thy, thz) at a constant acceleration, every pose checked. The paper
rerun (stewart_sim.studies.paper) computes their forces; the 3D view of a paper directory
(stewart_sim.view.sources) draws them again from the same definition."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import KinematicsError
from stewart_fmu.kinematics import check_poses, inverse_kinematics
from stewart_fmu.model import Model

TRAJECTORIES = ("x", "y", "z", "thx", "thy", "thz")
LINEAR_ACCELERATION = 10.0   # m/s^2, paper 3.1
ANGULAR_ACCELERATION = 8.0   # rad/s^2 (Euler-angle acceleration), paper 3.1


@dataclass(frozen=True)
class Trajectory:
    """One constant-acceleration move from rest at home, with its leg kinematics."""

    name: str
    axis: int                 # index into the pose (x, y, z, thx, thy, thz)
    acceleration: float       # m/s^2 or rad/s^2
    q: np.ndarray             # (N, 6)
    qd: np.ndarray            # (N, 6)
    qdd: np.ndarray           # (N, 6)
    lengths: np.ndarray       # (N, 6) l_i
    rates: np.ndarray         # (N, 6) ldot_i
    accelerations: np.ndarray  # (N, 6) lddot_i
    cond: np.ndarray          # (N,) scaled cond(J)


def make_trajectory(model: Model, name: str, t: np.ndarray) -> Trajectory:
    """q = home + a t^2 / 2 on one axis, from rest; raises if it leaves the workspace."""
    axis = TRAJECTORIES.index(name)
    acc = LINEAR_ACCELERATION if axis < 3 else ANGULAR_ACCELERATION
    q = np.tile(model.home, (t.size, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    q[:, axis] += 0.5 * acc * t**2
    qd[:, axis] = acc * t
    qdd[:, axis] = acc
    _check_workspace(model, name, q, t)
    kin = inverse_kinematics(model, q, qd, qdd)
    return Trajectory(name, axis, acc, q, qd, qdd, kin.lengths, kin.rates, kin.accelerations,
                      kin.cond)


def _check_workspace(model: Model, name: str, q: np.ndarray, t: np.ndarray) -> None:
    """check_poses, with the trajectory named in the error."""
    try:
        check_poses(model, q, t)
    except KinematicsError as exc:
        err = type(exc)(f"paper trajectory '{name}' on scene '{model.name}': {exc}")
        err.index, err.time = exc.index, exc.time
        raise err from exc
