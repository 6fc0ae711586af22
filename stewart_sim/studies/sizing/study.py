"""Actuator sizing: the demand of every motion on the scene's own drive, checked against its
motor, and (with a catalogue) every catalogue drive put in the scene's place and checked
against its ratings; the catalogue sweep runs on Dask, one task per drive.

The scene's drive ([drive] and [controller.motor]) is checked, per motion, on:
  stroke_min, stroke_max, cond, force (Kf I_max), current, voltage: cueing.feasibility's margins;
  speed: the peak |ldot| against the drives' no-load speed V_max / Ke' (controller.capability).
A catalogue drive replaces [drive] (gear ratio, pinion radius, rotor inertia: its reflected
inertia changes the rack force) and is checked, per motion, on:
  torque_peak: peak |torque| against peak_torque;
  torque_rms: the worst leg's RMS torque over the motion against continuous_torque;
  motor_speed: peak |motor speed| against max_speed.
Each check's ratio is demand / limit (limit / demand for stroke_min: feasibility.Margin), so
a ratio above 1 is past the limit. A check of a drive's rating is met with the margin m when
ratio (1 + m) <= 1; the stroke and cond(J), properties of the geometry that no drive changes
(and whose ratio of lengths is no fraction of a rating), are met within their limit.
A drive qualifies when it meets every check on every motion; the qualifying drives are ranked
by price (else mass), the others follow by their worst ratio.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from controller.capability import capability
from controller.config import ControllerConfig
from controller.drive import AxisModel
from stewart_fmu.budget import check_count
from stewart_fmu.errors import KinematicsError, StewartError, SweepError
from stewart_fmu.model import Model
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from stewart_sim.cueing.feasibility import Margin
from stewart_sim.shell.progress import Progress

from .catalogue import Drive
from .demand import LegDemand, Statistic, leg_demand
from .motions import Motion

DEFAULT_MARGIN = 0.2     # 20 % of every rating kept free: a common reserve in drive sizing
CANDIDATE_CHECKS = ("torque_peak", "torque_rms", "motor_speed")
ERROR_CHARS = 2000       # a failed drive's error text is cut to this
POINTS_KEPT = 3000       # operating points a task sends back per motion, for the figure only
# bytes one drive's result on one motion holds in the command: its operating points (speed and
# torque, POINTS_KEPT + 2 samples of 6 legs) and its checks and statistics
RESULT_BYTES = (POINTS_KEPT + 2) * 6 * 2 * 8 + 4096


GEOMETRY_CHECKS = ("stroke_min", "stroke_max", "cond")   # judged against the limit alone


def meets(ratio: float, margin: float, quantity: str | None = None) -> bool:
    """Whether a check's ratio (demand / limit) keeps the margin (a fraction of the limit; none
    for GEOMETRY_CHECKS)."""
    return ratio * (1.0 + (0.0 if quantity in GEOMETRY_CHECKS else margin)) <= 1.0


@dataclass(frozen=True)
class SceneSizing:
    """The scene's own drive on every motion: the demand and its checks per motion."""

    demands: tuple[LegDemand, ...]
    checks: tuple[tuple[Margin, ...], ...]     # per motion
    axis: AxisModel | None                     # None: no [drive] or no [controller]
    note: str | None                           # why the motor is not checked, if it is not

    @property
    def peak_torque(self) -> float | None:
        """The motor's most torque, N m: Kt x current_limit."""
        return None if self.axis is None else (self.axis.motor.torque_constant
                                               * self.axis.motor.current_limit)

    @property
    def no_load_speed(self) -> float | None:
        """The motor's no-load speed, rad/s: V_max / Ke."""
        return None if self.axis is None else (self.axis.motor.voltage_limit
                                               / self.axis.motor.back_emf)


def size_scene(model: Model, controller: ControllerConfig | None,
               motions: Sequence[Motion]) -> SceneSizing:
    """The demand of every motion on the scene's drive and its checks."""
    demands = []
    for m in motions:
        try:
            demands.append(leg_demand(model, m, controller))
        except KinematicsError as exc:     # a pose the dynamics refuse: name the motion
            raise type(exc)(f"{m.name}: {exc}") from None
    cap = capability(model, controller)
    checks = []
    for d in demands:
        found = list(d.feasibility.margins)
        if cap.drive is not None:
            found.append(_peak_check("speed", d.values["speed"], d.t, cap.drive.speed, "m/s"))
        checks.append(tuple(found))
    return SceneSizing(tuple(demands), tuple(checks), cap.axis,
                       demands[0].feasibility.drive_note)


