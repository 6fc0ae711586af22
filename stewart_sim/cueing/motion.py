"""The vehicle's motion, the input of motion cueing: specific force and angular velocity in the
vehicle frame, uniformly sampled, and its CSV file.

File format (one header row, then one row per sample, numbers repr-exact):

    t,fx,fy,fz,wx,wy,wz

t in s, strictly increasing with a constant step; fx, fy, fz the specific force (m/s^2) and
wx, wy, wz the angular velocity (rad/s), both in the vehicle frame: x forward, y left, z up,
so a vehicle at rest on level ground reads (0, 0, +9.81) and 0. Specific force is what an
accelerometer at the occupant's head measures: f = a - g (a the acceleration, g gravity).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stewart_fmu.errors import TrajectoryError
from stewart_fmu.io import named_array, read_samples, write_csv

MOTION_COLUMNS = ("t", "fx", "fy", "fz", "wx", "wy", "wz")
UNIFORM_TOLERANCE = 1e-6  # a time step may differ this much (relative) from the first one
# The physical bounds of a vehicle's motion: a sample step from 1 us (1 MHz, beyond any motion
# recording; the perception and washout filters are discretised at it, and a step of 1e-300 s
# leaves them singular) to 10 s, a specific force within 1e3 m/s^2 (100 g) and an angular
# velocity within 1e3 rad/s on each axis.
STEP_BOUNDS = (1e-6, 10.0)
VALUE_BOUNDS = {"f": 1e3, "w": 1e3}


class MotionError(TrajectoryError):
    """A vehicle motion (file or arrays) is malformed; the message names the file, line and
    column when there is one."""


@dataclass(frozen=True)
class VehicleMotion:
    """Specific force and angular velocity of the vehicle, vehicle frame (x forward, y left,
    z up), sampled at the uniform times t."""

    t: np.ndarray                 # (N,) s, uniformly sampled
    specific_force: np.ndarray    # (N, 3) m/s^2; at rest (0, 0, +9.81)
    angular_velocity: np.ndarray  # (N, 3) rad/s

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=float)
        f = np.array(self.specific_force, dtype=float)
        w = np.array(self.angular_velocity, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise MotionError(f"vehicle motion: t must have shape (N,) with N >= 2, got {t.shape}")
        for name, a in (("specific_force", f), ("angular_velocity", w)):
            if a.shape != (t.size, 3):
                raise MotionError(f"vehicle motion: {name} must have shape ({t.size}, 3), "
                                  f"got {a.shape}")
        data = np.column_stack([t, f, w])
        _check_samples(data, "vehicle motion", first_line=0)
        for name, a in (("t", t), ("specific_force", f), ("angular_velocity", w)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @property
    def dt(self) -> float:
        """The sampling step, s."""
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1))


def read_motion(path: str | Path) -> VehicleMotion:
    """Read a vehicle motion CSV (columns MOTION_COLUMNS, see the module doc). A bad file raises
    MotionError naming the file, the line and column, and the reason."""
    try:
        data = read_samples(path, MOTION_COLUMNS, "vehicle motion", min_rows=2)
    except TrajectoryError as exc:
        raise MotionError(str(exc)) from None
    _check_samples(data, str(path), first_line=2)
    return VehicleMotion(data[:, 0], data[:, 1:4], data[:, 4:7])


def write_motion(path: str | Path, motion: VehicleMotion) -> Path:
    """Write a vehicle motion as CSV (MOTION_COLUMNS, repr-exact, atomic)."""
    cols = np.column_stack([motion.t, motion.specific_force, motion.angular_velocity])
    return write_csv(path, named_array({c: cols[:, k] for k, c in enumerate(MOTION_COLUMNS)}))


def first_irregular_step(t: np.ndarray) -> int | None:
    """The first sample k whose step t[k] - t[k-1] is not positive or differs from the first
    step by more than UNIFORM_TOLERANCE (relative); None when t is uniform and increasing."""
    steps = np.diff(np.asarray(t, dtype=float))
    bad = (steps <= 0) | (np.abs(steps - steps[0]) > UNIFORM_TOLERANCE * steps[0])
    return int(np.flatnonzero(bad)[0]) + 1 if np.any(bad) else None


def _check_samples(data: np.ndarray, where: str, first_line: int) -> None:
    """Every value finite, t strictly increasing with a constant step. `first_line` is the
    file line of row 0 (0: arrays, name the sample instead)."""
    def at(row: int, column: str) -> str:
        return (f"line {row + first_line}, column '{column}'" if first_line
                else f"sample {row}, column '{column}'")
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        raise MotionError(f"{where}: {at(r, MOTION_COLUMNS[c])}: non-finite value {data[r, c]}")
    for c, name in enumerate(MOTION_COLUMNS[1:], start=1):
        big = np.flatnonzero(np.abs(data[:, c]) > VALUE_BOUNDS[name[0]])
        if big.size:
            r = int(big[0])
            raise MotionError(f"{where}: {at(r, name)}: {data[r, c]!r} beyond the bound "
                              f"{VALUE_BOUNDS[name[0]]:g} {'m/s^2' if name[0] == 'f' else 'rad/s'}")
    step = float(data[1, 0] - data[0, 0])
    if not STEP_BOUNDS[0] <= step <= STEP_BOUNDS[1]:
        raise MotionError(f"{where}: {at(1, 't')}: sample step {step!r} s must lie within "
                          f"[{STEP_BOUNDS[0]:g}, {STEP_BOUNDS[1]:g}] s")
    r = first_irregular_step(data[:, 0])
    if r is None:
        return
    steps = np.diff(data[:, 0])
    if steps[r - 1] <= 0:
        raise MotionError(f"{where}: {at(r, 't')}: time must increase strictly")
    raise MotionError(f"{where}: {at(r, 't')}: sampling must be uniform: step "
                      f"{float(steps[r - 1])!r} s differs from the first step "
                      f"{float(steps[0])!r} s")
