"""The one table of the native FMU's variables: names, value references, units, descriptions.

Names and meanings are those of the first (pythonfmu) FMU: every numeric value of
the scene's plant tables as a fixed parameter, q0/qd0, solver settings, inputs sigma[1..6] (and
tau[1..6] with a [drive]), outputs l, ldot, pose, rates, twist, cond, rack_force, force.<part>.
Value references are fixed (stewart_fmu/native/fmi/model.h defines the same numbers); a scene
declares the subset its tables give. This module also writes the scene's C file (start values,
declared value references, instantiation token) that the export compiles with the plant.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..dynamics import PARTS, inverse_dynamics, present_parts
from ..io import POSE
from ..scene import DEFAULT_GRAVITY, scene_from_dict
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

# Scene keys: dotted key -> (first value reference, shape, unit, description). model.h VR_*.
SCENE_KEYS: dict[str, tuple[int, tuple[int, ...], str | None, str]] = {
    "gravity": (1, (3,), "m/s2", "gravity in N"),
    "geometry.base_joints": (4, (6, 3), "m", "base joint a_i in N"),
    "geometry.platform_joints": (22, (6, 3), "m", "platform joint p_i in C"),
    "geometry.home": (40, (6,), None, "home pose (x, y, z, thx, thy, thz)"),
    "geometry.leg_min": (46, (), "m", "shortest leg length (stroke)"),
    "geometry.leg_max": (47, (), "m", "longest leg length (stroke)"),
    "platform.mass": (48, (), "kg", "platform mass"),
    "platform.inertia": (49, (3,), "kg.m2", "platform principal moments about its centre of mass"),
    "legs.lower_mass": (52, (), "kg", "lower leg part (cylinder) mass"),
    "legs.lower_com": (53, (), "m", "lower part centre of mass from the base joint"),
    "legs.lower_inertia": (54, (2,), "kg.m2", "lower part [transverse, axial] moments"),
    "legs.upper_mass": (56, (), "kg", "upper leg part (piston) mass"),
    "legs.upper_com": (57, (), "m", "upper part centre of mass from the platform joint"),
    "legs.upper_inertia": (58, (2,), "kg.m2", "upper part [transverse, axial] moments"),
    "drive.gear_ratio": (60, (), "1", "gearbox reduction ratio zeta"),
    "drive.rotor_inertia": (61, (), "kg.m2", "motor rotor inertia"),
    "drive.pinion_radius": (62, (), "m", "rack-and-pinion radius"),
    "friction.viscous": (63, (), "N.s/m", "viscous friction of each prismatic joint"),
    "friction.coulomb": (64, (), "N", "Coulomb friction of each prismatic joint"),
    "transmission.stiffness": (65, (), "N/m", "transmission stiffness, motor to leg (leg axis)"),
    "transmission.damping": (66, (), "N.s/m", "transmission damping, motor to leg (leg axis)"),
}
VR_TIME, VR_Q0, VR_QD0, VR_RTOL, VR_ATOL, VR_MAX_STEP, VR_N_PAR, VR_METHOD = 0, 67, 73, 79, 80, 81, 82, 82
VR_SIGMA, VR_TAU = 100, 106
VR_L, VR_LDOT, VR_Q, VR_QD, VR_V, VR_OMEGA, VR_COND, VR_RACK, VR_PARTS = (
    200, 206, 212, 218, 224, 227, 230, 231, 237)
METHODS = ("rk4", "euler", "dopri5")
LOG_CATEGORIES = {"logEvents": "initialization and step events",
                  "logStatusWarning": "warnings", "logStatusDiscard": "discarded steps, with the reason",
                  "logStatusError": "errors: calls out of order, bad arguments, invalid parameters",
                  "logStatusFatal": "fatal errors"}


@dataclass(frozen=True)
class Variable:
    """One scalar FMU variable (FMI 2.0 ScalarVariable, FMI 3.0 Float64 or String)."""

    name: str
    vr: int
    causality: str            # parameter, input, output, independent
    unit: str | None
    description: str
    start: float | str | None = None
    type: str = "Real"        # Real or String

    @property
    def variability(self) -> str:
        return "fixed" if self.causality == "parameter" else "continuous"

    @property
    def initial(self) -> str | None:
        return {"parameter": "exact", "output": "calculated"}.get(self.causality)


def lookup(data: Mapping[str, Any], dotted: str):
    node: Any = data
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def _indices(shape: tuple[int, ...]) -> list[tuple[int, ...]]:
    if len(shape) == 1:
        return [(i,) for i in range(shape[0])]
    return [(i, j) for i in range(shape[0]) for j in range(shape[1])]


def scene_parameters(data: Mapping[str, Any]) -> list[Variable]:
    """Every numeric value of the scene's plant tables, as a fixed parameter (gravity always)."""
    out = []
    for dotted, (vr, shape, unit, what) in SCENE_KEYS.items():
        value = lookup(data, dotted)
        if value is None:
            if dotted != "gravity":
                continue
            value = list(DEFAULT_GRAVITY)
        if not shape:
            out.append(Variable(dotted, vr, "parameter", unit, what, float(value)))
            continue
        for k, idx in enumerate(_indices(shape)):
            element = ",".join(str(i + 1) for i in idx)
            u = POSE_UNITS[idx[0]] if dotted == "geometry.home" else unit
            v: Any = value
            for i in idx:
                v = v[i]
            out.append(Variable(f"{dotted}[{element}]", vr + k, "parameter", u,
                                f"{what}, element [{element}]", float(v)))
    return out


