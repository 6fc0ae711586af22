"""The evaluation of sweep points: pure functions of (EvalSpec, points) -> one flat row per point.

Each point is the base scene with the point's values put in (stewart_fmu.scene.apply_overrides)
and one of:

  inverse      the inverse dynamics along the point's trajectory: peak |sigma_i| per leg and
               overall (rack force, drive included), peak motor torque sigma r / zeta, peak leg
               power |sigma_i ldot_i|, worst cond(J). Points of one geometry (and gravity)
               share their trajectory, its kinematics and its regressor Y (the inverse
               dynamics is linear in the inertial, drive and friction parameters pi:
               stewart_fmu.dynamics.regressor): one regressor call per trajectory in a task,
               then sigma = Y pi per point (rack_forces), equal to inverse_dynamics to rounding;
  closed_loop  the PID design at the point (controller.design.design_axis) and the closed loop
               tracking the trajectory (stewart_sim.studies.compare.study.run_mode): gains, margins,
               tracking errors, effort;
  envelope     the static (and load-case) forces over a pose grid about home: peak |sigma|,
               worst cond(J) over the reachable poses, the reachable share.
  modes        the scene's [stiffness] at home (stewart_fmu.stiffness.modes_map): the first
               mode's frequency and the weakest translational stiffness at C's origin.

Trajectories (TrajectorySettings.kind): "demo" (controller.moves's six-axis raised-cosine move,
fitted to the point's workspace), "run" (the `run` command's move out and back), "file" (a
trajectory CSV read once by the caller). A point that fails (a bad scene value, a pose past the
stroke or near a singularity, an infeasible design, a diverging loop) is a row with status
"error" and the error's text (cut to ERROR_CHARS); its results are NaN. So is a point whose
results break what they are (`result_problem`: not finite, a magnitude below zero, cond(J) below
1, a share outside [0, 1]): no row with status "ok" carries such a value.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np

from controller.config import ControllerConfig, controller_config
from controller.design import design_axis
from controller.moves import demo_trajectory, run_reference
from controller.trajectory import Trajectory
from stewart_fmu.dynamics import inverse_dynamics, regressor
from stewart_fmu.errors import SceneError, StewartError
from stewart_fmu.kinematics import COND_LIMIT, check_poses, inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.scene import apply_overrides, scene_from_dict
from stewart_fmu.standard import N_STANDARD, standard_parameters
from stewart_sim.studies.compare.study import run_mode
from stewart_fmu.stiffness import modes_map
from stewart_sim.studies.sweep.grid import EnvelopeSettings, TrajectorySettings
from stewart_sim.studies.sweep.joint_layout import LAYOUT_KEYS, apply_layout

LEGS = tuple(f"sigma{i}_max" for i in range(1, 7))
RESULTS = {
    "inverse": (*LEGS, "sigma_max", "torque_max", "power_max", "cond_max"),
    "closed_loop": ("kp", "ki", "kd", "phase_margin", "crossover_hz", "leg_err_rms",
                    "leg_err_max", "pose_err_max_linear", "pose_err_max_angular", "current_max",
                    "voltage_rms", "saturated_time"),
    "envelope": (*LEGS, "sigma_max", "torque_max", "cond_max", "reachable"),
    "modes": ("lowest_hz", "weakest_n_per_um"),
}
# What the results are: magnitudes (peaks, RMS, a time, a frequency) are at least 0, cond(J) at
# least 1, the reachable share at most 1; every other result need only be finite. torque_max is
# NaN (no motor torque to report) exactly when the scene has no [drive] table.
_AT_LEAST = {**dict.fromkeys((*LEGS, "sigma_max", "torque_max", "power_max", "crossover_hz",
                              "leg_err_rms", "leg_err_max", "pose_err_max_linear",
                              "pose_err_max_angular", "current_max", "voltage_rms",
                              "saturated_time", "reachable", "lowest_hz", "weakest_n_per_um"),
                             0.0), "cond_max": 1.0}
_AT_MOST = {"reachable": 1.0}
ERROR_CHARS = 4000   # an error row's text is cut to this (a chunk's rows have a size bound)
MAX_TRAJECTORIES = 16   # geometries whose trajectory and regressor a task or worker keeps
# Failures that make a point a row with its error: the package's typed errors, and numerical
# failures inside third-party code (python-control's design, LAPACK).
POINT_ERRORS = (StewartError, ArithmeticError, ValueError, np.linalg.LinAlgError)


@dataclass(frozen=True)
class EvalSpec:
    """What every point of a sweep shares: sent once per task to wherever it runs."""

    evaluation: str
    scene: Mapping[str, Any]                 # the base scene (parsed TOML)
    trajectory: TrajectorySettings = TrajectorySettings()
    envelope: EnvelopeSettings = EnvelopeSettings()
    files: Mapping[str, tuple[np.ndarray, ...]] = field(default_factory=dict)  # path -> t, q, qd, qdd
    source: str | None = None                # the scene file (for messages)


def columns(evaluation: str, keys: Sequence[str]) -> tuple[str, ...]:
    """The table's columns: point id, the axes, status, error text, the results."""
    return ("point", *keys, "status", "error", *RESULTS[evaluation])


