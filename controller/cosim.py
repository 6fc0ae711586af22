"""The co-simulation master: six axis controllers and their drives around the plant.

At each communication step (the controller period): measure leg lengths and rates, compute the
voltages (PID + feedforward), advance the motor currents, hand the mean motor torques to the
plant, step the plant. The plant is the in-process component (stewart_fmu.stepper.Plant) or the
exported FMU driven through fmpy; both see the same calls, so their results are equal.
"""
from __future__ import annotations

import math
import time as wallclock
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Protocol

import numpy as np
from numba import njit

from stewart_fmu.dynamics import _leg_state, inverse_dynamics
from stewart_fmu.errors import StewartError
from stewart_fmu.integrators import _A, _E, IntegratorOptions, dopri5_advance, rk4_advance
from stewart_fmu.io import POSE, named_array
from stewart_fmu.model import Model
from stewart_fmu.stability import default_options
from stewart_fmu.stepper import _WHY, Plant, StepRejected
from stewart_fmu.transmission import initial_state

from .axis import AxisControllers, MotorCurrents, advance_currents, pid_voltages
from .config import ControllerConfig
from .design import Analysis, DesignError, PidGains, analyse, sampled_spectral_radius, tune_pid
from .drive import AxisModel, axis_model
from .trajectory import LegReferences, Trajectory, leg_references

DIVERGENCE_FRACTION = 0.5  # a leg error beyond this fraction of the stroke range means unstable
DIVERGED = -1              # status of the compiled loop: tracking error beyond the bound


class UnstableLoopError(DesignError):
    """The closed loop is unstable (by analysis before the run, or diverging during it)."""


class PlantStepError(StewartError):
    """The plant refused a step (stroke, singularity) during a closed-loop run."""


class PlantPort(Protocol):
    """What the master needs of a plant."""

    def start(self, q0: np.ndarray, qd0: np.ndarray, t0: float,
              torque0: np.ndarray) -> None: ...  # torque0: held from the start
    def step(self, t: float, h: float, torque: np.ndarray) -> None: ...
    def measure(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...  # l, ldot, q


class InProcessPlant:
    """stewart_fmu.stepper.Plant behind the PlantPort calls."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None):
        self.plant = Plant(model, options)

    def start(self, q0, qd0, t0, torque0) -> None:
        self.plant.setup_experiment(t0)
        self.plant.enter_initialization_mode()
        self.plant.set_initial(q0, qd0)
        self.plant.set_torque(torque0)
        self.plant.exit_initialization_mode()

    def step(self, t, h, torque) -> None:
        self.plant.set_torque(torque)
        try:
            self.plant.do_step(t, h)
        except StepRejected as exc:
            raise PlantStepError(str(exc)) from None

    def measure(self):
        out = self.plant.outputs
        return out.lengths, out.rates, out.q


class FmuPlant:
    """The exported FMU driven through fmpy's FMU2Slave."""

    def __init__(self, path: str | Path):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.unzipdir = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName="plant")
        self.vr_tau = [self.vr[f"tau[{i}]"] for i in range(1, 7)]
        names = [f"l[{i}]" for i in range(1, 7)] + [f"ldot[{i}]" for i in range(1, 7)] + list(POSE)
        self.vr_out = [self.vr[n] for n in names]

    def start(self, q0, qd0, t0, torque0) -> None:
        f = self.fmu
        f.instantiate()
        f.setupExperiment(startTime=t0)
        f.enterInitializationMode()
        f.setReal([self.vr[f"q0[{k}]"] for k in range(1, 7)], list(map(float, q0)))
        f.setReal([self.vr[f"qd0[{k}]"] for k in range(1, 7)], list(map(float, qd0)))
        f.setReal(self.vr_tau, list(map(float, torque0)))
        f.exitInitializationMode()

    def step(self, t, h, torque) -> None:
        from fmpy.fmi1 import FMICallException

        self.fmu.setReal(self.vr_tau, list(map(float, torque)))
        try:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        except FMICallException as exc:
            raise PlantStepError(f"FMU refused the step at t = {t!r} s: {exc}") from None

    def measure(self):
        v = np.array(self.fmu.getReal(self.vr_out))
        return v[:6], v[6:12], v[12:18]

    def close(self) -> None:
        """Terminate, free the instance and delete the unzipped FMU."""
        import shutil

        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipdir, ignore_errors=True)


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


