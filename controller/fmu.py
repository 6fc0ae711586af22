"""The scene's per-axis controllers as an FMI 2.0 / 3.0 co-simulation FMU (`export-fmu
--controller`).

The binary is the one C implementation the closed loop takes (native/axis.c: axis_step, i.e.
pid_voltages and advance_currents) under native/fmi/model.c, with the plant's FMI layers
(stewart_fmu/native/fmi/fmi2Functions.c, fmi3Functions.c) and the core's life-cycle rules
(component.c). Its variables are the rows of native/fmi/axis_table.h, read here for the model
description. The design (gains, constant load) is the closed loop's (cosim.run_closed_loop): the
start values are those of the scene; integral0 and current0 those of the drives holding home.

Feedforward: an input, v_ff (V), that the master computes (feedforward.feedforward_voltage):
the Kane feedforward needs the plant's model, which the controller does not hold, and one input
serves "none" (0), "constant_load" and "kane" alike. Outputs are the sample at the current
communication point (direct feedthrough from l, ldot and the references): a master reads tau
after setting the measured lengths and before stepping the plant, and doStep then advances the
controller over whole controller periods with the inputs held. With the parameter delay = 1
(its start value is the scene's [controller] delay) they are the last step's sample instead: one
period of actuation delay, under that master or an SSP importer's step-then-exchange.
"""
from __future__ import annotations

import hashlib
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, indent, tostring

import numpy as np

from stewart_fmu.fmu.export import (NATIVE, build_binaries, core_sources, find_compiler, pack,
                                    platform_folder)
from stewart_fmu.fmu.model_description import fmi_root
from stewart_fmu.model import Model

from .config import ControllerConfig, scene_axis
from .design import check_stable, tune_pid
from .feedforward import equilibrium, feedforward_voltage
from .trajectory import Trajectory, leg_references

MODEL_IDENTIFIER = "StewartController"
HERE = Path(__file__).resolve().parent / "native"
TABLE = HERE / "fmi" / "axis_table.h"
SECTIONS = {"PARAMETERS": "parameter", "INPUTS": "input", "OUTPUTS": "output"}
# sources/ of the FMU -> the file it is copied from: the controller's model over the plant's FMI
# layers (which include "model.h" from their own directory: the controller's here).
OWN_SOURCES = {"axis.c": HERE / "axis.c", "axis.h": HERE / "axis.h",
               "fmi/model.c": HERE / "fmi" / "model.c", "fmi/model.h": HERE / "fmi" / "model.h",
               "fmi/axis_table.h": HERE / "fmi" / "axis_table.h"}
FMI_LAYER = {2: ["fmi/fmi2Functions.c", "fmi/fmi2_api.h", "fmi/fmi_export.h", "fmi/glue.c",
                 "fmi/glue.h"],
             3: ["fmi/fmi3Functions.c", "fmi/fmi3_api.h", "fmi/fmi_export.h", "fmi/glue.c",
                 "fmi/glue.h"]}
START_FILE = "fmi/start.c"
GENERATION_TOOL = "stewart-sim controller FMU export"


@dataclass(frozen=True)
class Variable:
    name: str          # "kp", "l[3]"
    vr: int
    causality: str     # parameter, input, output
    unit: str
    description: str
    start: float | None
    min: float | None = None   # the declared range (inputs: input_ranges(); parameters:
    max: float | None = None   # parameter_ranges(), None where it has no upper bound)


def input_ranges() -> dict[str, tuple[float, float]]:
    """axis_table.h's AXIS_FMU_INPUT_RANGES: (min, max) per input group ID."""
    body = re.search(r"#define AXIS_FMU_INPUT_RANGES\(X\)(.*?)\n\n", TABLE.read_text() + "\n\n", re.S)
    rows = re.findall(r"X\((\w+), ([-+.\deE]+), ([-+.\deE]+)\)", body.group(1))
    if len(rows) != body.group(1).count("X("):   # a row this reading would miss
        raise RuntimeError(f"{TABLE}: a row of AXIS_FMU_INPUT_RANGES is not on one line")
    return {name: (float(lo), float(hi)) for name, lo, hi in rows}


# axis_table.h's AXIS_BOUND_*: MIN <= x <= MAX (closed), MIN < x <= MAX (open).
BOUND_CLOSED, BOUND_OPEN = "AXIS_BOUND_CLOSED", "AXIS_BOUND_OPEN"


