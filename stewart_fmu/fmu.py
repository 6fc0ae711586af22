"""The FMU: the variables of the exported plant, their units, and the export with pythonfmu.

The slave class (`fmu_slave.py`) is a thin pythonfmu adapter over `stepper.Plant`; this module
holds what it needs (variable table, units, parameter names of a scene) and the export, so the
physics never lives in the adapter. At run time the FMU imports the installed `stewart_fmu`
package from the importing Python process (pythonfmu runs the slave in the importer's Python).
"""
from __future__ import annotations

import shutil
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from .io import POSE
from .scene import load_scene

SCENE_RESOURCE = "scene.toml"
# Base-unit exponents (kg, m, s, rad) of every unit the FMU uses.
UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "rad": {"rad": 1}, "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1},
    "kg": {"kg": 1}, "kg.m2": {"kg": 1, "m": 2}, "N": {"kg": 1, "m": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "N.s/m": {"kg": 1, "s": -1}, "s": {"s": 1},
    "m/s2": {"m": 1, "s": -2}, "N/m": {"kg": 1, "s": -2}, "1": {},
}
_POSE_UNITS = ("m", "m", "m", "rad", "rad", "rad")
_RATE_UNITS = ("m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s")
# Scene keys: (dotted key, shape, unit, description).
_SCENE_KEYS = {
    "gravity": ((3,), "m/s2", "gravity in N"),
    "geometry.base_joints": ((6, 3), "m", "base joint a_i in N"),
    "geometry.platform_joints": ((6, 3), "m", "platform joint p_i in C"),
    "geometry.home": ((6,), None, "home pose (x, y, z, thx, thy, thz)"),
    "geometry.leg_min": ((), "m", "shortest leg length (stroke)"),
    "geometry.leg_max": ((), "m", "longest leg length (stroke)"),
    "platform.mass": ((), "kg", "platform mass"),
    "platform.inertia": ((3,), "kg.m2", "platform principal moments about its centre of mass"),
    "legs.lower_mass": ((), "kg", "lower leg part (cylinder) mass"),
    "legs.lower_com": ((), "m", "lower part centre of mass from the base joint"),
    "legs.lower_inertia": ((2,), "kg.m2", "lower part [transverse, axial] moments"),
    "legs.upper_mass": ((), "kg", "upper leg part (piston) mass"),
    "legs.upper_com": ((), "m", "upper part centre of mass from the platform joint"),
    "legs.upper_inertia": ((2,), "kg.m2", "upper part [transverse, axial] moments"),
    "drive.gear_ratio": ((), "1", "gearbox reduction ratio zeta"),
    "drive.rotor_inertia": ((), "kg.m2", "motor rotor inertia"),
    "drive.pinion_radius": ((), "m", "rack-and-pinion radius"),
    "friction.viscous": ((), "N.s/m", "viscous friction of each prismatic joint"),
    "friction.coulomb": ((), "N", "Coulomb friction of each prismatic joint"),
    "transmission.stiffness": ((), "N/m", "transmission stiffness, motor to leg (leg axis)"),
    "transmission.damping": ((), "N.s/m", "transmission damping, motor to leg (leg axis)"),
}


@dataclass(frozen=True)
class Variable:
    """One FMU variable: name, unit, description, and where its value lives."""

    name: str
    unit: str | None
    description: str
    key: str = ""                 # scene key (parameters) or output/input group
    index: tuple[int, ...] = ()   # element of that key


def names(variables: list[Variable], key: str) -> list[str]:
    """The names of the variables of one group (e.g. "tau", "l", "q0"), in order."""
    return [v.name for v in variables if v.key == key]


def scene_parameters(data: Mapping[str, Any]) -> list[Variable]:
    """Every numeric scene value the scene declares, as a tunable-at-start parameter."""
    out = []
    for dotted, (shape, unit, what) in _SCENE_KEYS.items():
        value = _lookup(data, dotted)
        if value is None and dotted != "gravity":  # gravity has a default: always a parameter
            continue
        if not shape:
            out.append(Variable(dotted, unit, what, dotted))
            continue
        for idx in _indices(shape):
            name = f"{dotted}[{','.join(str(i + 1) for i in idx)}]"
            u = _POSE_UNITS[idx[0]] if dotted == "geometry.home" else unit
            element = ",".join(str(i + 1) for i in idx)
            out.append(Variable(name, u, f"{what}, element [{element}]", dotted, idx))
    return out


