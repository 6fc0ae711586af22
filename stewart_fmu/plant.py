"""The plant as an FMI 2.0 co-simulation component, in-process.

`Plant` follows the FMI life cycle (instantiate, setup experiment, initialization mode, set
inputs, do_step, get outputs, get/set/serialize state, reset, terminate) and checks the call
sequence itself, as the FMI Reference FMUs do. Each step is the C core's (step.plant_step), the
same step the exported FMU's binary takes.

State is (t, y) plus the held inputs and the adaptive step guess: everything a master needs
to roll back exactly (`get_state` / `set_state`, `serialize_state` / `deserialize_state`);
y = (q, qd), and with a compliant transmission (q, qd, s, sd) (see transmission.py).

Every step is checked for numerical instability (stability.py): a non-finite state, or energy
growing beyond the work of the held rack forces (power balance), raises IntegrationError with
the time, the integrator, its step and advice, and leaves the state at the start of the step.
"""
from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, replace

import numpy as np

from stewart_fmu.dynamics import forward_dynamics, inverse_dynamics_parts, leg_state, present_parts
from stewart_fmu.energy import DRIVEN, energy_terms
from stewart_fmu.errors import IntegrationError, StewartError, TrajectoryError
from stewart_fmu.integrators import COMPILED, IntegratorOptions, derivative, scipy_advance
from stewart_fmu.kinematics import check_poses, condition_number, inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.stability import advice, default_options, internal_step
from stewart_fmu.status import ENERGY_GAIN, STATE_NONFINITE, why
from stewart_fmu.step import (
    check_step,
    plant_step,
)
from stewart_fmu.transmission import initial_state, spring_forces

STATE_VERSION = 2        # 2: plain data with a checksum (1 was a pickle)
_MAGIC = b"STEWART-PLANT"
_HEADER = "<13sIBI"
_HEAD_SIZE = struct.calcsize(_HEADER)
PHASES = ("instantiated", "initialization", "stepping", "terminated")


class CallSequenceError(StewartError):
    """An FMI call out of order or with bad arguments (the FMU returns fmi2Error)."""


class StepRejected(StewartError):
    """A step would leave the valid region; the state stays at the start of the step
    (the FMU returns fmi2Discard: roll back or take a smaller step)."""

    def __init__(self, message: str, time: float, status: int):
        self.time, self.status = time, status
        super().__init__(message)


@dataclass(frozen=True)
class PlantState:
    """Everything needed to restore a Plant exactly (immutable; arrays are copies)."""

    phase: str
    time: float
    y: np.ndarray            # (12,) q then qd; (24,) then s, sd with a transmission
    force: np.ndarray        # (6,) rack forces sigma_i (N), held over a step
    torque: np.ndarray       # (6,) motor torques (N m), held over a step
    step_guess: float        # next internal step of the adaptive method (s)
    start_time: float
    initial: np.ndarray      # (12,) the initial q, qd of this experiment


class Outputs:
    """Outputs after the last step, computed on first use (cond(J) and the breakdown cost)."""

    def __init__(self, plant: "Plant"):
        self.plant = plant

    def _get(self, name: str, compute):
        cache = self.plant._cache
        if name not in cache:
            cache[name] = compute()
        return cache[name]

    @property
    def q(self) -> np.ndarray:
        return self.plant._y[:6].copy()

    @property
    def qd(self) -> np.ndarray:
        return self.plant._y[6:12].copy()

    def _legs(self):
        y = self.plant._y
        return self._get("legs", lambda: leg_state(self.plant.model, y[:6], y[6:12]))

    @property
    def spring_force(self) -> np.ndarray | None:
        """The transmission forces on the legs (N), None without a [transmission]."""
        p = self.plant
        if p.model.transmission is None:
            return None
        return self._get("spring", lambda: spring_forces(p.model, p._y))

    @property
    def lengths(self) -> np.ndarray:
        return self._legs()[0]

    @property
    def rates(self) -> np.ndarray:
        return self._legs()[1]

    @property
    def twist(self) -> np.ndarray:
        """(v, omega) of the platform in N."""
        return np.r_[self.plant._y[6:9], self._legs()[2]]

    @property
    def cond(self) -> float:
        """cond(J), scaled (the core's SVD, as the FMU's: computed only when asked for)."""
        y = self.plant._y
        return self._get("cond", lambda: condition_number(self.plant.model, y[:6]))

    @property
    def qdd(self) -> np.ndarray:
        return self._get("qdd", lambda: self._ydot()[6:12].copy())

    def _ydot(self) -> np.ndarray:
        p = self.plant
        if p.model.transmission is None:
            return np.r_[p._y[6:], forward_dynamics(p.model, p._y[:6], p._y[6:], p._rack)]
        return self._get("ydot", lambda: derivative(p.model.params, p._y, p._rack)[0])

    @property
    def parts(self) -> dict[str, np.ndarray]:
        """How the rack force splits: platform, legs, drives, gravity, friction (sums to it).
        With a transmission: the leg-side parts sum to the spring force, and drives = m_d sdd."""
        return self._get("parts", self._parts)

    def _parts(self) -> dict[str, np.ndarray]:
        p = self.plant
        out = {k: v[0] for k, v in inverse_dynamics_parts(
            p._leg_model, p._y[:6], p._y[6:12], self.qdd).items()}
        if p.model.transmission is not None:
            out["drives"] = p.model.drive.reflected_masses * self._ydot()[18:]
        return {k: out[k] for k in present_parts(p.model)}