def design_axis(model: Model, config: ControllerConfig) -> tuple[AxisModel, PidGains, Analysis]:
    """The constant-load drive, its tuned gains and the loop's analysis; refuses unstable loops."""
    axis = axis_model(model, config.motor, config.load_mass)
    gains = tune_pid(axis, config.bandwidth, config.phase_margin)
    return axis, gains, check_stable(axis, gains, config.dt)


def check_stable(axis: AxisModel, gains: PidGains, dt: float) -> Analysis:
    """analyse(), raising UnstableLoopError (with the margins) when the continuous loop or the
    loop sampled at dt is unstable."""
    a = analyse(axis, gains)
    rho = sampled_spectral_radius(axis, gains, dt)
    if not a.stable or not rho < 1.0:
        where = "closed loop" if not a.stable else f"loop sampled at {1 / dt:g} Hz (spectral radius {rho:.4g})"
        raise UnstableLoopError(
            f"{where} unstable with gains {gains}: gain margin {a.gain_margin_db:.3g} dB, "
            f"phase margin {a.phase_margin_deg:.3g} deg at {a.crossover_hz:.3g} Hz")
    return a


def feedforward_force(model: Model, config: ControllerConfig, axis: AxisModel,
                      traj: Trajectory, refs: LegReferences) -> np.ndarray | None:
    """Leg forces the feedforward of config.feedforward supplies (None: no feedforward)."""
    if config.feedforward == "kane":
        return inverse_dynamics(model, traj.q, traj.qd, traj.qdd)
    if config.feedforward == "constant_load":
        return axis.moving_mass * refs.lddot + axis.viscous * refs.ldot
    return None


def feedforward_voltage(model: Model, config: ControllerConfig, axis: AxisModel,
                        traj: Trajectory, refs: LegReferences) -> tuple[np.ndarray, np.ndarray]:
    """(voltage, current) feedforward per sample: R i + L di/dt + Ke' ldot_ref for the
    feedforward force's current i = F / Kf (the device computes the same from F and dF/dt)."""
    force = feedforward_force(model, config, axis, traj, refs)
    if force is None:
        return np.zeros_like(refs.l), np.zeros_like(refs.l)
    current = force / axis.force_constant
    di = np.gradient(force, traj.t, axis=0) / axis.force_constant
    return axis.voltage(current, di, refs.ldot), current


def run_closed_loop(model: Model, config: ControllerConfig, traj: Trajectory,
                    plant: PlantPort | None = None, gains: PidGains | None = None,
                    progress: Callable[[int, int], None] | None = None) -> ClosedLoopResult:
    """Track traj with the per-axis controllers; raises UnstableLoopError or PlantStepError."""
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
        wall = _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress)
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