def outputs(parts: tuple[str, ...]) -> list[Variable]:
    """The FMU's outputs: leg lengths and rates, pose and rates, twist, cond, force breakdown."""
    v = [Variable(f"l[{i}]", "m", f"length of leg {i}", "l", (i - 1,)) for i in range(1, 7)]
    v += [Variable(f"ldot[{i}]", "m/s", f"rate of leg {i}", "ldot", (i - 1,)) for i in range(1, 7)]
    v += [Variable(c, u, f"platform pose {c}", "q", (k,)) for k, (c, u) in enumerate(zip(POSE, _POSE_UNITS))]
    v += [Variable(f"d{c}", u, f"rate of {c}", "qd", (k,)) for k, (c, u) in enumerate(zip(POSE, _RATE_UNITS))]
    v += [Variable(f"v[{k + 1}]", "m/s", "platform velocity in N", "twist", (k,)) for k in range(3)]
    v += [Variable(f"omega[{k + 1}]", "rad/s", "platform angular velocity in N", "twist", (3 + k,))
          for k in range(3)]
    v.append(Variable("cond", "1", "condition number of the leg Jacobian (scaled)", "cond"))
    v += [Variable(f"rack_force[{i}]", "N", f"total force at rack {i} (sigma + zeta/r tau)",
                   "rack_force", (i - 1,)) for i in range(1, 7)]
    for part in parts:
        v += [Variable(f"force.{part}[{i}]", "N", f"part of rack force {i} spent on {part}",
                       f"part:{part}", (i - 1,)) for i in range(1, 7)]
    return v


def inputs(has_drive: bool) -> list[Variable]:
    """Rack forces sigma[i] (N); motor torques tau[i] (N m) when the scene has a [drive]."""
    v = [Variable(f"sigma[{i}]", "N", f"actuator force of leg {i} at the rack", "sigma", (i - 1,))
         for i in range(1, 7)]
    if has_drive:
        v += [Variable(f"tau[{i}]", "N.m", f"motor torque of leg {i}", "tau", (i - 1,))
              for i in range(1, 7)]
    return v


def initial_values() -> list[Variable]:
    """Initial pose q0 and rates qd0 (parameters; default home and rest)."""
    v = [Variable(f"q0[{k + 1}]", u, f"initial {c}", "q0", (k,)) for k, (c, u) in enumerate(zip(POSE, _POSE_UNITS))]
    v += [Variable(f"qd0[{k + 1}]", u, f"initial rate of {c}", "qd0", (k,))
          for k, (c, u) in enumerate(zip(POSE, _RATE_UNITS))]
    return v


def load_resources(resources: str | Path) -> dict[str, Any]:
    """The scene the FMU was exported with, read from its resources folder."""
    with (Path(resources) / SCENE_RESOURCE).open("rb") as fh:
        return tomllib.load(fh)


def export_fmu(scene: str | Path, out: str | Path) -> Path:
    """Build an FMI 2.0 co-simulation FMU of the scene with pythonfmu; returns its path."""
    from pythonfmu import FmuBuilder  # the export tool only; not needed to simulate



    load_scene(scene)  # a bad scene fails here with its SceneError, before any file is written
    out = Path(out)
    with tempfile.TemporaryDirectory(prefix="stewart_fmu_") as tmp:
        # Build from copies in a folder of their own: pythonfmu puts the script's folder on
        # sys.path, and this package's folder there would shadow modules by name.
        src = Path(tmp) / "src"
        src.mkdir()
        slave = Path(shutil.copy(Path(__file__).with_name("fmu_slave.py"), src))
        staged = Path(shutil.copyfile(scene, src / SCENE_RESOURCE))
        built = FmuBuilder.build_FMU(slave, dest=Path(tmp), project_files=[staged],
                                     needsExecutionTool="true",
                                     canHandleVariableCommunicationStepSize="true",
                                     canGetAndSetFMUstate="true", canSerializeFMUstate="true",
                                     canInterpolateInputs="false",
                                     canBeInstantiatedOnlyOncePerProcess="false")
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(built), out)
    return out


def _lookup(data: Mapping[str, Any], dotted: str):
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
