"""Global-space trajectories and their leg-length references.

Every generator returns a `Trajectory` (time, pose, pose rates, pose accelerations, exact
derivatives); `leg_references` turns it into leg lengths, rates and accelerations by inverse
kinematics after checking every pose (stroke, singularity) before anything runs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from stewart_fmu.budget import check_count
from stewart_fmu.errors import TrajectoryError
from stewart_fmu.io import read_trajectory
from stewart_fmu.kinematics import check_poses
from stewart_fmu.model import Model

# Minimum-jerk (quintic) profile s(u) = 10u^3 - 15u^4 + 6u^5: peak |s'| and |s''| for u in [0, 1].
QUINTIC_PEAK_RATE = 1.875
QUINTIC_PEAK_ACCELERATION = 10.0 / np.sqrt(3.0)


@dataclass(frozen=True)
class Trajectory:
    """Pose samples with exact first and second time derivatives, (N,) and (N, 6) arrays."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    def __post_init__(self) -> None:
        n = self.t.shape[0]
        for name in ("q", "qd", "qdd"):
            a = getattr(self, name)
            if a.shape != (n, 6):
                raise TrajectoryError(f"trajectory {name} must have shape ({n}, 6), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise TrajectoryError(f"trajectory {name} has non-finite values")
        if n < 2 or np.any(np.diff(self.t) <= 0):
            raise TrajectoryError("trajectory time must have two or more strictly increasing samples")


@dataclass(frozen=True)
class LegReferences:
    """Leg-length references of a trajectory, with the Jacobian's condition number per sample."""

    t: np.ndarray
    l: np.ndarray      # (N, 6) m
    ldot: np.ndarray   # (N, 6) m/s
    lddot: np.ndarray  # (N, 6) m/s^2
    cond: np.ndarray   # (N,)


def sample_times(duration: float, rate: float) -> np.ndarray:
    """0, 1/rate, ..., duration (inclusive)."""
    if not (np.isfinite(duration) and duration > 0 and np.isfinite(rate) and rate > 0):
        raise TrajectoryError(f"duration and rate must be finite and > 0, got {duration}, {rate}")
    # a trajectory holds t, q, qd, qdd (19 float64) a sample, and the checks as many again
    check_count(f"trajectory of {duration:g} s at {rate:g} Hz: samples", duration * rate + 1,
                2 * 19 * 8, "a shorter duration or a lower rate")
    return np.arange(int(round(duration * rate)) + 1) / rate


def constant_acceleration(start: np.ndarray, acceleration: np.ndarray, duration: float,
                          rate: float = 1000.0) -> Trajectory:
    """From rest at start, constant pose accelerations (the paper's Section 3 moves)."""
    t = sample_times(duration, rate)[:, None]
    a = np.broadcast_to(np.asarray(acceleration, dtype=float), (t.shape[0], 6))
    return Trajectory(t[:, 0], start + 0.5 * a * t**2, a * t, a.copy())


def quintic(start: np.ndarray, goal: np.ndarray, rate: float = 1000.0, duration: float | None = None,
            max_rate: np.ndarray | None = None, max_acceleration: np.ndarray | None = None
            ) -> Trajectory:
    """Minimum-jerk point-to-point move from rest to rest; without a duration, the shortest
    one that keeps every coordinate within max_rate and max_acceleration."""
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    d = goal - start
    if duration is None:
        duration = quintic_duration(d, max_rate, max_acceleration)
    t = sample_times(duration, rate)
    s, sd, sdd = minimum_jerk((t / duration)[:, None], duration)
    return Trajectory(t, start + d * s, d * sd, d * sdd)


def minimum_jerk(u, duration: float):
    """The quintic profile s(u) = 10u^3 - 15u^4 + 6u^5 from rest to rest and its first and
    second time derivatives, at u = t / duration in [0, 1] (numbers or arrays)."""
    s = u**3 * (10 - 15 * u + 6 * u**2)
    sd = 30 * u**2 * (1 - u) ** 2 / duration
    sdd = 60 * u * (1 - u) * (1 - 2 * u) / duration**2
    return s, sd, sdd


def quintic_step(t, start: float, duration: float):
    """The minimum-jerk step from 0 (before `start`) to 1 (after `start + duration`) at times
    t, with its first and second time derivatives (arrays like t)."""
    u = np.clip((np.asarray(t, dtype=float) - start) / duration, 0.0, 1.0)
    return minimum_jerk(u, duration)


def quintic_duration(d: np.ndarray, max_rate, max_acceleration) -> float:
    """The shortest quintic duration with peak rates and accelerations within the limits."""
    if max_rate is None or max_acceleration is None:
        raise TrajectoryError("quintic: give a duration or both max_rate and max_acceleration")
    vmax = np.broadcast_to(np.asarray(max_rate, dtype=float), (6,))
    amax = np.broadcast_to(np.asarray(max_acceleration, dtype=float), (6,))
    if np.any(vmax <= 0) or np.any(amax <= 0):
        raise TrajectoryError("quintic: max_rate and max_acceleration must be > 0")
    d = np.abs(d)
    duration = max(np.max(QUINTIC_PEAK_RATE * d / vmax), np.max(np.sqrt(QUINTIC_PEAK_ACCELERATION * d / amax)))
    if duration <= 0:
        raise TrajectoryError("quintic: start and goal are the same pose")
    return float(duration)


def sinusoid(centre: np.ndarray, amplitude: np.ndarray, frequency: np.ndarray, duration: float,
             rate: float = 1000.0, phase: np.ndarray | float = 0.0) -> Trajectory:
    """q = centre + amplitude sin(2 pi f t + phase) per coordinate (Hz, rad)."""
    t = sample_times(duration, rate)[:, None]
    w = 2 * np.pi * np.broadcast_to(np.asarray(frequency, dtype=float), (6,))
    a = np.broadcast_to(np.asarray(amplitude, dtype=float), (6,))
    arg = w * t + phase
    return Trajectory(t[:, 0], centre + a * np.sin(arg), a * w * np.cos(arg), -a * w**2 * np.sin(arg))


def waypoints(times: np.ndarray, poses: np.ndarray, rate: float = 1000.0) -> Trajectory:
    """A C2 path through waypoints (cubic spline, at rest at the first and last one)."""
    times, poses = np.asarray(times, dtype=float), np.asarray(poses, dtype=float)
    if times.ndim != 1 or poses.shape != (times.shape[0], 6) or times.shape[0] < 2:
        raise TrajectoryError(f"waypoints: need N >= 2 times and (N, 6) poses, got {times.shape}, {poses.shape}")
    if np.any(np.diff(times) <= 0):
        raise TrajectoryError("waypoints: times must increase strictly")
    t = times[0] + sample_times(times[-1] - times[0], rate)
    with np.errstate(over="ignore", invalid="ignore"):   # refused below, in one line
        try:
            spline = CubicSpline(times, poses, bc_type="clamped")
        except ValueError:      # the slopes between waypoints overflow: poses far too large
            raise TrajectoryError("waypoints: the slopes between waypoints are not finite "
                                  "(poses too large, or times too close, for a cubic spline)") \
                from None
        q, qd, qdd = spline(t), spline(t, 1), spline(t, 2)
    for name, a in (("poses", q), ("rates", qd), ("accelerations", qdd)):
        if not np.all(np.isfinite(a)):
            raise TrajectoryError(f"waypoints: the path's {name} are not finite (poses too "
                                  "large, or times too close, for a cubic spline)")
    return Trajectory(t, q, qd, qdd)


def waypoints_csv(path: str, rate: float = 1000.0) -> Trajectory:
    """Waypoints from a trajectory CSV (the contract's columns; only t and the pose are used)."""
    t, q, _, _ = read_trajectory(path)
    return waypoints(t, q, rate)


def leg_references(model: Model, traj: Trajectory) -> LegReferences:
    """Leg lengths, rates and accelerations; raises at the first pose past a stroke limit or
    near a singularity (with its sample index and time) before anything runs."""
    kin = check_poses(model, traj.q, traj.t, traj.qd, traj.qdd)
    return LegReferences(traj.t, kin.lengths, kin.rates, kin.accelerations, kin.cond)
