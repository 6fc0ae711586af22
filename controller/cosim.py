"""The co-simulation master: six axis controllers and their drives around the plant.

At each communication step (the controller period): measure leg lengths and rates, compute the
voltages (PID + feedforward), advance the motor currents, hand the mean motor torques to the
plant, step the plant. The plant is the in-process component (stewart_fmu.plant.Plant) or the
exported FMU driven through fmpy; both see the same calls, so their results are equal.
"""
from __future__ import annotations

import time as wallclock
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba import njit

from stewart_fmu.dynamics import leg_state_kernel
from stewart_fmu.energy import DRIVEN, energy_terms
from stewart_fmu.errors import IntegrationError, StewartError
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.io import POSE, named_array
from stewart_fmu.model import Model
from stewart_fmu.stability import ENERGY_TOL, default_options, internal_step
from stewart_fmu.status import ENERGY_GAIN, STATE_NONFINITE, why
from stewart_fmu.step import INFO_SIZE, METHODS, STEP_GUESS, fixed_substeps, plant_step
from stewart_fmu.transmission import initial_state

from .axis import AxisControllers, MotorCurrents, advance_currents, pid_voltages
from .config import ControllerConfig
from .design import Analysis, PidGains, UnstableLoopError, check_stable, tune_pid
from .drive import AxisModel, axis_model
from .feedforward import feedforward_voltage, start_at_equilibrium
from .plants import PlantPort, PlantStepError
from .trajectory import LegReferences, Trajectory, leg_references

DIVERGENCE_FRACTION = 0.5  # a leg error beyond this fraction of the stroke range means unstable
DIVERGED = -1              # status of the compiled loop: tracking error beyond the bound


@dataclass(frozen=True)
class Summary:
    """Tracking and effort figures of a run."""

    leg_rms: np.ndarray        # (6,) m
    leg_max: np.ndarray        # (6,) m
    pose_rms: np.ndarray       # (6,) m or rad
    pose_max: np.ndarray       # (6,) m or rad
    voltage_rms: np.ndarray    # (6,) V
    current_max: np.ndarray    # (6,) A
    saturated_time: float      # s, any axis at its voltage or current limit
    wall_time: float           # s
    realtime_factor: float     # simulated time / wall time


@dataclass(frozen=True)
class ClosedLoopResult:
    """Every signal per sample (a structured array, one column per signal) and the figures."""

    table: np.ndarray
    summary: Summary
    gains: PidGains
    analysis: Analysis
    axis: AxisModel
    config: ControllerConfig


def run_closed_loop(model: Model, config: ControllerConfig, traj: Trajectory,
                    plant: PlantPort | None = None, gains: PidGains | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    options: IntegratorOptions | None = None) -> ClosedLoopResult:
    """Track traj with the per-axis controllers; raises UnstableLoopError, PlantStepError, or
    IntegrationError (a numerically unstable plant step, as Plant.do_step raises it).
    `options`: the in-process plant's integrator (default: stability.default_options, as Plant)."""
    axis = axis_model(model, config.motor, config.load_mass)
    gains = gains or tune_pid(axis, config.bandwidth, config.phase_margin)
    analysis = check_stable(axis, gains, config.dt)
    _check_rate(traj, config)
    refs = leg_references(model, traj)
    v_ff, i_ff = feedforward_voltage(model, config, axis, traj, refs)
    ctrl, motors = AxisControllers(gains, axis, config.dt), MotorCurrents(axis, config.dt)
    rec = _Recorder(len(traj.t))
    bound = DIVERGENCE_FRACTION * _stroke_range(model, refs)
    if plant is None:  # in-process: the whole loop in one compiled call
        start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff[0], None)
        wall = _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress,
                             options or default_options(model))
    else:
        start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff[0], plant)
        start = wallclock.perf_counter()
        _run_ports(plant, traj, refs, v_ff, ctrl, motors, bound, rec, progress)
        wall = wallclock.perf_counter() - start
    table = rec.table(traj, refs, v_ff)
    return ClosedLoopResult(table, _summary(table, traj, config, wall), gains, analysis, axis, config)


