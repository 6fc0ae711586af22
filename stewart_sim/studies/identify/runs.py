"""Run files for `identify`: measured leg lengths and forces over time, read and checked, and the
pose of every sample by forward kinematics.

A run is a CSV with a time column `t` (s; `time` as `run` and `run --link` write it), the leg
lengths `l1..l6` (m) and the rack forces, from the first of these column sets it holds:

- `sigma1..sigma6` (N): measured rack forces (`run --link --record`, a force sensor);
- `force1..force6` (N): the rack forces of `run --link`'s table;
- `torque1..torque6` (N m): motor torques (`run`'s table: the mean torque over each servo
  sample, what the plant received): sigma_i = (zeta / r) tau_i, zeta / r the scene's
  [drive] DriveParams.force_per_torque;
- `current1..current6` (A): motor currents, with the scene's [drive] and [controller.motor]:
  sigma_i = K_t i_i zeta / r (torque_constant K_t). This neglects what lies between the winding
  and the rack beyond the model: gear and rack efficiency (losses proportional to the speed or
  constant land in the identified viscous and Coulomb friction, load-dependent ones do not),
  cogging and torque ripple, K_t's change with temperature and saturation, and the current's
  change within a servo sample (`run` writes the current at the sample's end; the plant
  received the sample's mean torque: prefer torques or forces where the file has them).

`x,y,z,thx,thy,thz` (a measured pose) may be added; any other column is ignored. `simulate`'s
motion.csv has no forces and is refused as such.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from stewart_fmu.errors import TrajectoryError
from stewart_fmu.io import POSE, csv_header, read_samples
from stewart_fmu.kinematics import forward_kinematics_many
from stewart_fmu.model import Model

if TYPE_CHECKING:
    from controller.drive import Motor

LEGS = tuple(f"l{i}" for i in range(1, 7))
TIME_COLUMNS = ("t", "time")
# The force sources, in the order they are looked for: (prefix, what the Run's source says).
FORCE_SOURCES = (("sigma", "sigma"), ("force", "force"),
                 ("torque", "torque (sigma = tau zeta / r)"),
                 ("current", "current (sigma = K_t i zeta / r)"))
# Fewer samples than this: refused. The frequency-domain derivatives (signal.py) need the
# cut-off well inside the band (at most rate / 5, so at least N / 10 spectral bins below it),
# the edges a reflected record loses to the filter and the decimation leave a fraction of the
# rest, and each kept sample gives six equations for up to 36 standard parameters: below 100
# samples none of this holds with a margin.
MIN_SAMPLES = 100
# Sampling times may deviate from a uniform grid (a line fitted to t against the sample index)
# by this fraction of the period: the filters and the derivatives assume one sampling rate,
# and a deviation e shifts a sample by qd e (at 0.1 m/s and 1 kHz, 1e-3 of the period is
# 0.1 um, below a 1 um encoder's resolution). Timestamps written at 1 us resolution pass at
# 1 kHz (5e-4 of the period).
TIME_JITTER = 1e-3
# N: the largest rack force a run may hold. The largest hydraulic actuators push about 1e7 N; a
# force above this is a wrong unit or a corrupt file, not a machine (and well inside it, the
# sums of squares of any record stay finite in float64).
MAX_FORCE = 1e9


@dataclass(frozen=True)
class Run:
    """One run: its samples, the forces in N whatever the file held (`source` says which)."""

    path: Path
    t: np.ndarray                 # (N,) s, uniformly sampled
    lengths: np.ndarray           # (N, 6) m, measured leg lengths
    sigma: np.ndarray             # (N, 6) N, rack forces
    pose: np.ndarray | None       # (N, 6) the measured pose when the file had x..thz
    source: str                   # the force columns used (FORCE_SOURCES)

    @property
    def rate(self) -> float:
        """The sampling rate (Hz): samples per second over the record."""
        return (len(self.t) - 1) / (self.t[-1] - self.t[0])


def read_run(path: str | Path, model: Model, motor: "Motor | None" = None) -> Run:
    """Read and check a run file (see the module doc) against the model's scene; `motor` (the
    scene's [controller.motor]) is needed only for a file with currents alone. Refusals are
    TrajectoryError naming the file and the reason: missing columns, fewer than MIN_SAMPLES
    samples, a time not uniformly sampled (TIME_JITTER), leg lengths outside the stroke, forces
    all zero or beyond MAX_FORCE."""
    path = Path(path)
    header = set(csv_header(path, "run"))
    time = next((c for c in TIME_COLUMNS if c in header), None)
    prefix, source = next(((p, s) for p, s in FORCE_SOURCES
                           if all(f"{p}{i}" in header for i in range(1, 7))), (None, None))
    missing = ([] if time else ["t (or time)"]) + [c for c in LEGS if c not in header]
    if prefix is None:
        missing.append("forces: " + ", ".join(f"{p}1..{p}6" for p, _ in FORCE_SOURCES))
    if missing:
        what = (" (a motion file of `simulate` holds no forces: identification needs measured "
                "ones)" if prefix is None and "dx" in header else "")
        raise TrajectoryError(f"{path}: not a run file: missing columns {'; '.join(missing)}"
                              f"{what}")
    has_pose = all(c in header for c in POSE)
    columns = (time, *LEGS, *(f"{prefix}{i}" for i in range(1, 7)), *(POSE if has_pose else ()))
    data = read_samples(path, columns, "run", anywhere=True)
    if len(data) < MIN_SAMPLES:
        raise TrajectoryError(f"{path}: {len(data)} samples, identification needs at least "
                              f"{MIN_SAMPLES}")
    t, lengths, raw = data[:, 0], data[:, 1:7], data[:, 7:13]
    _check_uniform(path, t)
    _check_stroke(path, model, t, lengths)
    with np.errstate(over="ignore"):     # a converted force beyond float64: refused below
        sigma = _forces(path, model, motor, prefix, raw)
    _check_forces(path, t, sigma, source)
    return Run(path, t, lengths, sigma, data[:, 13:19] if has_pose else None, source)


# Newton to round-off: the filter's second derivative multiplies a pose error by (2 pi f_c)^2, and
# noise-free runs must give the base parameters to 1e-8 (one more iteration than 1e-12 m).
FK_TOL = 1e-14


def pose_of(model: Model, run: Run) -> np.ndarray:
    """The pose (N, 6) of every sample from its measured leg lengths (forward kinematics to
    FK_TOL m in the lengths, all samples at once: stewart_fmu.kinematics.forward_kinematics_many),
    started from the measured pose where the run has one. A sample with no pose: TrajectoryError
    naming the file, the sample and its time."""
    sol = forward_kinematics_many(model, run.lengths, run.pose, tol=FK_TOL)
    bad = np.flatnonzero(~sol.converged)
    if bad.size:
        k = int(bad[0])
        raise TrajectoryError(
            f"{run.path}: sample {k} (t = {run.t[k]:.6g} s): forward kinematics failed: Newton "
            f"did not converge for leg lengths {run.lengths[k].tolist()} m (residual "
            f"{sol.residual[k]:.3g} m from the nearest solved sample; lengths the scene's "
            f"geometry cannot reach or a singular pose){_more(bad)}", index=k, time=float(run.t[k]))
    return sol.poses


def _more(bad: np.ndarray) -> str:
    return f"; {bad.size - 1} more such samples" if bad.size > 1 else ""


def _check_uniform(path: Path, t: np.ndarray) -> None:
    """The samples lie on a uniform grid to TIME_JITTER of the period."""
    k = np.arange(len(t), dtype=float)
    slope, offset = np.polyfit(k, t, 1)
    dev = np.abs(t - (offset + slope * k))
    worst = int(np.argmax(dev))
    if dev[worst] > TIME_JITTER * slope:
        raise TrajectoryError(
            f"{path}: time not uniformly sampled: sample {worst} (t = {t[worst]:.9g} s) is "
            f"{dev[worst]:.3g} s off the uniform grid of period {slope:.6g} s (more than "
            f"{TIME_JITTER:g} of it); the identification's filters and derivatives assume one "
            f"sampling rate: resample the run", index=worst, time=float(t[worst]))


def _check_stroke(path: Path, model: Model, t: np.ndarray, lengths: np.ndarray) -> None:
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else np.inf
    out = ~((lengths >= lo) & (lengths <= hi) & (lengths > 0))
    rows = np.flatnonzero(np.any(out, axis=1))
    if rows.size:
        k = int(rows[0])
        legs = [int(i) + 1 for i in np.flatnonzero(out[k])]
        raise TrajectoryError(
            f"{path}: sample {k} (t = {t[k]:.6g} s): leg(s) {legs} with lengths "
            f"{lengths[k, out[k]].tolist()} m outside the scene's stroke [{lo}, {hi}] m"
            f"{_more(rows)}", index=k, time=float(t[k]))


def _check_forces(path: Path, t: np.ndarray, sigma: np.ndarray, source: str) -> None:
    """The forces are those of a machine: not all zero (a moving platform is pushed by its
    legs, and the identification's noise model and the validation's relative errors need a
    force), none beyond MAX_FORCE in magnitude (after the conversion from `source`)."""
    peak = np.abs(sigma)
    if not np.any(peak > 0.0):
        raise TrajectoryError(f"{path}: every force ({source}) is zero: a run needs the forces "
                              "that moved the platform")
    over = np.flatnonzero(np.any(~(peak <= MAX_FORCE), axis=1))
    if over.size:
        k = int(over[0])
        raise TrajectoryError(
            f"{path}: sample {k} (t = {t[k]:.6g} s): force ({source}) of "
            f"{float(np.max(peak[k])):.3g} N, beyond {MAX_FORCE:g} N: a wrong unit or a "
            f"corrupt file{_more(over)}", index=k, time=float(t[k]))


def _forces(path: Path, model: Model, motor: "Motor | None", prefix: str,
            raw: np.ndarray) -> np.ndarray:
    """The rack forces (N) of the force columns `prefix`1..6 (see FORCE_SOURCES)."""
    if prefix in ("sigma", "force"):
        return raw
    if model.drive is None:
        raise TrajectoryError(f"{path}: forces from {prefix}1..{prefix}6 need the scene's "
                              f"[drive] (gear ratio and pinion radius): the scene has none")
    if prefix == "torque":
        return model.drive.force_per_torque * raw
    if motor is None:
        raise TrajectoryError(f"{path}: forces from current1..current6 need the scene's "
                              f"[controller.motor] torque_constant: the scene has none")
    return (motor.torque_constant * model.drive.force_per_torque) * raw