@dataclass(frozen=True)
class CandidateMotion:
    """One catalogue drive on one motion: its checks (CANDIDATE_CHECKS) and the peaks."""

    motion: str
    checks: tuple[Margin, ...]
    stats: Mapping[str, Statistic]          # demand.QUANTITIES without current, voltage


@dataclass(frozen=True)
class CandidateResult:
    """One catalogue drive on every motion; `error` when its evaluation failed (then no
    motions), and operating points (motor speed, torque: (K, 6) each, K <= POINTS_KEPT + 2
    samples: operating_points) per motion, for the figure."""

    drive: Drive
    motions: tuple[CandidateMotion, ...]
    points: tuple[tuple[np.ndarray, np.ndarray], ...]
    error: str | None = None

    def worst(self, quantity: str) -> tuple[Margin, str] | None:
        """The largest ratio of one check over the motions, and its motion."""
        found = [(c, m.motion) for m in self.motions for c in m.checks if c.quantity == quantity]
        return max(found, key=lambda cm: cm[0].ratio) if found else None

    @property
    def worst_ratio(self) -> float:
        ratios = [c.ratio for m in self.motions for c in m.checks]
        return max(ratios) if ratios and self.error is None else math.inf

    def qualifies(self, margin: float) -> bool:
        """Every check on every motion met with the margin."""
        return self.error is None and meets(self.worst_ratio, margin)


def evaluate_drive(scene: Mapping[str, Any], source: str | None, drive: Drive,
                   motions: Sequence[Motion]) -> CandidateResult:
    """A catalogue drive in place of the scene's [drive], on every motion (a Dask task: pure,
    of picklable arguments). A failure (a scene rule the drive breaks, a pose the dynamics
    refuse) is the result's error, not an exception."""
    try:
        model = scene_from_dict({**scene, "drive": drive.drive_table}, source)
    except StewartError as exc:
        return CandidateResult(drive, (), (), str(exc)[:ERROR_CHARS])
    return drive_result(model, drive, motions)


def drive_result(model: Model, drive: Drive, motions: Sequence[Motion]) -> CandidateResult:
    """evaluate_drive on a model built with the drive's [drive] table (Drive.drive_table), for
    a caller that has it already: the checks of the ratings need the demand alone
    (leg_demand's checks=False)."""
    try:
        rows, points = [], []
        for m in motions:
            d = leg_demand(model, m, None, checks=False)
            stats = d.statistics()
            torque, speed = d.values["torque"], d.values["motor_speed"]
            checks = (
                _peak_check("torque_peak", torque, d.t, drive.peak_torque, "N m"),
                Margin("torque_rms", stats["torque"].rms / drive.continuous_torque,
                       stats["torque"].rms, drive.continuous_torque, "N m", math.nan, -1,
                       stats["torque"].rms_leg),
                _peak_check("motor_speed", speed, d.t, drive.max_speed, "rad/s"))
            rows.append(CandidateMotion(m.name, checks, stats))
            points.append(operating_points(speed, torque))
        return CandidateResult(drive, tuple(rows), tuple(points))
    except StewartError as exc:
        return CandidateResult(drive, (), (), str(exc)[:ERROR_CHARS])