def solver_defaults(data: Mapping[str, Any]) -> dict[str, Any]:
    """The solver parameters' start values: stability.default_options of the scene's model,
    the integrator Plant(model) and the closed loop take (a stiff scene's step is smaller)."""
    o = default_options(scene_from_dict(data))
    return {"method": o.method, "rtol": o.rtol, "atol": o.atol, "max_step": o.max_step}


# DefaultExperiment: start 0, stop STOP_TIME, step STEP_SIZE; tolerance = the solver's rtol.
STOP_TIME, STEP_SIZE = 1.0, 1e-3


def hold_forces(data: Mapping[str, Any]) -> list[float]:
    """The start values of sigma[1..6]: the static rack forces that hold the platform at its home
    pose (inverse_dynamics at home, zero rates and accelerations), so that an importer that
    never sets the inputs sees the platform stay put. With a [drive] the tau inputs start at 0
    (at rest the drive adds no force): sigma alone carries the hold."""
    model = scene_from_dict(data)
    zero = np.zeros(6)
    return [float(x) for x in inverse_dynamics(model, np.asarray(model.home, dtype=float), zero, zero)]


def variables(data: Mapping[str, Any], fmi_version: int = 2) -> list[Variable]:
    """The FMU's variables for a parsed scene, in model-description order."""
    solver = solver_defaults(data)
    home = [float(x) for x in lookup(data, "geometry.home")]
    v = [Variable("time", VR_TIME, "independent", "s", "simulation time")] if fmi_version == 3 else []
    v += scene_parameters(data)
    v += [Variable(f"q0[{k + 1}]", VR_Q0 + k, "parameter", u, f"initial {c}", home[k])
          for k, (c, u) in enumerate(zip(POSE, POSE_UNITS))]
    v += [Variable(f"qd0[{k + 1}]", VR_QD0 + k, "parameter", u, f"initial rate of {c}", 0.0)
          for k, (c, u) in enumerate(zip(POSE, RATE_UNITS))]
    v += [Variable("solver.rtol", VR_RTOL, "parameter", None, "integrator relative tolerance (dopri5)",
                   solver["rtol"]),
          Variable("solver.atol", VR_ATOL, "parameter", None, "integrator absolute tolerance (dopri5)",
                   solver["atol"]),
          Variable("solver.max_step", VR_MAX_STEP, "parameter", "s", "largest internal step (s)",
                   solver["max_step"]),
          Variable("solver.method", VR_METHOD, "parameter", None,
                   f"integrator: one of {', '.join(METHODS)}", solver["method"], "String")]
    hold = hold_forces(data)
    v += [Variable(f"sigma[{i}]", VR_SIGMA + i - 1, "input", "N",
                   f"actuator force of leg {i} at the rack (starts at the force holding home)", hold[i - 1])
          for i in range(1, 7)]
    if "drive" in data:
        v += [Variable(f"tau[{i}]", VR_TAU + i - 1, "input", "N.m", f"motor torque of leg {i}", 0.0)
              for i in range(1, 7)]
    return v + outputs(data)