def _run_ports(plant, traj, refs, v_ff, ctrl, motors, bound, rec, progress) -> None:
    """The master's loop in Python, around any PlantPort (e.g. an FMU)."""
    for k, t in enumerate(traj.t):
        l, ldot, q = plant.measure()
        v, sat = ctrl.step(refs.l[k], refs.ldot[k], l, ldot, v_ff[k])
        torque, limited = motors.step(v, ldot)
        rec.add(k, l, ldot, q, v, motors.current, torque, sat | limited)
        err = np.abs(refs.l[k] - l)
        if np.any(err > bound) or not np.all(np.isfinite(err)):
            raise _diverged(float(t), err, bound)
        if k + 1 < len(traj.t):
            plant.step(float(t), float(traj.t[k + 1] - t), torque)
        if progress is not None and k % 1000 == 0:
            progress(k, len(traj.t))


def _diverged(t: float, err: np.ndarray, bound: float) -> UnstableLoopError:
    return UnstableLoopError(f"tracking diverged at t = {t!r} s: leg errors {err.tolist()} m "
                             f"exceed {bound:.3g} m ({DIVERGENCE_FRACTION} of the stroke)")


CHUNK = 20_000  # samples per compiled call, so that long runs can report progress


def _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress, o) -> float:
    """The in-process loop as compiled calls; the same arithmetic as _run_ports with
    InProcessPlant (the default integrator options of stewart_fmu.plant.Plant). Returns the
    loop's wall time, after a zero-sample call has loaded the compiled kernel (the one-time
    cost of a fresh process is not the loop's)."""
    h = float(traj.t[1] - traj.t[0])
    g, m, ax = ctrl.gains, motors.axis.motor, motors.axis
    gain = model.drive.force_per_torque
    y = initial_state(model, traj.q[0], traj.qd[0], motors.current * ax.force_constant)
    energy = np.stack([energy_terms(model, y), np.empty(DRIVEN + 6)])  # step start, step end
    info = np.zeros(INFO_SIZE)
    info[STEP_GUESS] = o.max_step
    n = len(traj.t)

    def chunk(k0: int, k1: int):
        return _loop_kernel(
            model.params, y, traj.t, k0, k1, refs.l, refs.ldot, v_ff, g.kp, g.ki, g.kd,
            m.voltage_limit, ctrl.dt, ctrl.integral, m.resistance, m.torque_constant,
            ax.emf_constant, m.current_limit, motors.decay, motors.mean_decay, motors.current,
            gain, METHODS[o.method], fixed_substeps(h, o.max_step), o.rtol, o.atol, o.max_step,
            o.max_steps, energy, info, bound, rec.data["l"], rec.data["ldot"], rec.data["q"],
            rec.data["v"], rec.data["i"], rec.data["tau"], rec.sat)

    chunk(0, 0)  # load the compiled kernel: no samples, no state change
    start = wallclock.perf_counter()
    for k0 in range(0, n, CHUNK):
        k, status = chunk(k0, min(k0 + CHUNK, n))
        if status:
            break
        if progress is not None:
            progress(min(k0 + CHUNK, n), n)
    wall = wallclock.perf_counter() - start
    if status == DIVERGED:
        raise _diverged(float(traj.t[k]), np.abs(refs.l[k] - rec.data["l"][k]), bound)
    if status in (ENERGY_GAIN, STATE_NONFINITE):  # numerically unstable: as Plant.do_step says
        step = internal_step(o, float(traj.t[k + 1] - traj.t[k]))
        raise IntegrationError(
            f"integration unstable in the step from t = {float(traj.t[k])!r} s ({o.method}, "
            f"internal step {step:.3g} s): {why(status)}", float(traj.t[k]), o.method, step)
    if status:
        raise PlantStepError(
            f"plant refused the step at t = {float(traj.t[k])!r} s: "
            f"{why(status)}; state at the start of the step: "
            f"q = {rec.data['q'][k].tolist()}, leg lengths = {rec.data['l'][k].tolist()} m "
            f"(stroke [{model.leg_min}, {model.leg_max}]), motor torques = "
            f"{rec.data['tau'][k].tolist()} N m")
    return wall


