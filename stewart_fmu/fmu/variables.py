"""The native FMU's variables: the table of native/include/stewart_table.h, for one Model.

Names, value references, shapes, units and descriptions are the table's (read from the core by
stewart_fmu/table.py); this module gives them the scene's values: every numeric value of the
scene's plant tables as a fixed parameter, q0/qd0, solver settings, inputs sigma (and tau with
a [drive]), outputs l, ldot, pose, rates, twist, cond, rack_force, force.<part> (and, FMI 3.0
only, the pose and its rates as arrays q, qd). A scene declares the subset its tables give. A
group of several values is several scalars in FMI 2.0 (sigma[1] .. sigma[6]) and one array
variable in FMI 3.0 (sigma, six values at one value reference). This module also writes the scene's C file (start
values, declared value references, instantiation token) that the export compiles with the plant.
Everything is computed from the Model (the scene read and checked once).
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .. import table
from ..dynamics import inverse_dynamics, present_parts
from ..errors import SceneError
from ..model import Model
from ..native import core
from ..stability import default_options

# Base-unit exponents (kg, m, s, rad) of every unit the FMU uses.
UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "rad": {"rad": 1}, "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1},
    "kg": {"kg": 1}, "kg.m2": {"kg": 1, "m": 2}, "N": {"kg": 1, "m": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "N.s/m": {"kg": 1, "s": -1}, "s": {"s": 1},
    "m/s2": {"m": 1, "s": -2}, "N/m": {"kg": 1, "s": -2}, "1": {},
}
POSE_UNITS = ("m", "m", "m", "rad", "rad", "rad")
RATE_UNITS = ("m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s")



def _shape(g: table.VariableGroup) -> tuple[int, ...]:
    if g.shape > 0:
        return (g.count // g.shape, g.shape)
    return (g.count,) if g.count > 1 else ()


# Scene keys: dotted key -> (first value reference, shape, unit, description), from the table.
SCENE_KEYS: dict[str, tuple[int, tuple[int, ...], str | None, str]] = {
    key: (g.vr, _shape(g), g.unit if g.unit not in ("", "pose") else None, g.description)
    for key, g in table.scene_groups().items()}
VR_TIME, VR_N_PAR, VR_METHOD, VR_END = table.VR_TIME, table.VR_N_PAR, table.VR_METHOD, table.VR_END
VR_Q0, VR_QD0, VR_RTOL, VR_ATOL, VR_MAX_STEP = (table.vr(i) for i in ("Q0", "QD0", "RTOL", "ATOL", "MAX_STEP"))
VR_SIGMA, VR_TAU = table.vr("SIGMA"), table.vr("TAU")
VR_L, VR_LDOT, VR_Q, VR_QD, VR_V, VR_OMEGA, VR_COND, VR_RACK, VR_PARTS = (
    table.vr(i) for i in ("L", "LDOT", "Q_X", "QD_X", "V", "OMEGA", "COND", "RACK", "FORCE_PLATFORM"))
LOG_CATEGORIES = {"logEvents": "initialization and step events",
                  "logStatusWarning": "warnings", "logStatusDiscard": "discarded steps, with the reason",
                  "logStatusError": "errors: calls out of order, bad arguments, invalid parameters",
                  "logStatusFatal": "fatal errors"}


@dataclass(frozen=True)
class Variable:
    """One FMU variable (FMI 2.0 ScalarVariable, FMI 3.0 Float64 or String): a scalar, or with
    a shape an FMI 3.0 array whose values (and start) are in row-major order."""

    name: str
    vr: int
    causality: str            # parameter, input, output, independent
    unit: str | None
    description: str
    start: float | str | tuple[float, ...] | None = None
    type: str = "Real"        # Real or String
    shape: tuple[int, ...] = ()
    min: float | None = None  # the declared range (inputs: table.INPUT_RANGES; parameters: their
                              # group's physical bounds), each element's
    max: float | None = None

    @property
    def size(self) -> int:
        """How many values the variable's value reference holds (1 for a scalar)."""
        return int(np.prod(self.shape)) if self.shape else 1

    @property
    def variability(self) -> str:
        return "fixed" if self.causality == "parameter" else "continuous"

    @property
    def initial(self) -> str | None:
        return {"parameter": "exact", "output": "calculated"}.get(self.causality)