@dataclass(frozen=True)
class Bound:
    """A parameter group's bounds (axis_table.h's AXIS_FMU_PARAMETER_RANGES): min < x (open) or
    min <= x (closed), x <= max (inf: no upper bound)."""

    open: bool
    min: float
    max: float

    def reason(self, x: float) -> str | None:
        """Why x breaks the bounds, in the FMU's words ("must be a finite number > 0, got -1.0"),
        None when it does not."""
        low = "" if np.isinf(self.min) else f" {'>' if self.open else '>='} {self.min:g}"
        if not np.isfinite(x) or not (x > self.min if self.open else x >= self.min):
            return f"must be a finite number{low}, got {x!r}"
        if not x <= self.max:
            return f"must be <= {self.max:g}, got {x!r}"
        return None


def parameter_ranges() -> dict[str, Bound]:
    """axis_table.h's AXIS_FMU_PARAMETER_RANGES: the bounds per parameter group ID (HUGE_VAL:
    no upper bound, inf here)."""
    body = re.search(r"#define AXIS_FMU_PARAMETER_RANGES\(X\)(.*?)\n\n", TABLE.read_text() + "\n\n", re.S)
    number = r"([-+.\deE]+|HUGE_VAL)"
    rows = re.findall(rf"X\((\w+), (AXIS_BOUND_OPEN|AXIS_BOUND_CLOSED), {number}, {number}\)", body.group(1))
    if len(rows) != body.group(1).count("X("):   # a row this reading would miss
        raise RuntimeError(f"{TABLE}: a row of AXIS_FMU_PARAMETER_RANGES is not on one line")
    value = {"HUGE_VAL": float("inf")}
    return {name: Bound(kind == BOUND_OPEN, float(value.get(lo, lo)), float(value.get(hi, hi)))
            for name, kind, lo, hi in rows}


def table_rows() -> dict[str, list[tuple[str, str, int, str, str]]]:
    """axis_table.h's rows per section: (ID, NAME, COUNT, UNIT, DESCRIPTION)."""
    text = TABLE.read_text()
    row = re.compile(r'X\((\w+), "([^"]+)", (\d+), "([^"]*)", "([^"]*)"\)')
    out = {}
    for section in SECTIONS:
        body = re.search(rf"#define AXIS_FMU_{section}\(X\)(.*?)\n\n", text, re.S)
        rows = [(a, b, int(c), d, e) for a, b, c, d, e in row.findall(body.group(1))]
        if len(rows) != body.group(1).count("X("):   # a row this reading would miss
            raise RuntimeError(f"{TABLE}: a row of AXIS_FMU_{section} is not on one line")
        out[section] = rows
    return out


def _bases() -> dict[str, int]:
    text = TABLE.read_text()
    return {s: int(re.search(rf"#define AXIS_VR_{s} (\d+)", text).group(1)) for s in SECTIONS}


def start_values(model: Model, config: ControllerConfig) -> dict[str, np.ndarray]:
    """The scene's values of the table's parameters and inputs by group NAME: the closed loop's
    design (tune_pid to the [controller] targets, checked stable at its rate), the drive, and
    the drives holding the platform at rest at home (feedforward.equilibrium with the
    feedforward the scene chose); inputs: the home's leg lengths, at rest."""
    axis = scene_axis(model, config)
    gains = tune_pid(axis, config.bandwidth, config.phase_margin)
    check_stable(axis, gains, config.dt, config.delay)
    zeros = np.zeros((2, 6))
    rest = Trajectory(np.array([0.0, config.dt]), np.tile(model.home, (2, 1)), zeros, zeros.copy())
    refs = leg_references(model, rest)
    _, i_ff = feedforward_voltage(model, config, axis, rest, refs)
    current0, integral0 = equilibrium(model, rest.q[0], rest.qd[0], refs.ldot[0], i_ff[0], gains, axis)
    m = config.motor
    return {"rate": config.rate, "kp": gains.kp, "ki": gains.ki, "kd": gains.kd,
            "voltage_limit": m.voltage_limit, "current_limit": m.current_limit,
            "resistance": m.resistance, "inductance": m.inductance,
            "torque_constant": m.torque_constant, "emf_constant": axis.emf_constant,
            "force_per_torque": model.drive.force_per_torque, "integral0": integral0,
            "current0": current0, "reference": 0.0, "delay": float(config.delay), "l_ref": refs.l[0], "ldot_ref": np.zeros(6), "v_ff": np.zeros(6),
            "l": refs.l[0], "ldot": np.zeros(6)}