@njit(cache=True, error_model="numpy")
def _loop_kernel(p, y, t, k0, k1, l_ref, ldot_ref, v_ff, kp, ki, kd, vmax, dt, integral, R, Kt,
                 emf, ilim, decay, mean_decay, current, gain, method, n_sub, rtol, atol,
                 max_step, max_steps, energy, info, bound, rec_l, rec_ldot, rec_q, rec_v, rec_i,
                 rec_tau, rec_sat):
    """measure -> PID -> motor currents -> plant step (stewart_fmu.step.plant_step, the step
    Plant takes, with its check) for samples k0..k1-1 (state carried in y, integral, current,
    energy[0] (the energy terms of y) and info); (k, status) of a failure, (-1, 0) when all
    went well."""
    n = t.shape[0]
    ynext, rack = np.empty(y.shape[0]), np.empty(6)
    v, torque = np.empty(6), np.empty(6)
    sat, limited = np.empty(6, np.bool_), np.empty(6, np.bool_)
    for k in range(k0, k1):
        l, ldot, _ = leg_state_kernel(p, y[:6], y[6:12])
        pid_voltages(kp, ki, kd, vmax, dt, integral, l_ref[k], ldot_ref[k], l, ldot, v_ff[k], v, sat)
        advance_currents(R, Kt, emf, ilim, decay, mean_decay, current, v, ldot, torque, limited)
        for i in range(6):
            rec_l[k, i], rec_ldot[k, i], rec_q[k, i] = l[i], ldot[i], y[i]
            rec_v[k, i], rec_i[k, i], rec_tau[k, i] = v[i], current[i], torque[i]
            rec_sat[k, i] = sat[i] or limited[i]
            err = abs(l_ref[k, i] - l[i])
            if not err <= bound:
                return k, DIVERGED
        if k + 1 < n:
            for i in range(6):
                rack[i] = 0.0 + gain * torque[i]  # the plant's rack force: sigma (0) + zeta/r tau
            status = plant_step(p, method, y, ynext, rack, t[k + 1] - t[k], n_sub, rtol, atol,
                                max_step, max_steps, energy[0], energy[1], ENERGY_TOL, info)
            if status != 0:
                return k, status
            y[:] = ynext
            energy[0, :] = energy[1]
    return -1, 0


def _check_rate(traj: Trajectory, config: ControllerConfig) -> None:
    steps = np.diff(traj.t)
    if not np.allclose(steps, config.dt, rtol=1e-9, atol=0):
        raise StewartError(f"trajectory sampled at {1 / np.mean(steps):.6g} Hz; the controller runs "
                           f"at {config.rate:g} Hz: sample the trajectory at the controller rate")


def _stroke_range(model: Model, refs: LegReferences) -> float:
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else 2 * float(np.max(refs.l))
    return hi - lo


class _Recorder:
    """Preallocated signal arrays (no per-step allocation)."""

    def __init__(self, n: int):
        self.data = {k: np.empty((n, 6)) for k in ("l", "ldot", "q", "v", "i", "tau")}
        self.sat = np.zeros((n, 6), dtype=bool)

    def add(self, k, l, ldot, q, v, i, tau, sat) -> None:
        for key, val in (("l", l), ("ldot", ldot), ("q", q), ("v", v), ("i", i), ("tau", tau)):
            self.data[key][k] = val
        self.sat[k] = sat

    def table(self, traj: Trajectory, refs: LegReferences, v_ff: np.ndarray) -> np.ndarray:
        cols = {"time": traj.t}
        for name, arr in (("l_ref", refs.l), ("l", self.data["l"]), ("e", refs.l - self.data["l"]),
                          ("voltage", self.data["v"]), ("v_ff", v_ff), ("current", self.data["i"]),
                          ("torque", self.data["tau"]), ("saturated", self.sat.astype(float))):
            cols.update({f"{name}{i + 1}": arr[:, i] for i in range(6)})
        for k, c in enumerate(POSE):
            cols[f"{c}_ref"] = traj.q[:, k]
            cols[c] = self.data["q"][:, k]
        return named_array(cols)


def _summary(table: np.ndarray, traj: Trajectory, config: ControllerConfig, wall: float) -> Summary:
    def legs(prefix):
        return np.column_stack([table[f"{prefix}{i}"] for i in range(1, 7)])

    e = legs("e")
    pose_err = np.column_stack([table[c] - table[f"{c}_ref"] for c in POSE])
    sat = np.any(legs("saturated") > 0, axis=1)
    duration = float(traj.t[-1] - traj.t[0])
    return Summary(np.sqrt(np.mean(e**2, axis=0)), np.max(np.abs(e), axis=0),
                   np.sqrt(np.mean(pose_err**2, axis=0)), np.max(np.abs(pose_err), axis=0),
                   np.sqrt(np.mean(legs("voltage") ** 2, axis=0)), np.max(np.abs(legs("current")), axis=0),
                   float(np.count_nonzero(sat)) * config.dt, wall, duration / wall if wall > 0 else np.inf)