def outputs(data: Mapping[str, Any]) -> list[Variable]:
    """Leg lengths and rates, pose and rates, twist, cond, rack forces and their breakdown."""
    o = lambda name, vr, unit, what: Variable(name, vr, "output", unit, what)  # noqa: E731
    v = [o(f"l[{i}]", VR_L + i - 1, "m", f"length of leg {i}") for i in range(1, 7)]
    v += [o(f"ldot[{i}]", VR_LDOT + i - 1, "m/s", f"rate of leg {i}") for i in range(1, 7)]
    v += [o(c, VR_Q + k, u, f"platform pose {c}") for k, (c, u) in enumerate(zip(POSE, POSE_UNITS))]
    v += [o(f"d{c}", VR_QD + k, u, f"rate of {c}") for k, (c, u) in enumerate(zip(POSE, RATE_UNITS))]
    v += [o(f"v[{k + 1}]", VR_V + k, "m/s", "platform velocity in N") for k in range(3)]
    v += [o(f"omega[{k + 1}]", VR_OMEGA + k, "rad/s", "platform angular velocity in N") for k in range(3)]
    v.append(o("cond", VR_COND, "1", "condition number of the leg Jacobian (scaled)"))
    v += [o(f"rack_force[{i}]", VR_RACK + i - 1, "N", f"total force at rack {i} (sigma + zeta/r tau)")
          for i in range(1, 7)]
    for part in present_parts(scene_from_dict(data)):
        base = VR_PARTS + 6 * PARTS.index(part)
        v += [o(f"force.{part}[{i}]", base + i - 1, "N", f"part of rack force {i} spent on {part}")
              for i in range(1, 7)]
    return v


def token(data: Mapping[str, Any], fmi_version: int) -> str:
    """Instantiation token (guid): a hash of the variable table and start values."""
    text = repr([(x.name, x.vr, x.unit, x.start) for x in variables(data, fmi_version)])
    h = hashlib.sha256(f"stewart-native-fmu/1/{fmi_version}/{text}".encode()).hexdigest()
    return "{" + f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}" + "}"


def _c_double(x: float) -> str:
    if math.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return x.hex() if x != 0 else "0.0"


def scene_c_source(data: Mapping[str, Any], fmi_version: int) -> str:
    """The scene's C file: start values and declared parameters by value reference, the token."""
    start = [0.0] * VR_N_PAR
    declared = [0] * VR_N_PAR
    for var in variables(data, fmi_version):
        if var.type == "Real" and var.causality in ("parameter", "independent") and var.vr < VR_N_PAR:
            start[var.vr] = 0.0 if var.start is None else float(var.start)
            declared[var.vr] = 1
    rows = ",\n    ".join(f"{_c_double(x)} /* {k} */" for k, x in enumerate(start))
    sigma = ", ".join(_c_double(x) for x in hold_forces(data))
    flags = ", ".join(str(f) for f in declared)
    return (f"/* Generated by stewart_fmu.fmu.export for scene {data.get('name', '?')!r} "
            f"(FMI {fmi_version}.0): do not edit. */\n"
            "#include <math.h>\n\n#include \"model.h\"\n\n"
            f"const char STEWART_MODEL_TOKEN[] = \"{token(data, fmi_version)}\";\n"
            f"const int STEWART_START_METHOD = {METHODS.index(solver_defaults(data)['method'])};\n"
            f"const unsigned char STEWART_DECLARED[VR_N_PAR] = {{{flags}}};\n"
            f"const double STEWART_START[VR_N_PAR] = {{\n    {rows}\n}};\n"
            f"const double STEWART_START_SIGMA[6] = {{{sigma}}};\n")