def lookup(data: Mapping[str, Any], dotted: str):
    """The value at a dotted key of a parsed scene, None where absent."""
    node: Any = data
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def scene_value(model: Model, key: str) -> Any:
    """The value the scene gave a key of its plant tables, as the Model holds it (None when the
    scene has no such key): [geometry] and gravity are Model attributes, [platform] its
    platform_* ones, the other tables their parameter objects."""
    tab, _, name = key.rpartition(".")
    if tab in ("", "geometry"):
        return getattr(model, name)
    if tab == "platform":
        return getattr(model, f"platform_{name}")
    params = getattr(model, tab)
    return None if params is None else getattr(params, name)


def _unit(g: table.VariableGroup, idx: tuple[int, ...]) -> str | None:
    if g.unit in ("pose", "rate"):
        return (POSE_UNITS if g.unit == "pose" else RATE_UNITS)[idx[0]]
    return g.unit or None


def _declared_bounds(g: table.VariableGroup) -> tuple[float | None, float | None]:
    """A parameter's physical bounds from the table, as min and max (FMI's are inclusive: an
    open bound's end, e.g. a mass of 0, is declared but refused by exitInitializationMode)."""
    if g.causality != "parameter" or g.bound == table.BOUND_ANY:
        return None, None
    return g.min, g.max


def _group(g: table.VariableGroup, value: Any, fmi_version: int) -> list[Variable]:
    """The variables of one group holding `value` (None: outputs, no start): FMI 2.0 scalars,
    or one FMI 3.0 array (no unit when its elements' units differ: q0, qd0, q, qd); a per-leg
    parameter given as one number is the one variable under the group's plain name."""
    arr = np.zeros(_shape(g)) if value is None else np.asarray(value, dtype=float)
    start = (lambda x: None) if value is None else float
    lo, hi = table.INPUT_RANGES.get(g.id, _declared_bounds(g))
    if arr.ndim == 0:
        return [Variable(g.name, g.vr, g.causality, _unit(g, (0,)), g.description, start(arr), min=lo, max=hi)]
    if fmi_version == 3:
        unit = None if g.unit in ("pose", "rate") else g.unit or None
        return [Variable(g.name, g.vr, g.causality, unit, g.description,
                         None if value is None else tuple(float(x) for x in arr.ravel()),
                         shape=arr.shape, min=lo, max=hi)]
    out = []
    for k, idx in enumerate(np.ndindex(arr.shape)):
        element = ",".join(str(i + 1) for i in idx)
        what = f"{g.description}, leg {element}" if g.shape == table.PER_LEG else \
            f"{g.description}, element [{element}]"
        out.append(Variable(f"{g.name}[{element}]", g.vr + k, g.causality, _unit(g, idx), what,
                            start(arr[idx]), min=lo, max=hi))
    return out


def scene_parameters(model: Model, fmi_version: int = 2) -> list[Variable]:
    """Every numeric value of the scene's plant tables, as a fixed parameter (gravity always)."""
    out = []
    for key, g in table.scene_groups().items():
        value = scene_value(model, key)
        if value is not None:
            out += _group(g, value, fmi_version)
    return out


def solver_defaults(model: Model) -> dict[str, Any]:
    """The solver parameters' start values: stability.default_options of the scene's model,
    the integrator Plant(model) and the closed loop take (a stiff scene's step is smaller)."""
    o = default_options(model)
    return {"method": o.method, "rtol": o.rtol, "atol": o.atol, "max_step": o.max_step}


# DefaultExperiment: start 0, stop STOP_TIME, step STEP_SIZE; tolerance = the solver's rtol.
STOP_TIME, STEP_SIZE = 1.0, 1e-3


def hold_forces(model: Model) -> list[float]:
    """The start values of sigma[1..6]: the static rack forces that hold the platform at its home
    pose (inverse_dynamics at home, zero rates and accelerations), so that an importer that
    never sets the inputs sees the platform stay put. With a [drive] the tau inputs start at 0
    (at rest the drive adds no force): sigma alone carries the hold."""
    zero = np.zeros(6)
    return [float(x) for x in inverse_dynamics(model, np.asarray(model.home, dtype=float), zero, zero)]