class Plant:
    """The Stewart platform plant as an FMI co-simulation component (see the module doc)."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None):
        self.model = model
        self.options = options or default_options(model)
        # The leg side of a compliant transmission: the model without the drive inertia.
        self._leg_model = (model if model.transmission is None
                           else replace(model, drive=None, transmission=None))
        self._drive_gain = model.drive.force_per_torque if model.drive is not None else 0.0
        self._initial = np.r_[model.home, np.zeros(6)]
        self._set_fresh()

    @property
    def options(self) -> IntegratorOptions:
        return self._options

    @options.setter
    def options(self, value: IntegratorOptions) -> None:
        self._options = value
        self._native_options = value.native() if value.method in COMPILED else None

    # --- life cycle ------------------------------------------------------------------------

    def _set_fresh(self) -> None:
        self._phase = "instantiated"
        self._start = 0.0
        self._t = 0.0
        self._y = self._initial.copy()
        self._force = np.zeros(6)
        self._torque = np.zeros(6)
        self._rack = np.zeros(6)
        self._step_guess = self.options.max_step
        self._next = np.empty(self.model.state_size)  # the step's result; swapped on success
        self._energy: np.ndarray | None = None        # energy_terms of _y (power balance)
        self._energy_next = np.empty(DRIVEN + 6)      # ... of _next (swapped on success)
        self._excess = self._allowed = 0.0            # the last step's power balance (J)
        self.evaluations = 0          # right-hand-side evaluations so far
        self._cache: dict = {}
        self._outputs = Outputs(self)

    @property
    def phase(self) -> str:
        return self._phase

    @property
    def time(self) -> float:
        return self._t

    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        """Start time and (optionally) the integrator's relative tolerance."""
        self._require("setup_experiment", "instantiated")
        _finite_scalar("start_time", start_time)
        if tolerance is not None:
            if not (math.isfinite(tolerance) and tolerance > 0):
                raise CallSequenceError(f"setup_experiment: tolerance must be > 0, got {tolerance}")
            self.options = replace(self.options, rtol=tolerance)
        self._start = self._t = float(start_time)

    def enter_initialization_mode(self) -> None:
        self._require("enter_initialization_mode", "instantiated")
        self._phase = "initialization"

    def set_initial(self, q=None, qd=None) -> None:
        """Initial pose and pose rates (before or during initialization mode)."""
        self._require("set_initial", "instantiated", "initialization")
        for name, value, sl in (("q", q, slice(0, 6)), ("qd", qd, slice(6, 12))):
            if value is not None:
                self._initial[sl] = _finite_vector(name, value)
        self._y = self._initial_state()

    def _initial_state(self) -> np.ndarray:
        """y at the initial q, qd; a transmission starts preloaded with the held rack force."""
        return initial_state(self.model, self._initial[:6], self._initial[6:], self._rack)

    def exit_initialization_mode(self) -> None:
        """Check the initial pose (stroke, singularity) and start stepping."""
        self._require("exit_initialization_mode", "initialization")
        check_poses(self.model, self._y[:6])
        self._y = self._initial_state()
        self._energy = None
        self._phase = "stepping"
        self._cache.clear()

    def terminate(self) -> None:
        self._require("terminate", "initialization", "stepping")
        self._phase = "terminated"

    def reset(self) -> None:
        """Back to the state right after instantiation (options and initial values kept)."""
        self._set_fresh()

    # --- inputs and outputs ----------------------------------------------------------------

    def set_force(self, sigma) -> None:
        """Rack forces sigma_i (N) held from now on."""
        self._require("set_force", "instantiated", "initialization", "stepping")
        self._force = _finite_vector("force", sigma)
        self._inputs_changed()

    def set_torque(self, tau) -> None:
        """Motor torques (N m), added to the rack force as zeta / r * tau (needs a [drive])."""
        self._require("set_torque", "instantiated", "initialization", "stepping")
        if self.model.drive is None:
            raise CallSequenceError("set_torque: the scene has no [drive]: set rack forces instead")
        self._torque = _finite_vector("torque", tau)
        self._inputs_changed()

    def hold_inputs(self, force: np.ndarray, torque: np.ndarray) -> None:
        """Set both inputs without copying or checking them (an adapter that already checked
        each value, e.g. the FMU slave); use set_force / set_torque otherwise."""
        self._force, self._torque = force.copy(), torque.copy()
        self._inputs_changed()

    def _inputs_changed(self) -> None:
        self._rack = self._force + self._drive_gain * self._torque
        self._cache.clear()

    @property
    def rack_force(self) -> np.ndarray:
        """The total force at each rack: sigma + zeta / r * tau."""
        return self._rack.copy()

    @property
    def outputs(self) -> Outputs:
        return self._outputs

    @property
    def parts(self) -> tuple[str, ...]:
        return present_parts(self.model)

    # --- stepping --------------------------------------------------------------------------

    def do_step(self, current_time: float, step_size: float) -> None:
        """Advance from current_time (the component's time) by step_size > 0."""
        if self._phase != "stepping":
            self._require("do_step", "stepping")
        t = self._t
        if not (step_size > 0 and math.isfinite(step_size)):
            raise CallSequenceError(f"do_step: step_size must be finite and > 0, got {step_size!r}")
        if not abs(current_time - t) <= 1e-9 * max(1.0, abs(t)):  # also catches NaN
            raise CallSequenceError(f"do_step: current_time {current_time!r} is not the "
                                    f"component's time {t!r}")
        status = self._advance(step_size)
        if status == STATE_NONFINITE:
            self._unstable(current_time, step_size, "the state became non-finite")
        if status == ENERGY_GAIN:
            self._unstable(current_time, step_size,
                           f"the energy grew by {self._excess:.3g} J more than the rack forces "
                           f"supplied (allowed {self._allowed:.3g} J)")
        if status:
            self._check_stiff(current_time, step_size, why(status))
            raise StepRejected(self._rejection(status, current_time, step_size), current_time,
                               status)
        self._energy, self._energy_next = self._energy_next, self._energy
        self._y, self._next = self._next, self._y
        self._t = current_time + step_size
        self._cache.clear()

    def _advance(self, h: float) -> int:
        """self._next = self._y advanced by h and checked (step.plant_step); its status."""
        o, model = self.options, self.model
        if self._energy is None:
            self._energy = energy_terms(model, self._y)
        if o.method in COMPILED:
            r = plant_step(model.native, self._native_options, self._y, self._next, self._rack,
                           h, self._energy, self._energy_next, self._step_guess)
            self._step_guess = r.step_guess
        else:
            status, calls = scipy_advance(model.native, self._y, self._next, self._rack, h, o)
            self.evaluations += calls
            if status:
                return status
            r = check_step(model.native, self._next, self._energy, self._energy_next,
                           self._rack, h)
        self.evaluations += r.evaluations
        self._excess, self._allowed = r.excess, r.allowed
        return r.status

    def _check_stiff(self, t: float, h: float, why: str) -> None:
        """A fixed-step method past its stability limit explains a failed step: say so."""
        if self.options.method == "rk4":
            self._unstable(t, h, why, always=False)

    def _unstable(self, t: float, h: float, why: str, always: bool = True) -> None:
        """Raise IntegrationError naming time, method, step and advice (when `always` is
        False, only if the internal step exceeds the stable RK4 step at the state)."""
        step = internal_step(self.options, h)
        stable, text = advice(self.model, self._y, self._rack)
        if always or step > stable:  # stable is inf where the Jacobian cannot be evaluated
            raise IntegrationError(
                f"integration unstable in the step from t = {t!r} s by {h!r} s "
                f"({self.options.method}, internal step {step:.3g} s): {why}; {text}",
                t, self.options.method, step, stable)

    def _rejection(self, status: int, t: float, h: float) -> str:
        q, qd = self._y[:6], self._y[6:12]
        lengths = inverse_kinematics(self.model, q, with_cond=False).lengths
        return (f"step from t = {t!r} s by {h!r} s rejected ({self.options.method}): "
                f"{why(status)}; state at the start of the step: "
                f"q = {q.tolist()}, qd = {qd.tolist()}, leg lengths = {lengths.tolist()} m "
                f"(stroke [{self.model.leg_min}, {self.model.leg_max}]), rack force = "
                f"{self._rack.tolist()} N")

    # --- state -----------------------------------------------------------------------------

    def get_state(self) -> PlantState:
        return PlantState(self._phase, self._t, self._y.copy(), self._force.copy(),
                          self._torque.copy(), self._step_guess, self._start,
                          self._initial.copy())

    def set_state(self, state: PlantState) -> None:
        if not isinstance(state, PlantState):
            raise CallSequenceError(f"set_state: expected a PlantState, got {type(state).__name__}")
        self._phase, self._t, self._start = state.phase, state.time, state.start_time
        self._y, self._force, self._torque = state.y.copy(), state.force.copy(), state.torque.copy()
        self._step_guess, self._initial = state.step_guess, state.initial.copy()
        self._energy = None
        self._inputs_changed()

    @staticmethod
    def serialize_state(state: PlantState) -> bytes:
        """Plain data, never code: magic, version, phase, state size, the floats of the state
        (little-endian float64), then a CRC-32 of all that."""
        head = struct.pack(_HEADER, _MAGIC, STATE_VERSION, PHASES.index(state.phase), state.y.size)
        body = np.concatenate([[state.time, state.start_time, state.step_guess], state.y,
                               state.force, state.torque, state.initial]).astype("<f8").tobytes()
        return head + body + struct.pack("<I", zlib.crc32(head + body))

    @staticmethod
    def deserialize_state(data: bytes) -> PlantState:
        """The state serialize_state wrote; CallSequenceError for any other bytes."""
        if not isinstance(data, (bytes, bytearray)) or len(data) < _HEAD_SIZE + 4:
            raise CallSequenceError("deserialize_state: not a serialized plant state (too short)")
        data = bytes(data)
        if struct.unpack("<I", data[-4:])[0] != zlib.crc32(data[:-4]):
            raise CallSequenceError("deserialize_state: checksum mismatch (corrupted or foreign state)")
        magic, version, phase, n = struct.unpack(_HEADER, data[:_HEAD_SIZE])
        if magic != _MAGIC or version != STATE_VERSION:
            raise CallSequenceError(f"deserialize_state: not a plant state of version {STATE_VERSION}")
        values = np.frombuffer(data[_HEAD_SIZE:-4], dtype="<f8").astype(float)
        if n not in (12, 24) or phase >= len(PHASES) or values.size != 3 + n + 24:
            raise CallSequenceError("deserialize_state: inconsistent sizes in the state")
        y, rest = values[3:3 + n], values[3 + n:]
        return PlantState(PHASES[phase], float(values[0]), y.copy(), rest[:6].copy(),
                          rest[6:12].copy(), float(values[2]), float(values[1]), rest[12:24].copy())

    def _require(self, call: str, *phases: str) -> None:
        if self._phase not in phases:
            raise CallSequenceError(f"{call} is not allowed in phase '{self._phase}' "
                                    f"(allowed in: {', '.join(phases)})")


def _finite_scalar(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CallSequenceError(f"{name} must be a finite number, got {value!r}")


def _finite_vector(name: str, value) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise TrajectoryError(f"{name} must be six numbers, got {value!r}") from None
    if arr.shape != (6,):
        raise TrajectoryError(f"{name} must be six numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise TrajectoryError(f"{name} must be finite, got {arr.tolist()}")
    return arr