def variables(values: dict[str, np.ndarray] | None = None) -> list[Variable]:
    """Every scalar of the table in value-reference order, with start values from `values`
    (start_values; outputs have none)."""
    out, bases, ranges, bounds = [], _bases(), input_ranges(), parameter_ranges()
    for section, rows in table_rows().items():
        vr = bases[section]
        for ident, name, count, unit, what in rows:
            start = None if values is None or section == "OUTPUTS" else np.ravel(values[name])
            lo, hi = ranges.get(ident, (None, None)) if section == "INPUTS" else (None, None)
            if start is not None and lo is not None and not np.all((start >= lo) & (start <= hi)):
                raise ValueError(f"the start of input {name} ({', '.join(f'{x:g}' for x in start)}) lies "
                                 f"outside its declared range [{lo:g}, {hi:g}]")
            if section == "PARAMETERS" and ident in bounds:
                bound = bounds[ident]
                lo, hi = bound.min, (None if np.isinf(bound.max) else bound.max)
                for x in (() if start is None else start):
                    why = bound.reason(float(x))
                    if why:
                        raise ValueError(f"the start of parameter {name}: {why}")
            for i in range(count):
                out.append(Variable(name if count == 1 else f"{name}[{i + 1}]", vr + i,
                                    SECTIONS[section], unit, what,
                                    None if start is None else float(start[i]), lo, hi))
            vr += count
    return out


def token(table: list[Variable], fmi_version: int, move: np.ndarray | None = None) -> str:
    """Instantiation token (guid): a hash of the variable table, its start values and the
    carried move."""
    text = repr([(x.name, x.vr, x.unit, x.start) for x in table])
    moved = b"" if move is None else np.ascontiguousarray(move, dtype=np.float64).tobytes()
    h = hashlib.sha256(f"stewart-controller-fmu/1/{fmi_version}/{text}".encode() + moved).hexdigest()
    return "{" + f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}" + "}"


def start_c_source(table: list[Variable], fmi_version: int,
                   move: np.ndarray | None = None) -> str:
    """The FMU's generated start file (START_FILE): the token, the start values by value reference and the carried move (n, 18)
    (l_ref, ldot_ref, v_ff per sample; none: an empty move), hexadecimal: exact."""
    def rows(causality):
        return ",\n    ".join(f"{float(x.start).hex()} /* {x.name} */"
                               for x in table if x.causality == causality)
    flat = np.zeros(1) if move is None else np.ravel(move)
    samples = ",\n    ".join(", ".join(float(v).hex() for v in flat[k:k + 6])
                              for k in range(0, flat.size, 6))
    return (f"/* Generated by controller.fmu (FMI {fmi_version}.0): do not edit. */\n"
            '#include "model.h"\n\n'
            f'const char AXIS_MODEL_TOKEN[] = "{token(table, fmi_version, move)}";\n'
            f"const double AXIS_START[N_PAR] = {{\n    {rows('parameter')}\n}};\n"
            f"const double AXIS_START_INPUTS[N_IN] = {{\n    {rows('input')}\n}};\n"
            f"const long AXIS_REF_N = {0 if move is None else move.shape[0]};\n"
            f"const double AXIS_REF[] = {{\n    {samples}\n}};\n")


