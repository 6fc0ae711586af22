"""The project's reference moves, from rest at home, sized to each scene's workspace.

* `demo_trajectory`: the smooth six-axis raised-cosine move of `make demo` (and `inverse`).
* `move_and_hold`: quintic moves out and back with holds; `run_reference` is the one `run`,
  `run --link` and the studies track.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from controller.trajectory import Trajectory, leg_references, quintic, sample_times
from stewart_fmu.errors import KinematicsError, TrajectoryError
from stewart_fmu.kinematics import check_poses, inverse_kinematics
from stewart_fmu.model import Model

DEMO_RATE = 1000.0           # Hz
DEMO_DURATION = 4.0          # s
DEMO_FREQUENCIES = (1.0, 1.3, 1.6, 1.15, 1.45, 0.85)  # Hz, one per pose coordinate
DEMO_STROKE_FRACTION = 0.3   # translation amplitude over the smallest stroke margin at home
DEMO_ANGLE = 0.1             # rad, largest rotation amplitude


def demo_trajectory(model: Model, duration: float, rate: float = DEMO_RATE
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A smooth six-axis move from rest at home, q = home + a (1 - cos wt) / 2, exact rates."""
    t = np.arange(int(round(duration * rate)) + 1) / rate
    w = 2 * np.pi * np.asarray(DEMO_FREQUENCIES)
    amplitude = demo_amplitudes(model)
    for _ in range(20):  # halve until the whole move stays in the workspace
        q, qd, qdd = _raised_cosine(model.home, amplitude, w, t)
        try:
            check_poses(model, q, t)
            return t, q, qd, qdd
        except KinematicsError:
            amplitude = amplitude / 2
    raise TrajectoryError(f"scene '{model.name}': no demonstration move fits its workspace")


def demo_amplitudes(model: Model) -> np.ndarray:
    """Translations a fraction of the stroke margin at home, rotations up to DEMO_ANGLE."""
    lengths = inverse_kinematics(model, model.home).lengths
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else math.inf
    margin = float(np.min(np.minimum(lengths - lo, hi - lengths)))
    margin = min(margin, 0.5 * float(np.min(lengths)))  # at most half a leg (no limits)
    linear = DEMO_STROKE_FRACTION * margin
    angle = min(DEMO_ANGLE, linear / model.characteristic_length)
    return np.array([linear, -linear, linear, angle, -angle, angle])


def _raised_cosine(home: np.ndarray, a: np.ndarray, w: np.ndarray, t: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q = home + a (1 - cos wt) / 2 and its first and second time derivatives."""
    wt = np.outer(t, w)
    q = home + a * (1 - np.cos(wt)) / 2
    qd = a * w * np.sin(wt) / 2
    qdd = a * w**2 * np.cos(wt) / 2
    return q, qd, qdd


def move_and_hold(model: Model, rate: float, move_time: float, hold_time: float,
                  back: bool = False, fraction: float = 1.0) -> Trajectory:
    """From rest at home, a quintic six-axis move to home + fraction * demo_amplitudes (a third of
    the stroke margin in translation, up to 0.1 rad in rotation), a hold, and with `back` the
    same move back home and a second hold. The goal is halved until the whole path stays inside
    the stroke and away from singularities. Sampled at `rate` (the controller rate)."""
    if not (move_time > 0 and hold_time >= 0):
        raise TrajectoryError(f"move time {move_time} s must be > 0 and hold time {hold_time} s >= 0")
    amplitude = fraction * demo_amplitudes(model)
    for _ in range(20):
        goal = model.home + amplitude
        parts = [quintic(model.home, goal, rate, move_time)]
        if back:
            parts += [_hold(goal, hold_time, rate), quintic(goal, model.home, rate, move_time)]
        parts.append(_hold(model.home if back else goal, hold_time, rate))
        traj = _concatenate(parts, rate)
        try:
            leg_references(model, traj)
            return traj
        except KinematicsError:
            amplitude = amplitude / 2
    raise TrajectoryError(f"scene '{model.name}': no move fits its workspace")


def _hold(pose: np.ndarray, duration: float, rate: float) -> Trajectory | None:
    if duration <= 0:
        return None
    n = sample_times(duration, rate).size
    zeros = np.zeros((n, 6))
    return Trajectory(sample_times(duration, rate), np.tile(pose, (n, 1)), zeros, zeros.copy())


def _concatenate(parts: Sequence[Trajectory | None], rate: float) -> Trajectory:
    """Join pieces that each start at t = 0 and meet at rest: the first sample of every later
    piece repeats the last of the one before and is dropped."""
    parts = [p for p in parts if p is not None]
    q = np.vstack([parts[0].q] + [p.q[1:] for p in parts[1:]])
    qd = np.vstack([parts[0].qd] + [p.qd[1:] for p in parts[1:]])
    qdd = np.vstack([parts[0].qdd] + [p.qdd[1:] for p in parts[1:]])
    return Trajectory(np.arange(q.shape[0]) / rate, q, qd, qdd)


RUN_MOVE = 0.3               # `run`: each quintic move (out, back) takes this share of the run
RUN_HOLD = 0.2               # ... and each hold after a move this share
RUN_MIN_MOVE_SAMPLES = 10    # ... and has at least this many controller samples


def run_reference(model: Model, config, duration: float):
    """The demonstration reference of `run`: from rest at home a quintic six-axis move out
    (RUN_MOVE of the duration), a hold (RUN_HOLD), the move back and a second hold, sampled
    at the controller rate (move_and_hold)."""
    shortest = RUN_MIN_MOVE_SAMPLES / (RUN_MOVE * config.rate)
    if duration < shortest:
        raise TrajectoryError(f"--duration {duration:g} s is too short: each move needs "
                              f"{RUN_MIN_MOVE_SAMPLES} controller samples ({shortest:.3g} s "
                              f"or more at {config.rate:g} Hz)")
    return move_and_hold(model, config.rate, RUN_MOVE * duration, RUN_HOLD * duration, back=True)