def operating_points(speed: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every k-th sample of (speed, torque) so that at most POINTS_KEPT are kept, and the
    samples of the peak |speed| and the peak |torque| (a long motion's arrays stay on the
    worker; the peaks are in the checks, exactly)."""
    step = max(1, -(-speed.shape[0] // POINTS_KEPT))
    peaks = [int(np.argmax(np.abs(a)) // a.shape[1]) for a in (speed, torque)]
    rows = np.union1d(np.arange(0, speed.shape[0], step), peaks)
    return speed[rows], torque[rows]


def _peak_check(quantity: str, values: np.ndarray, t: np.ndarray, limit: float,
                unit: str) -> Margin:
    """The sample and leg of the largest |value| against a limit on the magnitude."""
    k, col = np.unravel_index(int(np.argmax(np.abs(values))), values.shape)
    value = float(values[k, col])
    return Margin(quantity, abs(value) / limit, value, float(limit), unit, float(t[k]), int(k),
                  int(col) + 1)


class SizingError(StewartError, ValueError):
    """A sizing whose numbers are not finite (the message names the drive or the motion)."""


@dataclass(frozen=True)
class CatalogueSweep:
    """Every catalogue drive's result, in catalogue order, and where they ran."""

    results: tuple[CandidateResult, ...]
    workers: int
    dashboard: str | None


def sweep_catalogue(scene: Path, drives: Sequence[Drive], motions: Sequence[Motion],
                    scheduler: str | None = None, workers: int | None = None,
                    progress: Progress | None = None) -> CatalogueSweep:
    """evaluate_drive for every drive on Dask: a LocalCluster of `workers` processes (default:
    one per core, at most one per drive), or the running `scheduler`'s workers."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    from stewart_sim.studies.sweep.cluster import dask_client

    data = read_scene_dict(scene)
    n = workers or min(len(drives), os.cpu_count() or 1)
    with dask_client(scheduler, n) as client:
        shared = client.scatter(list(motions), broadcast=True)
        futures = {client.submit(evaluate_drive, data, str(scene), d, shared, pure=False): k
                   for k, d in enumerate(drives)}
        results: list[CandidateResult | None] = [None] * len(drives)
        try:
            for done, fut in enumerate(as_completed(futures), start=1):
                results[futures[fut]] = fut.result()
                if progress is not None:
                    progress.update("catalogue", done, len(drives), unit="drives")
        except (KilledWorker, FutureCancelledError) as exc:
            raise SweepError(None, f"a drive's task was lost on the cluster: {exc}") from None
        count = len(client.scheduler_info()["workers"])
        dashboard = client.dashboard_link
    return CatalogueSweep(tuple(results), count, dashboard)


def check_budget(drives: Sequence[Drive], motions: Sequence[Motion], where: str) -> None:
    """Refuse (BudgetError naming `where`) a catalogue whose results on the motions would not
    fit the memory budget: checked before the sweep starts."""
    check_count(f"{where}: {len(drives)} drives x {len(motions)} motions: results",
                len(drives) * len(motions), RESULT_BYTES, "give fewer drives or motions")


def check_finite(sizing: SceneSizing, results: Sequence[CandidateResult], where: str) -> None:
    """Refuse (SizingError naming the drive of `where`, or the motion) a demand, check or
    statistic that is not finite, before anything is written: numerical trouble is reported,
    never ranked. (A torque_rms check has no time: its t is NaN by design.)"""
    for demand, checks in zip(sizing.demands, sizing.checks):
        bad = _not_finite(checks, demand.statistics())
        if bad:
            raise SizingError(f"{demand.motion}: the scene's drive: {bad} is not finite "
                              "(numerical trouble)")
    for result in results:
        for motion in result.motions:
            bad = _not_finite(motion.checks, motion.stats)
            if bad:
                raise SizingError(f"{where}: drive {result.drive.name!r} on {motion.motion}: "
                                  f"{bad} is not finite (numerical trouble: check its ratings "
                                  "and gearbox)")


def _not_finite(checks: Sequence[Margin], stats: Mapping[str, Statistic]) -> str | None:
    """The first quantity of the checks or statistics with a non-finite number, or None."""
    for c in checks:
        if not all(math.isfinite(v) for v in (c.ratio, c.value, c.limit)):
            return f"{c.quantity} ({c.value!r} {c.unit} against {c.limit!r})"
    for name, s in stats.items():
        if not all(math.isfinite(v) for v in (s.peak.value, s.rms)):
            return f"{name} (peak {s.peak.value!r}, RMS {s.rms!r})"
    return None


def ranking(results: Sequence[CandidateResult], margin: float) -> list[CandidateResult]:
    """The qualifying drives by cost (price, else mass; then name), then the others by their
    worst ratio (failed evaluations last)."""
    good = sorted((r for r in results if r.qualifies(margin)),
                  key=lambda r: (r.drive.cost, r.drive.name))
    rest = sorted((r for r in results if not r.qualifies(margin)),
                  key=lambda r: (r.worst_ratio, r.drive.name))
    return good + rest
