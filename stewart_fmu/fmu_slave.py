"""pythonfmu slave of the Stewart platform plant: a thin adapter over stewart_fmu.plant.Plant.

pythonfmu copies this file into the FMU and finds the slave class by its literal header line.
Every name it registers comes from stewart_fmu.fmu; every check and all physics run in Plant.

pythonfmu 0.7 turns any Python exception into fmi2Fatal and then releases its references to the
slave without clearing them, so an instance that raised once is unsafe to call again. This
adapter therefore never raises: every problem is logged with its cause, time and values, and
makes the next doStep return fmi2Discard (state unchanged, so the master can roll back): a
non-finite input (ignored until a finite value is set), a call out of sequence, a step <= 0 or
at the wrong time, a rejected step (stroke, singularity), a parameter that fails validation at
exitInitializationMode (the instance then refuses every step).
"""
from __future__ import annotations

import math
import pickle
import traceback
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from stewart_fmu import fmu
from stewart_fmu.errors import IntegrationError
from stewart_fmu.integrators import INTEGRATORS, IntegratorOptions
from stewart_fmu.plant import Plant, StepRejected
from stewart_fmu.scene import DEFAULT_GRAVITY, apply_overrides, scene_from_dict
from stewart_fmu.stability import default_options


class StewartPlant(Fmi2Slave):
    author = "stewart-sim"
    description = "Stewart platform plant (Kane's method): rack forces in, leg and pose states out"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.scene = fmu.load_resources(self.resources)
        self.model = scene_from_dict(self.scene)
        self.overrides: dict = {}
        self.units: dict[str, str | None] = {}
        self.values = {"sigma": np.zeros(6), "tau": np.zeros(6),
                       "q0": self.model.home.copy(), "qd0": np.zeros(6)}
        defaults = default_options(self.model)  # as Plant(model) and the closed loop
        self.solver = {"method": defaults.method, "rtol": defaults.rtol, "atol": defaults.atol,
                       "max_step": defaults.max_step}
        self.start_time = 0.0
        self.tolerance: float | None = None
        self.plant = Plant(self.model, defaults)
        self.inputs_changed = False               # values["sigma"/"tau"] not yet in the plant
        self.bad_inputs: dict[str, float] = {}   # non-finite inputs set and not yet replaced
        self.init_error: str | None = None       # why exitInitializationMode failed
        self._register_all()

    # --- variables -------------------------------------------------------------------------

    def _add(self, var: fmu.Variable, causality, variability, getter, setter=None,
             initial=None) -> None:
        self.units[var.name] = var.unit
        self.register_variable(Real(var.name, causality=causality, variability=variability,
                                    description=var.description, initial=initial,
                                    getter=getter, setter=setter), nested=False)

    def _register_all(self) -> None:
        fixed, par = Fmi2Variability.fixed, Fmi2Causality.parameter
        for var in fmu.scene_parameters(self.scene):
            self._add(var, par, fixed, self._scene_getter(var), self._scene_setter(var))
        for var in fmu.initial_values():
            self._add(var, par, fixed, self._array_getter(var), self._array_setter(var))
        for name, what in (("rtol", "relative tolerance"), ("atol", "absolute tolerance"),
                           ("max_step", "largest internal step (s)")):
            self._add(fmu.Variable(f"solver.{name}", "s" if name == "max_step" else None,
                                   f"integrator {what}"), par, fixed,
                      lambda n=name: self.solver[n], lambda v, n=name: self._set_solver(n, v))
        self.register_variable(String(
            "solver.method", causality=par, variability=fixed,
            description=f"integrator: one of {', '.join(INTEGRATORS)}",
            getter=lambda: self.solver["method"],
            setter=lambda v: self._set_solver("method", v)), nested=False)
        for var in fmu.inputs(self.model.drive is not None):
            self._add(var, Fmi2Causality.input, Fmi2Variability.continuous,
                      self._array_getter(var), self._input_setter(var))
        for var in fmu.outputs(self.plant.parts):
            self._add(var, Fmi2Causality.output, Fmi2Variability.continuous,
                      self._output_getter(var), initial=Fmi2Initial.exact)

    def _scene_getter(self, var):
        def get():
            value = self.overrides.get(var.key, fmu._lookup(self.scene, var.key))
            if value is None:  # gravity left to its default
                value = DEFAULT_GRAVITY
            return float(np.asarray(value, dtype=float)[var.index]) if var.index else float(value)
        return get

    def _scene_setter(self, var):
        def set_(value):
            if self._too_late(var.name):
                return
            if not var.index:
                self.overrides[var.key] = float(value)
                return
            current = np.array(self.overrides.get(var.key, fmu._lookup(self.scene, var.key))
                               or DEFAULT_GRAVITY, dtype=float)
            current[var.index] = value
            self.overrides[var.key] = current.tolist()
        return set_

    def _array_getter(self, var):
        return lambda: float(self.values[var.key][var.index])

    def _array_setter(self, var):
        def set_(value):
            if not self._too_late(var.name):
                self.values[var.key][var.index] = value
        return set_

    def _input_setter(self, var):
        def set_(value):
            if math.isfinite(value):
                if self.bad_inputs:
                    self.bad_inputs.pop(var.name, None)
                self.values[var.key][var.index] = value
                self.inputs_changed = True
                return
            self.bad_inputs[var.name] = value
            self._error(f"input {var.name} = {value!r} at t = {self.plant.time!r} s is not "
                        f"finite: ignored, and every doStep is discarded until it is finite")
        return set_

    def _output_getter(self, var):
        """Read through self.plant at call time: initialization replaces the plant."""
        key, idx = var.key, var.index
        if key == "cond":
            return lambda: self.plant.outputs.cond
        if key.startswith("part:"):
            return lambda: float(self._synced().outputs.parts[key[5:]][idx])
        if key == "rack_force":
            return lambda: float(self._synced().rack_force[idx])
        attr = {"l": "lengths", "ldot": "rates"}.get(key, key)
        return lambda: float(getattr(self.plant.outputs, attr)[idx])

    def _set_solver(self, name: str, value) -> None:
        if not self._too_late(f"solver.{name}"):
            self.solver[name] = value

    def _too_late(self, name: str) -> bool:
        """Parameters are fixed once initialization ends: a later set is logged and ignored."""
        if self.plant.phase in ("instantiated", "initialization"):
            return False
        self._error(f"parameter {name} can only be set before exitInitializationMode: ignored")
        return True

    def _error(self, message: str) -> None:
        self.log(message, Fmi2Status.error)

    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category=None, debug=None) -> None:
        """FMI 2.0 (2.1.5): the importer's logger takes the message as a printf format (fmpy
        passes it to vsnprintf), so a literal '%' is written '%%'; pythonfmu does not escape it,
        and a '%s' in a value we quote (e.g. a solver name) would crash the importer."""
        super().log(msg.replace("%", "%%"), status, category)

    # --- never raise into pythonfmu (see the module doc) ------------------------------------

    def set_real(self, vrs, values):
        self._guarded("setReal", super().set_real, vrs, values)

    def set_integer(self, vrs, values):
        self._guarded("setInteger", super().set_integer, vrs, values)

    def set_boolean(self, vrs, values):
        self._guarded("setBoolean", super().set_boolean, vrs, values)

    def set_string(self, vrs, values):
        self._guarded("setString", super().set_string, vrs, values)

    def get_real(self, vrs):
        return self._guarded("getReal", super().get_real, vrs) or [math.nan] * len(vrs)

    def get_integer(self, vrs):
        return self._guarded("getInteger", super().get_integer, vrs) or [0] * len(vrs)

    def get_boolean(self, vrs):
        return self._guarded("getBoolean", super().get_boolean, vrs) or [False] * len(vrs)

    def get_string(self, vrs):
        return self._guarded("getString", super().get_string, vrs) or [""] * len(vrs)

    def _guarded(self, call: str, fn, *args):
        try:
            return fn(*args)
        except Exception as exc:  # an exception would make pythonfmu drop this instance
            self._error(f"{call}: {type(exc).__name__}: {exc}")
            return None

    # --- life cycle ------------------------------------------------------------------------

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._guarded("setupExperiment", self._setup, start_time, tolerance)

    def _setup(self, start_time, tolerance=None) -> None:
        self.start_time = float(start_time)
        # pythonfmu passes 0 when the master defines no tolerance: only a positive one counts.
        self.tolerance = float(tolerance) if tolerance and math.isfinite(tolerance) and tolerance > 0 else None
        self.plant.setup_experiment(self.start_time, self.tolerance)

    def enter_initialization_mode(self):
        self._guarded("enterInitializationMode", self.plant.enter_initialization_mode)

    def exit_initialization_mode(self):
        """Build the model with the parameters set, then start the plant at q0, qd0."""
        try:
            model = scene_from_dict(apply_overrides(self.scene, self.overrides))
            plant = Plant(model, IntegratorOptions(**self.solver))
            plant.setup_experiment(self.start_time, self.tolerance)
            plant.enter_initialization_mode()
            plant.set_initial(self.values["q0"], self.values["qd0"])
            plant.hold_inputs(self.values["sigma"], self.values["tau"])  # a spring's preload
            plant.exit_initialization_mode()
        except Exception as exc:  # a bad parameter or initial pose: refuse to step, say why
            self.init_error = f"exitInitializationMode failed: {type(exc).__name__}: {exc}"
            self._error(self.init_error)
            return
        self.model, self.plant, self.init_error = model, plant, None
        self.inputs_changed = True

    def do_step(self, current_time, step_size):
        """fmi2OK, or fmi2Discard (False) with the reason logged; never raises."""
        refusal = self._refusal()
        if refusal:
            self.log(f"doStep at t = {current_time!r} s refused: {refusal}", Fmi2Status.discard)
            return False
        try:
            self._synced().do_step(current_time, step_size)
        except (StepRejected, IntegrationError) as exc:
            self.log(str(exc), Fmi2Status.discard)
            return False
        except Exception as exc:  # call out of sequence, bad step: logged as an error, discarded
            self._error(f"doStep(t = {current_time!r}, h = {step_size!r}): {type(exc).__name__}: {exc}")
            return False
        return True

    def _synced(self) -> Plant:
        """The plant, holding the inputs last set (each value was checked in its setter)."""
        if self.inputs_changed:
            self.plant.hold_inputs(self.values["sigma"], self.values["tau"])
            self.inputs_changed = False
        return self.plant

    def _refusal(self) -> str | None:
        if self.init_error:
            return self.init_error
        if self.bad_inputs:
            return f"non-finite inputs {self.bad_inputs}"
        return None

    def terminate(self):
        self._guarded("terminate", self.plant.terminate)

    # --- state -----------------------------------------------------------------------------

    def _get_fmu_state(self):
        return self._guarded("getFMUstate", self._snapshot)

    def _snapshot(self) -> dict:
        return {"plant": self._synced().get_state(), "values": {k: v.copy() for k, v in self.values.items()},
                "overrides": dict(self.overrides), "solver": dict(self.solver),
                "start_time": self.start_time, "bad_inputs": dict(self.bad_inputs),
                "init_error": self.init_error}

    def _set_fmu_state(self, state):
        self._guarded("setFMUstate", self._restore, state)

    def _restore(self, state) -> None:
        if state is None:
            raise ValueError("the serialized state could not be read (see the log)")
        if state["overrides"] != self.overrides or state["solver"] != self.solver:
            self.overrides, self.solver = dict(state["overrides"]), dict(state["solver"])
            self.model = scene_from_dict(apply_overrides(self.scene, self.overrides))
            self.plant = Plant(self.model, IntegratorOptions(**self.solver))
        self.plant.set_state(state["plant"])
        self.values = {k: v.copy() for k, v in state["values"].items()}
        self.start_time, self.init_error = state["start_time"], state["init_error"]
        self.bad_inputs = dict(state["bad_inputs"])
        self.inputs_changed = False

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes):
        try:
            return pickle.loads(data)
        except Exception:  # reported by _set_fmu_state (a static method cannot log)
            traceback.print_exc()
            return None

    # --- model description -----------------------------------------------------------------

    def to_xml(self, model_options=dict()) -> Element:
        """pythonfmu's description plus units (UnitDefinitions and unit attributes)."""
        root = super().to_xml(model_options)
        units = SubElement(Element("x"), "UnitDefinitions")
        for name in sorted({u for u in self.units.values() if u}):
            unit = SubElement(units, "Unit", {"name": name})
            SubElement(unit, "BaseUnit", {k: str(v) for k, v in fmu.UNITS[name].items()})
        root.insert(list(root).index(root.find("CoSimulation")) + 1, units)
        for sv in root.find("ModelVariables"):
            unit = self.units.get(sv.get("name"))
            if unit and sv.find("Real") is not None:
                sv.find("Real").set("unit", unit)
        return root
