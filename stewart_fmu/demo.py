"""The demonstration move of `make demo`: a smooth six-axis move from rest at home."""
from __future__ import annotations

import math

import numpy as np

from .errors import KinematicsError, TrajectoryError
from .kinematics import check_poses, inverse_kinematics
from .model import Model

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