def evaluate_batch(spec: EvalSpec, points: Sequence[tuple[int, Mapping[str, Any]]],
                   cache: "TrajectoryCache | None" = None) -> list[dict[str, Any]]:
    """Rows of several points (a task); trajectories shared by points of one geometry are
    computed once (in `cache`, which may outlive the task: a worker's, for one sweep)."""
    cache = TrajectoryCache() if cache is None else cache
    return [evaluate_point(spec, pid, values, cache) for pid, values in points]


class TrajectoryCache(OrderedDict):
    """The trajectories (with kinematics and regressor, a few MB each) of the geometries seen
    last: at most MAX_TRAJECTORIES, the least recently used dropped."""

    def __getitem__(self, key: str) -> Any:
        self.move_to_end(key)
        return super().__getitem__(key)

    def __setitem__(self, key: str, value: Any) -> None:
        super().__setitem__(key, value)
        while len(self) > MAX_TRAJECTORIES:
            self.popitem(last=False)


def evaluate_point(spec: EvalSpec, pid: int, values: Mapping[str, Any],
                   cache: dict[str, Any] | None = None) -> dict[str, Any]:
    """The row of one point; failures become a row with status "error"."""
    row: dict[str, Any] = {"point": pid, **values, "status": "ok", "error": ""}
    nan = dict.fromkeys(RESULTS[spec.evaluation], np.nan)
    try:
        results = _EVALUATE[spec.evaluation](spec, values, {} if cache is None else cache)
    except SceneError as exc:  # the point's values, not the scene file: name the point
        text = (f"SceneError: {point_label(pid, values)}: scene key '{exc.key}': "
                f"{exc.reason}")
        return _failed(row, text, nan)
    except POINT_ERRORS as exc:
        text = str(exc) if isinstance(exc, _RunFailed) else f"{type(exc).__name__}: {exc}"
        return _failed(row, text, nan)
    checked = {name: float(results.get(name, np.nan)) for name in nan}
    drive = has_drive(spec.scene)
    for name, value in checked.items():
        problem = result_problem(name, value, drive)
        if problem is not None:
            return _failed(row, f"result {name} = {value!r}: {problem}", nan)
    return {**row, **checked}


def _failed(row: dict[str, Any], text: str, nan: Mapping[str, float]) -> dict[str, Any]:
    """The row of a point that failed: its error's text (cut to ERROR_CHARS), NaN results."""
    text = text or "failed, without a message"
    if len(text) > ERROR_CHARS:
        text = text[:ERROR_CHARS - 3] + "..."
    return {**row, "status": "error", "error": text, **nan}


def has_drive(scene: Mapping[str, Any]) -> bool:
    """Whether the base scene (parsed TOML) has a [drive] table: torque_max exists."""
    return isinstance(scene.get("drive"), Mapping)


def result_problem(name: str, value: float, drive: bool) -> str | None:
    """Why `value` cannot be the result `name` of a point evaluated without error (None: it
    can); `drive`: the scene has a [drive] table (has_drive). A finite value within
    result_bounds(name) always can."""
    if math.isnan(value) and name == "torque_max" and not drive:
        return None
    if not math.isfinite(value):
        return "not finite"
    low, high = result_bounds(name)
    if value < low:
        return f"below {low:g}"
    if value > high:
        return f"above {high:g}"
    return None


def result_bounds(name: str) -> tuple[float, float]:
    """The least and the most a result may be (-inf, inf: any finite value)."""
    return _AT_LEAST.get(name, -math.inf), _AT_MOST.get(name, math.inf)


def point_label(pid: int | None, values: Mapping[str, Any]) -> str:
    """'grid point 3 (geometry.leg_max = 0.05, platform.mass = 0.5)' for messages."""
    inner = ", ".join(f"{k} = {v!r}" for k, v in values.items())
    return ("grid point" if pid is None else f"grid point {pid}") + f" ({inner})"


def point_scene(spec: EvalSpec, values: Mapping[str, Any]) -> dict[str, Any]:
    """The point's scene dict: the base scene with the point's scene and controller values."""
    overrides = {k: v for k, v in values.items()
                 if not k.startswith("trajectory.") and k not in LAYOUT_KEYS}
    return apply_layout(apply_overrides(spec.scene, overrides), values)


def point_model(spec: EvalSpec, values: Mapping[str, Any]) -> Model:
    """The point's Model (SceneError for a value the scene rejects)."""
    return scene_from_dict(point_scene(spec, values), spec.source)


def point_trajectory(spec: EvalSpec, values: Mapping[str, Any]) -> TrajectorySettings:
    """The trajectory settings with the point's trajectory.* values."""
    t = {k.split(".", 1)[1]: v for k, v in values.items() if k.startswith("trajectory.")}
    return replace(spec.trajectory, **t)


