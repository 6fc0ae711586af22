"""pythonfmu slave of the Stewart platform plant: a thin adapter over stewart_fmu.stepper.Plant.

pythonfmu copies this file into the FMU and finds the class by the literal line
`class StewartPlant(Fmi2Slave):`. Every name it registers comes from stewart_fmu.fmu; every
check and all physics run in Plant. Errors: a CallSequenceError, a bad input or a bad parameter
raises (the FMU returns fmi2Error with the message logged); a StepRejected is logged and do_step
returns False (fmi2Discard), the state staying at the start of the step for a rollback.
"""
from __future__ import annotations

import pickle
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from stewart_fmu import fmu
from stewart_fmu.errors import StewartError
from stewart_fmu.integrators import INTEGRATORS, IntegratorOptions
from stewart_fmu.scene import apply_overrides, scene_from_dict
from stewart_fmu.stepper import Plant, StepRejected


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
        defaults = IntegratorOptions()
        self.solver = {"method": defaults.method, "rtol": defaults.rtol, "atol": defaults.atol,
                       "max_step": defaults.max_step}
        self.start_time = 0.0
        self.plant = Plant(self.model, defaults)
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
            return float(np.asarray(value, dtype=float)[var.index]) if var.index else float(value)
        return get

    def _scene_setter(self, var):
        def set_(value):
            self._require_setup(var.name)
            if not var.index:
                self.overrides[var.key] = float(value)
                return
            current = np.array(self.overrides.get(var.key, fmu._lookup(self.scene, var.key)), dtype=float)
            current[var.index] = value
            self.overrides[var.key] = current.tolist()
        return set_

    def _array_getter(self, var):
        return lambda: float(self.values[var.key][var.index])

    def _array_setter(self, var):
        def set_(value):
            self._require_setup(var.name)
            self.values[var.key][var.index] = value
        return set_

    def _input_setter(self, var):
        def set_(value):
            if not np.isfinite(value):
                self._fail(f"input {var.name} = {value!r} at t = {self.plant.time!r} s is not finite")
            self.values[var.key][var.index] = value
        return set_

    def _output_getter(self, var):
        """Read through self.plant at call time: initialization replaces the plant."""
        key, idx = var.key, var.index
        if key == "cond":
            return lambda: self.plant.outputs.cond
        if key.startswith("part:"):
            return lambda: float(self.plant.outputs.parts[key[5:]][idx])
        if key == "rack_force":
            return lambda: float(self.plant.rack_force[idx])
        attr = {"l": "lengths", "ldot": "rates"}.get(key, key)
        return lambda: float(getattr(self.plant.outputs, attr)[idx])

    def _set_solver(self, name: str, value) -> None:
        self._require_setup(f"solver.{name}")
        self.solver[name] = value

    def _require_setup(self, name: str) -> None:
        if self.plant.phase not in ("instantiated", "initialization"):
            self._fail(f"parameter {name} can only be set before the end of initialization")

    def _fail(self, message: str):
        self.log(message, Fmi2Status.error)
        raise StewartError(message)

    # --- life cycle ------------------------------------------------------------------------

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.start_time = float(start_time)
        self.plant.setup_experiment(self.start_time)

    def enter_initialization_mode(self):
        self.plant.enter_initialization_mode()

    def exit_initialization_mode(self):
        """Build the model with the parameters set, then start the plant at q0, qd0."""
        try:
            model = scene_from_dict(apply_overrides(self.scene, self.overrides))
            options = IntegratorOptions(**self.solver)
        except (StewartError, ValueError, TypeError) as exc:
            self._fail(f"exitInitializationMode: {exc}")
        plant = Plant(model, options)
        plant.setup_experiment(self.start_time)
        plant.enter_initialization_mode()
        plant.set_initial(self.values["q0"], self.values["qd0"])
        try:
            plant.exit_initialization_mode()
        except StewartError as exc:
            self._fail(f"exitInitializationMode: initial pose rejected: {exc}")
        self.model, self.plant = model, plant

    def do_step(self, current_time, step_size):
        self.plant.set_force(self.values["sigma"])
        if self.model.drive is not None:
            self.plant.set_torque(self.values["tau"])
        try:
            self.plant.do_step(current_time, step_size)
        except StepRejected as exc:
            self.log(str(exc), Fmi2Status.discard)
            return False
        except StewartError as exc:
            self._fail(f"doStep: {exc}")
        return True

    def terminate(self):
        self.plant.terminate()

    # --- state -----------------------------------------------------------------------------

    def _get_fmu_state(self):
        return {"plant": self.plant.get_state(), "values": {k: v.copy() for k, v in self.values.items()},
                "overrides": dict(self.overrides), "solver": dict(self.solver),
                "start_time": self.start_time}

    def _set_fmu_state(self, state):
        if state["overrides"] != self.overrides or state["solver"] != self.solver:
            self.overrides, self.solver = dict(state["overrides"]), dict(state["solver"])
            self.model = scene_from_dict(apply_overrides(self.scene, self.overrides))
            self.plant = Plant(self.model, IntegratorOptions(**self.solver))
        self.plant.set_state(state["plant"])
        self.values = {k: v.copy() for k, v in state["values"].items()}
        self.start_time = state["start_time"]

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes):
        return pickle.loads(data)

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
