"""The co-simulation master: six axis controllers and their drives around the plant.

At each communication step (the controller period): measure leg lengths and rates, compute the
voltages (PID + feedforward), advance the motor currents, hand the mean motor torques to the
plant, step the plant (with the scene's [controller] delay = 1, the torques of the sample before:
ControllerConfig). The plant is the in-process component (stewart_fmu.plant.Plant) or the
exported FMU driven through fmpy; both see the same calls, so their results are equal. With
the in-process plant the whole loop runs in C (controller/native/axis.c, closed_loop_run, around
the plant's C core stewart_step), a chunk of samples per call.
"""
from __future__ import annotations

import time as wallclock
from dataclasses import dataclass
from typing import Callable

import numpy as np

from stewart_fmu.errors import IntegrationError, StewartError
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.io import POSE, named_array
from stewart_fmu.model import Model
from stewart_fmu.native import core
from stewart_fmu.stability import ENERGY_TOL, default_options, internal_step
from stewart_fmu.status import ENERGY_GAIN, STATE_NONFINITE
from stewart_fmu.transmission import initial_state

from .axis import AxisControllers, MotorCurrents, servo_step
from .config import ControllerConfig, scene_axis
from .design import Analysis, PidGains, UnstableLoopError, check_stable, tune_pid
from .drive import AxisModel
from .feedforward import feedforward_voltage, start_at_equilibrium
from .native._axis import ffi, lib
from .plants import PlantPort, PlantStepError
from .trajectory import LegReferences, Trajectory, leg_references

DIVERGENCE_FRACTION = 0.5  # a leg error beyond this fraction of the stroke range means unstable
DIVERGED = lib.AXIS_DIVERGED  # status of the C loop: tracking error beyond the bound (-1)


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
    axis = scene_axis(model, config)
    gains = gains or tune_pid(axis, config.bandwidth, config.phase_margin)
    analysis = check_stable(axis, gains, config.dt, config.delay)
    _check_rate(traj, config)
    refs = leg_references(model, traj)
    v_ff, i_ff = feedforward_voltage(model, config, axis, traj, refs)
    ctrl, motors = AxisControllers(gains, axis, config.dt), MotorCurrents(axis, config.dt)
    rec = _Recorder(len(traj.t))
    bound = DIVERGENCE_FRACTION * _stroke_range(model, refs)
    if plant is None:  # in-process: the whole loop in C (controller/native/axis.c)
        start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff[0], None)
        wall = _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress,
                             options or default_options(model), _held(config, motors))
    else:
        start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff[0], plant)
        start = wallclock.perf_counter()
        _run_ports(plant, traj, refs, v_ff, ctrl, motors, bound, rec, progress,
                   _held(config, motors))
        wall = wallclock.perf_counter() - start
    table = rec.table(traj, refs, v_ff)
    return ClosedLoopResult(table, _summary(table, traj, config, wall), gains, analysis, axis, config)


def _held(config: ControllerConfig, motors: MotorCurrents) -> np.ndarray | None:
    """The torques latched for the first period with one period of actuation delay (the drives'
    start: the torque the plant was started with), None without delay."""
    if config.delay == 0:
        return None
    return np.ascontiguousarray(motors.current * motors.axis.motor.torque_constant, dtype=np.float64)


def _run_ports(plant, traj, refs, v_ff, ctrl, motors, bound, rec, progress, held) -> None:
    """The master's loop in Python, around any PlantPort (e.g. an FMU): one servo_step per
    sample; held (_held): None, or the latched torques of one period of delay."""
    for k, t in enumerate(traj.t):
        l, ldot, q = plant.measure()
        v, torque, saturated = servo_step(ctrl, motors, refs.l[k], refs.ldot[k], l, ldot, v_ff[k])
        rec.add(k, l, ldot, q, v, motors.current, torque, saturated)
        err = np.abs(refs.l[k] - l)
        if np.any(err > bound) or not np.all(np.isfinite(err)):
            raise _diverged(float(t), err, bound)
        if k + 1 < len(traj.t):
            plant.step(float(t), float(traj.t[k + 1] - t), torque if held is None else held)
            if held is not None:  # latched after the step, as closed_loop_run
                held = torque
        if progress is not None and k % 1000 == 0:
            progress(k, len(traj.t))


def _diverged(t: float, err: np.ndarray, bound: float) -> UnstableLoopError:
    return UnstableLoopError(f"tracking diverged at t = {t!r} s: leg errors {err.tolist()} m "
                             f"exceed {bound:.3g} m ({DIVERGENCE_FRACTION} of the stroke)")