def variables(model: Model, fmi_version: int = 2, solver: Mapping[str, Any] | None = None,
              hold: list[float] | None = None) -> list[Variable]:
    """The FMU's variables for a scene's Model, in model-description order (solver and hold:
    solver_defaults and hold_forces when already computed)."""
    solver = solver_defaults(model) if solver is None else solver
    hold = hold_forces(model) if hold is None else hold
    lo, hi = table.INPUT_RANGES["SIGMA"]
    for i, x in enumerate(hold):   # sigma's start must lie in its declared range
        if not lo <= x <= hi:
            raise SceneError("platform.mass", f"the force holding the home pose on leg {i + 1}, {x:g} N, lies "
                             f"outside the FMU's input range [{lo:g}, {hi:g}] N of sigma", model.source)
    g = table.GROUPS
    v = [Variable("time", VR_TIME, "independent", "s", "simulation time")] if fmi_version == 3 else []
    v += scene_parameters(model, fmi_version)
    v += _group(g["Q0"], model.home, fmi_version) + _group(g["QD0"], np.zeros(6), fmi_version)
    for key in ("RTOL", "ATOL", "MAX_STEP"):
        v += _group(g[key], solver[key.lower()], fmi_version)
    m = g["METHOD"]
    v.append(Variable(m.name, m.vr, "parameter", None, f"{m.description}: one of {', '.join(core.METHODS)}",
                      solver["method"], "String"))
    v += _group(g["SIGMA"], hold, fmi_version)
    if model.drive is not None:
        v += _group(g["TAU"], np.zeros(6), fmi_version)
    return v + outputs(model, fmi_version)


def outputs(model: Model, fmi_version: int = 2) -> list[Variable]:
    """Leg lengths and rates, pose and rates, twist, cond, rack forces and their breakdown (the
    parts of the effects the model has); with FMI 3.0 also the pose and its rates as arrays."""
    parts = {f"force.{p}" for p in present_parts(model)}
    return [x for g in table.VARIABLES if g.causality == "output"
            and (not g.name.startswith("force.") or g.name in parts)
            and (fmi_version == 3 or not g.fmi3_only) for x in _group(g, None, fmi_version)]


def token(table_: list[Variable], fmi_version: int) -> str:
    """Instantiation token (guid): a hash of the variable table and start values."""
    text = repr([(x.name, x.vr, x.unit, x.start) + ((x.shape,) if x.shape else ()) for x in table_])
    h = hashlib.sha256(f"stewart-native-fmu/1/{fmi_version}/{text}".encode()).hexdigest()
    return "{" + f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}" + "}"


def _c_double(x: float) -> str:
    if math.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return x.hex() if x != 0 else "0.0"


def element_starts(table_: list[Variable]) -> dict[int, float]:
    """The start value of every Real value the variables hold, by value reference (an FMI 3.0
    array's element k at the array's value reference + k, as the binary stores it)."""
    out = {}
    for var in table_:
        if var.type == "Real" and var.start is not None:
            values = var.start if var.shape else (var.start,)
            out.update((var.vr + k, float(x)) for k, x in enumerate(values))
    return out


def scene_c_source(model: Model, table_: list[Variable], fmi_version: int) -> str:
    """The scene's C file: start values of the parameters and how many values each declared
    value reference holds, the token (table_: variables(model, fmi_version))."""
    starts = element_starts(table_)
    start = [starts.get(vr, 0.0) for vr in range(VR_N_PAR)]
    sizes = [0] * VR_END
    for var in table_:
        sizes[var.vr] = var.size
    by_name = {var.name: var for var in table_}
    rows = ",\n    ".join(f"{_c_double(x)} /* {k} */" for k, x in enumerate(start))
    sigma = ", ".join(_c_double(starts[VR_SIGMA + i]) for i in range(6))
    flags = ", ".join(str(f) for f in sizes)
    method = by_name[table.GROUPS["METHOD"].name].start
    return (f"/* Generated by stewart_fmu.fmu.export for scene {model.name!r} "
            f"(FMI {fmi_version}.0): do not edit. */\n"
            "#include <math.h>\n\n#include \"model.h\"\n\n"
            f"const char STEWART_MODEL_TOKEN[] = \"{token(table_, fmi_version)}\";\n"
            f"const int STEWART_START_METHOD = {core.METHODS[method]};\n"
            f"const unsigned char STEWART_VALUES[VR_END] = {{{flags}}};\n"
            f"const double STEWART_START[VR_N_PAR] = {{\n    {rows}\n}};\n"
            f"const double STEWART_START_SIGMA[6] = {{{sigma}}};\n")
