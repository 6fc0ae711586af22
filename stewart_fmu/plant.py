"""The plant as an FMI 2.0 co-simulation component, in-process.

`Plant` is the Python face of the C component the exported FMU wraps (native/src/component.c):
its life cycle (instantiate, setup experiment, initialization mode, set inputs, do_step, get
outputs, get/set/serialize state, reset, terminate) follows the component's one table of
call-sequence rules; its state (phase, time, y, held inputs, adaptive step guess, initial
values) lives in the component's plain-data struct; a state is serialized in the component's
format, and a refused step is described by the component's message. Each step is the C core's
stewart_step, the same step the exported FMU's binary takes.

State is (t, y) plus the held inputs and the adaptive step guess: everything a master needs
to roll back exactly (`get_state` / `set_state`, `serialize_state` / `deserialize_state`);
y = (q, qd), and with a compliant transmission (q, qd, s, sd) (see transmission.py).

Every step is checked for numerical instability (the core's power balance): a non-finite
state, or energy growing beyond the work of the held rack forces, raises IntegrationError with
the time, the integrator, its step and advice (stability.advice), and leaves the state at the
start of the step. Python keeps what C cannot do: scipy's methods (integrators.scipy_advance,
whose result the component checks and takes as its own step), the stiffness advice, the
typed errors, and the outputs derived on demand.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from stewart_fmu.dynamics import PARTS, forward_dynamics, leg_state, present_parts
from stewart_fmu.errors import (IntegrationError, SingularityError, StewartError, StrokeLimitError,
                                 TrajectoryError)
from stewart_fmu.integrators import COMPILED, IntegratorOptions, derivative, scipy_advance
from stewart_fmu.kinematics import condition_number
from stewart_fmu.model import Model
from stewart_fmu import table
from stewart_fmu.native import core
from stewart_fmu.native.core import ffi, lib
from stewart_fmu.stability import ENERGY_TOL, advice, default_options, internal_step
from stewart_fmu.status import (
    BAD_CALL,
    OK,
    BAD_STEP,
    BAD_TIME,
    ENERGY_GAIN,
    STATE_NONFINITE,
    STEP_TOO_SMALL,
    TOO_MANY_STEPS,
    why,
)
from stewart_fmu.transmission import spring_forces

STATE_VERSION = lib.STEWART_STATE_VERSION   # 3: the component's format (2 was Plant's own)
PHASES = tuple(ffi.string(lib.stewart_phase_name(p)).decode() for p in range(lib.STEWART_N_PHASES))
_NAME = b"stewart_fmu.plant.Plant"
_KEY = lib.stewart_hash(_NAME, len(_NAME))   # the key of Plant's serialized states
_MESSAGE = 1024                              # bytes of a refusal message
_buf = ffi.from_buffer


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
    """Everything needed to restore a Plant exactly (immutable; arrays are copies): the fields
    of the component's state (stewart_component) as Python values."""

    phase: str
    time: float
    y: np.ndarray            # (12,) q then qd; (24,) then s, sd with a transmission
    force: np.ndarray        # (6,) rack forces sigma_i (N), held over a step
    torque: np.ndarray       # (6,) motor torques (N m), held over a step
    step_guess: float        # next internal step of the adaptive method (s)
    start_time: float
    initial: np.ndarray      # (12,) the initial q, qd of this experiment


def _view(field) -> np.ndarray:
    """A numpy view of a double array inside the component's struct (no copy)."""
    return np.frombuffer(ffi.buffer(field), dtype=np.float64)


def _to_component(state: PlantState, call: str):
    """A stewart_component holding `state` (rack = force: set_state recomputes it)."""
    c = ffi.new("stewart_component *")
    try:
        phase = PHASES.index(state.phase)
        y = np.asarray(state.y, dtype=np.float64)
        if y.ndim != 1 or y.size > lib.STEWART_MAX_STATE:
            raise ValueError
        c.phase, c.n, c.time, c.start_time = phase, y.size, state.time, state.start_time
        c.step_guess = state.step_guess
        _view(c.y)[:y.size] = y
        for name, value in (("sigma", state.force), ("tau", state.torque), ("rack", state.force),
                            ("initial", state.initial)):
            _view(getattr(c, name))[:] = value
    except (ValueError, TypeError):
        raise CallSequenceError(f"{call}: not a state of a Plant (phase or sizes)") from None
    return c


def _from_component(c) -> PlantState:
    return PlantState(PHASES[c.phase], c.time, _view(c.y)[:c.n].copy(), _view(c.sigma).copy(),
                      _view(c.tau).copy(), c.step_guess, c.start_time, _view(c.initial).copy())


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
        self.qdd    # the forward kernel's typed errors first (and qdd is cached for later)
        parts, status = core.plant_parts(p._params, p._y, p._rack)
        if status != OK:
            raise StewartError(f"the rack force's parts at t = {p.time!r} s: {why(status)}")
        return {k: parts[PARTS.index(k)] for k in present_parts(p.model)}