def trajectory(spec: EvalSpec, model: Model, settings: TrajectorySettings,
               rate: float, config: ControllerConfig | None = None) -> Trajectory:
    """The point's trajectory (closed loop: sampled at the controller `rate`; the "run"
    reference needs the point's [controller] table, `config`)."""
    if settings.kind == "file":
        return Trajectory(*spec.files[settings.file])
    if settings.kind == "run":
        if config is None:
            raise StewartError("sweep: trajectory kind 'run' needs the scene's [controller] table")
        return run_reference(model, replace(config, rate=rate), settings.duration)
    return Trajectory(*demo_trajectory(model, settings.duration, rate))


def _inverse(spec: EvalSpec, values: Mapping[str, Any], cache: dict[str, Any]) -> dict[str, float]:
    data = point_scene(spec, values)
    model = scene_from_dict(data, spec.source)
    settings = point_trajectory(spec, values)
    config = controller_config(model) if settings.kind == "run" else None
    rate = settings.rate if config is None else config.rate
    # the trajectory and its kinematics depend on the geometry only; Y on it and gravity
    key = repr((sorted(data["geometry"].items()), data.get("gravity"), model.effects,
                settings, rate))
    if key not in cache:
        traj = trajectory(spec, model, settings, rate, config)
        kin = check_poses(model, traj.q, traj.t, traj.qd, traj.qdd)
        y = regressor(model, traj.q, traj.qd, traj.qdd).reshape(-1, N_STANDARD)
        cache[key] = (traj, kin.rates, float(kin.cond.max()), y)
    traj, rates, cond, y = cache[key]
    sigma = rack_forces(model, traj.q, y)
    return {**_peaks(model, sigma), "power_max": float(np.max(np.abs(sigma * rates))),
            "cond_max": cond}


def rack_forces(model: Model, q: np.ndarray, y: np.ndarray) -> np.ndarray:
    """sigma (N, 6) of the model along poses q (N, 6) whose regressor rows are y (6N,
    N_STANDARD): Y pi, the inverse dynamics of any model of that geometry and gravity."""
    return (y @ standard_parameters(model)).reshape(np.shape(q))


def _peaks(model: Model, sigma: np.ndarray) -> dict[str, float]:
    """Peak |sigma| per leg and overall, and the peak motor torque it takes (NaN: no drive)."""
    peak = np.max(np.abs(sigma), axis=0)
    d = model.drive
    torque = np.nan if d is None else float(peak.max()) * d.pinion_radius / d.gear_ratio
    return {**dict(zip(LEGS, map(float, peak))), "sigma_max": float(peak.max()),
            "torque_max": torque}


def _closed_loop(spec: EvalSpec, values: Mapping[str, Any], cache: dict[str, Any]
                 ) -> dict[str, float]:
    model = point_model(spec, values)
    config = controller_config(model)
    traj = trajectory(spec, model, point_trajectory(spec, values), config.rate, config)
    _, gains, analysis = design_axis(model, config)
    run = run_mode(model, config, traj, gains, config.feedforward)
    if run.status != "ok":
        raise _RunFailed(run.message)
    return {"kp": gains.kp, "ki": gains.ki, "kd": gains.kd,
            "phase_margin": analysis.phase_margin_deg, "crossover_hz": analysis.crossover_hz,
            "leg_err_rms": run.leg_rms, "leg_err_max": run.leg_max,
            "pose_err_max_linear": run.pose_max_linear,
            "pose_err_max_angular": run.pose_max_angular, "current_max": run.current_max,
            "voltage_rms": run.voltage_rms, "saturated_time": run.saturated_time}


class _RunFailed(StewartError):
    """The closed loop failed; the message already names the error (diverged, step refused)."""


def _envelope(spec: EvalSpec, values: Mapping[str, Any], cache: dict[str, Any]) -> dict[str, float]:
    model = point_model(spec, values)
    poses = model.home + spec.envelope.offsets()
    ok, cond = reachable(model, poses)
    if not ok.any():
        raise StewartError(f"no pose of the envelope's {len(poses)} is reachable (stroke, "
                           f"singularity)")
    acc = np.array(spec.envelope.accelerations)
    q = np.repeat(poses[ok], len(acc), axis=0)
    qdd = np.tile(acc, (int(ok.sum()), 1))
    sigma = inverse_dynamics(model, q, np.zeros_like(q), qdd)
    return {**_peaks(model, sigma), "cond_max": float(cond[ok].max()),
            "reachable": float(ok.mean())}


def reachable(model: Model, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which poses lie within the stroke and away from singularities, and cond(J) of each."""
    kin = inverse_kinematics(model, poses)
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else np.inf
    inside = np.all((kin.lengths >= lo) & (kin.lengths <= hi) & (kin.lengths > 0), axis=1)
    return inside & (kin.cond < COND_LIMIT), kin.cond


def _modes(spec: EvalSpec, values: Mapping[str, Any], cache: dict[str, Any]) -> dict[str, float]:
    model = point_model(spec, values)
    at_home = modes_map(model, np.asarray(model.home, dtype=float)[None])
    return {"lowest_hz": float(at_home.lowest_hz[0]),
            "weakest_n_per_um": float(at_home.weakest[0]) * 1e-6}


_EVALUATE = {"inverse": _inverse, "closed_loop": _closed_loop, "envelope": _envelope,
             "modes": _modes}