def _run_compiled(model, traj, refs, v_ff, ctrl, motors, bound, rec, progress) -> float:
    """The in-process loop as compiled calls; the same arithmetic as _run_ports with
    InProcessPlant (the default integrator options of stewart_fmu.stepper.Plant). Returns the
    loop's wall time, after a zero-sample call has loaded the compiled kernel (the one-time
    cost of a fresh process is not the loop's)."""
    o = default_options(model)
    h = float(traj.t[1] - traj.t[0])
    n_sub = max(1, math.ceil(h / o.max_step - 1e-9))
    g, m, ax = ctrl.gains, motors.axis.motor, motors.axis
    gain = model.drive.gear_ratio / model.drive.pinion_radius
    y = initial_state(model, traj.q[0], traj.qd[0], motors.current * ax.force_constant)
    h_try = np.array([o.max_step])
    n = len(traj.t)

    def chunk(k0: int, k1: int):
        return _loop_kernel(
            model.params, y, traj.t, k0, k1, refs.l, refs.ldot, v_ff, g.kp, g.ki, g.kd,
            m.voltage_limit, ctrl.dt, ctrl.integral, m.resistance, m.torque_constant,
            ax.emf_constant, m.current_limit, motors.decay, motors.mean_decay, motors.current,
            gain, n_sub, o.method == "rk4", o.rtol, o.atol, o.max_step, o.max_steps, _A, _E,
            h_try, bound, rec.data["l"], rec.data["ldot"], rec.data["q"], rec.data["v"],
            rec.data["i"], rec.data["tau"], rec.sat)

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
    if status:
        raise PlantStepError(
            f"plant refused the step at t = {float(traj.t[k])!r} s: "
            f"{_WHY.get(status, f'status {status}')}; state at the start of the step: "
            f"q = {rec.data['q'][k].tolist()}, leg lengths = {rec.data['l'][k].tolist()} m "
            f"(stroke [{model.leg_min}, {model.leg_max}]), motor torques = "
            f"{rec.data['tau'][k].tolist()} N m")
    return wall


@njit(cache=True, error_model="numpy")
def _loop_kernel(p, y, t, k0, k1, l_ref, ldot_ref, v_ff, kp, ki, kd, vmax, dt, integral, R, Kt,
                 emf, ilim, decay, mean_decay, current, gain, n_sub, use_rk4, rtol, atol,
                 max_step, max_steps, A, E, h_try, bound, rec_l, rec_ldot, rec_q, rec_v, rec_i,
                 rec_tau, rec_sat):
    """measure -> PID -> motor currents -> plant step for samples k0..k1-1 (state carried in
    y, integral, current, h_try); (k, status) of a failure, (-1, 0) when all went well."""
    n = t.shape[0]
    ynext, rack = np.empty(y.shape[0]), np.empty(6)
    v, torque = np.empty(6), np.empty(6)
    sat, limited = np.empty(6, np.bool_), np.empty(6, np.bool_)
    for k in range(k0, k1):
        l, ldot, _ = _leg_state(p, y[:6], y[6:12])
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
            h = t[k + 1] - t[k]
            if use_rk4:
                status = rk4_advance(p, y, ynext, rack, h, n_sub)
            else:
                status, h_try[0], _, _ = dopri5_advance(p, y, ynext, rack, h, h_try[0], rtol,
                                                        atol, max_step, max_steps, A, E)
            if status != 0:
                return k, status
            y[:] = ynext
    return -1, 0


def _check_rate(traj: Trajectory, config: ControllerConfig) -> None:
    steps = np.diff(traj.t)
    if not np.allclose(steps, config.dt, rtol=1e-9, atol=0):
        raise StewartError(f"trajectory sampled at {1 / np.mean(steps):.6g} Hz; the controller runs "
                           f"at {config.rate:g} Hz: sample the trajectory at the controller rate")


def start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff0, plant) -> None:
    """The drives hold the platform at the first pose before the move (bumpless start): the
    integral supplies what the feedforward's resistive and back-EMF parts do not, so the
    feedforward's inductive part (L di/dt) still reaches the motor from the first sample."""
    hold = inverse_dynamics(model, traj.q[0], traj.qd[0], np.zeros(6))
    motors.current = hold / motors.axis.force_constant
    v_hold = motors.axis.voltage(motors.current, 0.0, 0.0)
    v_static = motors.axis.voltage(i_ff0, 0.0, refs.ldot[0])
    ctrl.integral = (v_hold - v_static) / gains.ki if gains.ki > 0 else np.zeros(6)
    if plant is not None:
        plant.start(traj.q[0], traj.qd[0], float(traj.t[0]),
                    motors.current * motors.axis.motor.torque_constant)


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