CHUNK = 20_000  # samples per C call, so that long runs can report progress
# The C core's statuses of the step's check, as stewart_fmu.status names them.
_STATUS = {core.UNSTABLE: ENERGY_GAIN, core.STATE_NONFINITE: STATE_NONFINITE}


def _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress, o, held) -> float:
    """The in-process loop in C (controller/native/axis.c: closed_loop_run, CHUNK samples per
    call, the plant step being the C core's stewart_step); the same arithmetic as _run_ports
    with InProcessPlant (the default integrator options of stewart_fmu.plant.Plant); held as
    there, updated in place. Returns the loop's wall time."""
    g, m, ax = ctrl.gains, motors.axis.motor, motors.axis
    n = len(traj.t)
    P = model.native
    opts = core.options(o.method, o.rtol, o.atol, o.max_step, o.max_steps, ENERGY_TOL)
    d = ffi.new("stewart_data *")          # the plant's state, carried from call to call
    y = initial_state(model, traj.q[0], traj.qd[0], motors.current * ax.force_constant)
    d.n = y.shape[0]
    ffi.memmove(d.y, y.astype(np.float64).tobytes(), y.nbytes)
    core.lib.stewart_energy_terms(P.ptr, d.y, d.energy)
    d.t, d.step_guess = float(traj.t[0]), o.max_step
    c = ffi.new("axis_loop *", dict(
        kp=g.kp, ki=g.ki, kd=g.kd, vmax=m.voltage_limit, dt=ctrl.dt, R=m.resistance,
        Kt=m.torque_constant, emf=ax.emf_constant, ilim=m.current_limit, decay=motors.decay,
        mean_decay=motors.mean_decay, gain=model.drive.force_per_torque, bound=bound))
    ctrl.integral = np.ascontiguousarray(ctrl.integral, dtype=np.float64)
    motors.current = np.ascontiguousarray(motors.current, dtype=np.float64)
    inputs = [np.ascontiguousarray(a, dtype=np.float64) for a in (traj.t, refs.l, refs.ldot, v_ff)]
    keep = [ffi.from_buffer(a) for a in inputs]
    out = {k: rec.data[k] for k in ("l", "ldot", "q", "v", "i", "tau")}
    r = ffi.new("axis_records *")
    bufs = [ffi.from_buffer(a, require_writable=True) for a in (*out.values(), rec.sat)]
    for name, b in zip(("l", "ldot", "q", "v", "i", "tau"), bufs):
        setattr(r, name, ffi.cast("double *", b))
    r.sat = ffi.cast("unsigned char *", bufs[-1])
    integral, current = ffi.from_buffer(ctrl.integral), ffi.from_buffer(motors.current)
    held_buf = ffi.NULL if held is None else ffi.from_buffer(held, require_writable=True)
    k_fail = ffi.new("long *")
    start = wallclock.perf_counter()
    status = 0
    for k0 in range(0, n, CHUNK):
        status = lib.closed_loop_run(P.ptr, opts, c, d, integral, current, keep[0], n, keep[1],
                                     keep[2], keep[3], k0, min(k0 + CHUNK, n), held_buf, r,
                                     k_fail)
        if status:
            break
        if progress is not None:
            progress(min(k0 + CHUNK, n), n)
    wall = wallclock.perf_counter() - start
    k = k_fail[0]
    if status == DIVERGED:
        raise _diverged(float(traj.t[k]), np.abs(refs.l[k] - rec.data["l"][k]), bound)
    status = _STATUS.get(status, status)
    if status:  # the state in d is the failed step's start: the core's one refusal message
        t_k, h = float(traj.t[k]), float(traj.t[k + 1] - traj.t[k])
        y = np.frombuffer(ffi.buffer(d.y), dtype=np.float64)[:d.n]
        tau = rec.data["tau"][k] if held is None else held   # the failed step's torques
        rack = 0.0 + model.drive.force_per_torque * tau  # as closed_loop_run
        text = core.refusal(P, o.method, t_k, h, status, y, rack, d.excess, d.allowed)
        if status in (ENERGY_GAIN, STATE_NONFINITE):  # numerically unstable: as Plant.do_step
            step = internal_step(o, h)
            raise IntegrationError(f"{text}; internal step {step:.3g} s", t_k, o.method, step)
        raise PlantStepError(text)
    return wall


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