def model_description(name: str, table: list[Variable], fmi_version: int,
                      sources: list[str], move: np.ndarray | None = None) -> bytes:
    """modelDescription.xml (FMI 2.0 or 3.0): parameters fixed and exact, inputs continuous,
    outputs calculated; DefaultExperiment steps one controller period."""
    import datetime

    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    attrs = {"modelName": name, "description": "Six per-axis PID position controllers with "
             "anti-windup and their DC motor currents: leg references and measured leg lengths "
             "in, motor torques out", "generationTool": GENERATION_TOOL,
             "generationDateAndTime": stamp, "variableNamingConvention": "structured"}
    root = fmi_root(fmi_version, attrs, token(table, fmi_version, move), MODEL_IDENTIFIER,
                    sources, serializes=False)
    units = SubElement(root, "UnitDefinitions")
    for unit in sorted({x.unit for x in table if x.unit}):
        SubElement(units, "Unit", {"name": unit})
    rate = next(x.start for x in table if x.name == "rate")
    SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stopTime": "1.0",
                                           "stepSize": repr(1.0 / rate)})
    mv = SubElement(root, "ModelVariables")
    if fmi_version == 3:
        SubElement(mv, "Float64", {"name": "time", "valueReference": "0", "causality": "independent",
                                   "variability": "continuous", "description": "simulation time"})
    index = {}
    for k, x in enumerate(table):
        common = {"name": x.name, "valueReference": str(x.vr), "description": x.description,
                  "causality": x.causality,
                  "variability": "fixed" if x.causality == "parameter" else "continuous"}
        if x.causality == "parameter":
            common["initial"] = "exact"
        index[x.vr] = k + 1 + (fmi_version == 3)
        real = {"unit": x.unit} if x.unit else {}
        if x.min is not None:   # a parameter without an upper bound declares min alone
            real["min"] = repr(x.min)
        if x.max is not None:
            real["max"] = repr(x.max)
        if x.start is not None:
            real["start"] = repr(x.start)
        if fmi_version == 2:
            SubElement(SubElement(mv, "ScalarVariable", common), "Real", real)
        else:
            SubElement(mv, "Float64", {**common, **real})
    ms = SubElement(root, "ModelStructure")
    outputs = [x for x in table if x.causality == "output"]
    if fmi_version == 2:
        for tag in ("Outputs", "InitialUnknowns"):
            group = SubElement(ms, tag)
            for x in outputs:
                SubElement(group, "Unknown", {"index": str(index[x.vr])})
    else:
        for tag in ("Output", "InitialUnknown"):
            for x in outputs:
                SubElement(ms, tag, {"valueReference": str(x.vr)})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def _build_description(sources: list[str]) -> bytes:
    """sources/buildDescription.xml (FMI 3.0): one configuration; include directories sources/
    (axis.h) and include/ (the core's stewart.h)."""
    root = Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    cfg = SubElement(root, "BuildConfiguration", {"modelIdentifier": MODEL_IDENTIFIER})
    fs = SubElement(cfg, "SourceFileSet", {"language": "C99"})
    for f in sources:
        SubElement(fs, "SourceFile", {"name": f})
    for d in (".", "include"):
        SubElement(fs, "IncludeDirectory", {"name": d})
    SubElement(cfg, "Library", {"name": "m"})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def export_controller(model: Model, config: ControllerConfig, out_path: str | Path,
                      fmi_version: int = 2, move: np.ndarray | None = None) -> Path:
    """Build the controller FMU of a scene's Model and [controller] at out_path; returns it.
    move: (n, 18) l_ref, ldot_ref, v_ff per controller sample from the start time, carried in
    the FMU (its parameter reference then starts at 1). UnstableLoopError if the design is not
    stable at the rate, CompilerNotFoundError, BuildError."""
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    if move is not None and (move.ndim != 2 or move.shape[1] != 18 or move.shape[0] < 1):
        raise ValueError(f"move must have shape (n, 18), got {move.shape}")
    values = start_values(model, config)
    if move is not None:
        values["reference"] = 1.0
        values["l_ref"], values["ldot_ref"], values["v_ff"] = move[0, :6], move[0, 6:12], move[0, 12:]
    table = variables(values)
    compiler = find_compiler()
    platform_folder(fmi_version)   # BuildError before any work: no binaries folder for this platform
    core = core_sources()
    own = {**{rel: NATIVE / rel for rel in core + FMI_LAYER[fmi_version]}, **OWN_SOURCES}
    c_files = sorted(f for f in own if f.endswith(".c")) + [START_FILE]
    out = Path(out_path)
    with tempfile.TemporaryDirectory(prefix="stewart_controller_fmu_") as tmp:
        root = Path(tmp) / "fmu"
        src = root / "sources"
        for rel, origin in own.items():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(origin, src / rel)
        (src / START_FILE).write_text(start_c_source(table, fmi_version, move))
        if fmi_version == 3:
            (src / "buildDescription.xml").write_bytes(_build_description(c_files))
        (root / "modelDescription.xml").write_bytes(
            model_description(f"{model.name} controller", table, fmi_version, c_files, move))
        build_binaries(compiler, [str(src / f) for f in c_files],
                       ["-I", str(src), "-I", str(src / "include")], root, MODEL_IDENTIFIER,
                       fmi_version, "the controller FMU")
        pack(root, Path(tmp) / "packed.fmu", out)
    return out