class Plant:
    """The Stewart platform plant as an FMI co-simulation component (see the module doc)."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None):
        self.model = model
        self.options = options or default_options(model)
        self._drive_gain = model.drive.force_per_torque if model.drive is not None else 0.0
        self._params = model.native
        self._p = self._params.ptr
        self._s = s = ffi.new("stewart_component *")
        self._initial, self._force, self._torque, self._rack, self._yall = (
            _view(f) for f in (s.initial, s.sigma, s.tau, s.rack, s.y))
        self._message = ffi.new("char[]", _MESSAGE)
        self._do_step = lib.stewart_component_do_step
        self._cache: dict = {}
        self._outputs = Outputs(self)
        self._reset(np.r_[model.home, np.zeros(6)])

    @property
    def options(self) -> IntegratorOptions:
        return self._options

    @options.setter
    def options(self, value: IntegratorOptions) -> None:
        self._options = value
        self._native_options = value.native() if value.method in COMPILED else None

    # --- life cycle: the component's (stewart_component_*), its rules and its refusals --------

    def _reset(self, initial: np.ndarray) -> None:
        lib.stewart_component_reset(self._s, self._p, _buf(initial), _buf(np.zeros(6)),
                                    self.options.max_step)
        self._changed()

    def _changed(self) -> None:
        """After the state's size or values changed in C: the views and the cache follow."""
        n = self._s.n
        self._y = self._yall[:n]
        self._next = np.empty(n)      # scipy's result, checked by the component
        self._cache.clear()

    def _refuse_call(self, name: str, call: int) -> None:
        lib.stewart_call_refusal(self._message, _MESSAGE, name.encode(), call, self._s.phase)
        raise CallSequenceError(ffi.string(self._message).decode())

    def _require(self, name: str, call: int) -> None:
        if not lib.stewart_allowed(call, self._s.phase):
            self._refuse_call(name, call)

    @property
    def phase(self) -> str:
        return PHASES[self._s.phase]

    @property
    def time(self) -> float:
        return self._s.time

    @property
    def evaluations(self) -> int:
        """Right-hand-side evaluations so far (kept by set_state, zeroed by reset)."""
        return self._s.evaluations

    def setup_experiment(self, start_time: float = 0.0, tolerance: float | None = None) -> None:
        """Start time and (optionally) the integrator's relative tolerance."""
        self._require("setup_experiment", lib.STEWART_CALL_SETUP)
        _finite_scalar("start_time", start_time)
        if tolerance is not None:
            if not (math.isfinite(tolerance) and tolerance > 0):
                raise CallSequenceError(f"setup_experiment: tolerance must be > 0, got {tolerance}")
            self.options = replace(self.options, rtol=tolerance)
        lib.stewart_component_setup(self._s, float(start_time))

    def enter_initialization_mode(self) -> None:
        if lib.stewart_component_enter_init(self._s):
            self._refuse_call("enter_initialization_mode", lib.STEWART_CALL_ENTER_INIT)

    def set_initial(self, q=None, qd=None) -> None:
        """Initial pose and pose rates (before or during initialization mode)."""
        self._require("set_initial", lib.STEWART_CALL_SET_PARAMETER)
        q, qd = (None if v is None else _finite_vector(name, v) for name, v in (("q", q), ("qd", qd)))
        lib.stewart_component_set_initial(self._s, self._p, ffi.NULL if q is None else _buf(q),
                                          ffi.NULL if qd is None else _buf(qd))
        self._changed()

    def exit_initialization_mode(self) -> None:
        """Check the initial pose (stroke, singularity) and start stepping; a pose that fails
        leaves the component failed (reset to start again), as the FMU."""
        self._require("exit_initialization_mode", lib.STEWART_CALL_EXIT_INIT)
        rule, reason = core.check_pose(self._params, self._initial[:6].copy(), table.vr("Q0"))
        if rule != core.RULE_OK:  # the FMU's check of q0 (native/src/rules.c)
            lib.stewart_component_fail(self._s)
            error = StrokeLimitError if rule == core.RULE_POSE_STROKE else SingularityError
            raise error(f"the initial pose {reason}")
        lib.stewart_component_exit_init(self._s, self._p)
        self._changed()

    def terminate(self) -> None:
        if lib.stewart_component_terminate(self._s):
            self._refuse_call("terminate", lib.STEWART_CALL_TERMINATE)

    def reset(self) -> None:
        """Back to the state right after instantiation (options and initial values kept)."""
        self._reset(self._initial.copy())

    # --- inputs and outputs ----------------------------------------------------------------

    def set_force(self, sigma) -> None:
        """Rack forces sigma_i (N) held from now on."""
        self._hold("set_force", _finite_vector("force", sigma), None)

    def set_torque(self, tau) -> None:
        """Motor torques (N m), added to the rack force as zeta / r * tau (needs a [drive])."""
        self._require("set_torque", lib.STEWART_CALL_SET_INPUT)
        if self.model.drive is None:
            raise CallSequenceError("set_torque: the scene has no [drive]: set rack forces instead")
        self._hold("set_torque", None, _finite_vector("torque", tau))

    def hold_inputs(self, force: np.ndarray, torque: np.ndarray) -> None:
        """Set both inputs (an adapter that already checked each value, e.g. the FMU slave);
        use set_force / set_torque otherwise."""
        self._hold("hold_inputs", np.ascontiguousarray(force, dtype=np.float64),
                   np.ascontiguousarray(torque, dtype=np.float64))

    def _hold(self, name: str, force, torque) -> None:
        status = lib.stewart_component_set_inputs(self._s, ffi.NULL if force is None else _buf(force),
                                                  ffi.NULL if torque is None else _buf(torque),
                                                  self._drive_gain)
        if status == BAD_CALL:
            self._refuse_call(name, lib.STEWART_CALL_SET_INPUT)
        if status:
            raise TrajectoryError(f"{name}: the inputs must be finite (kept the old ones)")
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
        if self._native_options is not None:
            status = self._do_step(self._s, self._p, self._native_options, current_time,
                                   step_size)
        else:
            status = self._scipy_step(current_time, step_size)
        if status:
            self._refused(status, current_time, step_size)
        if self._cache:
            self._cache.clear()

    def _scipy_step(self, t: float, h: float) -> int:
        """A scipy method's step: the component checks the call, Python integrates, the
        component checks the result (finite, power balance) and takes it."""
        s = self._s
        status = lib.stewart_component_begin_step(s, self._p, t, h)
        if status:
            return status
        status, calls = scipy_advance(self._params, self._y, self._next, self._rack, h,
                                      self.options)
        s.evaluations += calls
        if status:
            s.excess = s.allowed = 0.0
            return status
        return lib.stewart_component_end_step(s, self._p, _buf(self._next), t, h, ENERGY_TOL)

    def _refused(self, status: int, t: float, h: float) -> None:
        """Raise the typed error of a refused do_step (the state stays at the step's start)."""
        if status == BAD_CALL:
            self._refuse_call("do_step", lib.STEWART_CALL_DO_STEP)
        if status == BAD_STEP:
            raise CallSequenceError(f"do_step: step_size {why(status)}, got {h!r}")
        if status == BAD_TIME:
            raise CallSequenceError(f"do_step: current_time {t!r} {why(status)} {self.time!r}")
        if status in (STATE_NONFINITE, ENERGY_GAIN):
            self._unstable(t, h, status)
        if self.options.method == "rk4":  # past its stability limit explains a failed step
            self._unstable(t, h, status, always=False)
        raise StepRejected(self._refusal(status, t, h), t, status)

    def _refusal(self, status: int, t: float, h: float) -> str:
        """The component's message of a refused step (the FMU logs the same), with advice for
        the methods only Plant has."""
        lib.stewart_component_refusal(self._message, _MESSAGE, self._s, self._p,
                                      self.options.method.encode(), t, h, status)
        text = ffi.string(self._message).decode()
        if status in (TOO_MANY_STEPS, STEP_TOO_SMALL):
            text += "; a stiff plant: try 'Radau' or 'BDF'"
        return text

    def _unstable(self, t: float, h: float, status: int, always: bool = True) -> None:
        """Raise IntegrationError: the refusal, the internal step and advice (when `always` is
        False, only if the internal step exceeds the stable RK4 step at the state)."""
        step = internal_step(self.options, h)
        stable, text = advice(self.model, self._y, self._rack)
        if always or step > stable:  # stable is inf where the Jacobian cannot be evaluated
            raise IntegrationError(f"{self._refusal(status, t, h)}; internal step {step:.3g} s: "
                                   f"{text}", t, self.options.method, step, stable)

    # --- state: the component's plain data and its one serialized format --------------------

    def get_state(self) -> PlantState:
        return _from_component(self._s)

    def set_state(self, state: PlantState) -> None:
        """Restore a state after the component's sanity check (phase, sizes, finite values)."""
        if not isinstance(state, PlantState):
            raise CallSequenceError(f"set_state: expected a PlantState, got {type(state).__name__}")
        status = lib.stewart_component_load(self._s, _to_component(state, "set_state"), self._p)
        if status:
            raise CallSequenceError(f"set_state: not a state of this plant: {why(status)}")
        lib.stewart_component_hold(self._s, self._drive_gain)
        self._changed()

    @staticmethod
    def serialize_state(state: PlantState) -> bytes:
        """Plain data, never code: the component's format (stewart_serialize: magic, version,
        size, key, FNV-1a checksum, then the state's fields as they lie in memory)."""
        size = lib.stewart_serialized_size(0)
        out = ffi.new("char[]", size)
        lib.stewart_serialize(_to_component(state, "serialize_state"), ffi.NULL, 0, _KEY, out, size)
        return ffi.buffer(out)[:]

    @staticmethod
    def deserialize_state(data: bytes) -> PlantState:
        """The state serialize_state wrote; CallSequenceError for any other bytes."""
        if not isinstance(data, (bytes, bytearray)):
            raise CallSequenceError("deserialize_state: not a serialized plant state (not bytes)")
        c = ffi.new("stewart_component *")
        status = lib.stewart_deserialize(_buf(data), len(data), _KEY, c, ffi.NULL, 0)
        if status:
            raise CallSequenceError(f"deserialize_state: not a serialized plant state: {why(status)}")
        return _from_component(c)


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
