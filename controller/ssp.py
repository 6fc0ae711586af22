"""The closed loop of `run` as an SSP 1.0 archive (`export-ssp`): the plant FMU and the
controller FMU (FMI 2.0, the version FMPy's simulate_ssp runs), their connections, a parameter
set per component, and the move.

    SystemStructure.ssd       the plant's l, ldot -> the controller's l, ldot; the controller's
                              tau -> the plant's tau (WIRES); DefaultExperiment 0 .. the move's end,
                              OSP annotation: fixed step = the controller period (libcosim)
    resources/plant.fmu       export-fmu of the scene (stewart_fmu.fmu.export)
    resources/controller.fmu  export-fmu --controller, carrying the move (controller.fmu: its
                              parameter reference = 1: l_ref, ldot_ref, v_ff from the move)
    resources/plant.ssv       every Real parameter of the plant FMU (the scene's values, the
                              solver's), q0, qd0 the move's start, sigma = 0 (the drives alone
                              push)
    resources/controller.ssv  the design: gains, limits, rate, the drives' start, delay = 1

Each parameter of a set carries its declared range (the FMU's min and max, from the tables
stewart_table.h and axis_table.h, and whether min itself is excluded) in an annotation
(RANGE_TYPE): SSP 1.0's ssv:Real holds a value and a unit only, and a ssv:Parameter may carry
ssc:Annotations. export_ssp refuses a set whose values break them (ParameterRangeError, before
anything is written); controller.ssp_check refuses such an archive before any importer
instantiates an FMU (libcosim aborts its process on the fmi2Error that follows).

The move is `run`'s reference (controller.moves.run_reference) and its feedforward voltage
(feedforward.feedforward_voltage), sampled at the controller rate.

Timing: SSP importers step every FMU over the period and then pass the outputs on (FMPy's
simulate_ssp, libcosim's fixed-step algorithm), so the torque the controller computes from the
lengths at t_k reaches the plant over [t_k+1, t_k+2]: one period of actuation delay, the
scene's `[controller] delay = 1` (config.ControllerConfig). The controller FMU's parameter
delay = 1 (its outputs are the last step's sample, before the first step the drives' start)
makes that loop `run`'s with delay 1, sample for sample; so the SSP is always written with
delay 1, whatever the scene's.
"""
from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, indent, register_namespace, tostring

import numpy as np

from stewart_fmu import table
from stewart_fmu.errors import StewartError
from stewart_fmu.fmu import variables as plant_fmu
from stewart_fmu.fmu.export import export_model, pack
from stewart_fmu.model import Model

from .config import ControllerConfig, scene_axis
from .feedforward import feedforward_voltage
from .fmu import Bound, export_controller, parameter_ranges, start_values, table_rows
from .trajectory import Trajectory, leg_references

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
# The parameters' declared ranges: ssc:Annotation type RANGE_TYPE holding <range:Range min=".."
# [max=".."] [minExclusive="true"]/> (no max: none; minExclusive: min itself is refused).
RANGE = "urn:stewart-sim:ssp:parameter-range"
RANGE_TYPE = "org.stewart-sim.parameter-range"
for _prefix, _uri in (("ssd", SSD), ("ssc", SSC), ("ssv", SSV), ("osp", OSP), ("range", RANGE)):
    register_namespace(_prefix, _uri)
ANY = Bound(False, -np.inf, np.inf)   # no declared range: any finite number

PLANT, CONTROLLER = "plant", "controller"
LEGS = range(1, 7)
# (start element, its output group, end element, its input group): the loop's wires
WIRES = ((PLANT, "l", CONTROLLER, "l"), (PLANT, "ldot", CONTROLLER, "ldot"),
         (CONTROLLER, "tau", PLANT, "tau"))
# the controller's parameters written into its parameter set (the design, editable there)
CONTROLLER_PARAMETERS = ("rate", "kp", "ki", "kd", "voltage_limit", "current_limit", "resistance",
                         "inductance", "torque_constant", "emf_constant", "force_per_torque",
                         "integral0", "current0", "reference", "delay")


class ParameterRangeError(StewartError, ValueError):
    """A parameter set's value breaks its declared range (or is no number): one line naming the
    component, the parameter and the bound."""

    def __init__(self, component: str, name: str, value: float, reason: str, where: str = ""):
        self.component, self.name, self.value = component, name, value
        super().__init__(f"{where}parameter {component}.{name} {reason}")


def move_of(model: Model, config: ControllerConfig, traj: Trajectory) -> np.ndarray:
    """(n, 18): l_ref, ldot_ref and the feedforward voltage per sample of traj, as
    cosim.run_closed_loop computes them."""
    refs = leg_references(model, traj)
    axis = scene_axis(model, config)
    v_ff, _ = feedforward_voltage(model, config, axis, traj, refs)
    return np.hstack([refs.l, refs.ldot, v_ff])


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _parameter_set(name: str, values: dict[str, tuple[float, Bound]]) -> bytes:
    """A ssv file: each parameter's value and, in its annotation, its declared range."""
    root = Element(_q(SSV, "ParameterSet"), {"version": "1.0", "name": name})
    params = SubElement(root, _q(SSV, "Parameters"))
    for key, (value, bound) in values.items():
        p = SubElement(params, _q(SSV, "Parameter"), {"name": key})
        SubElement(p, _q(SSV, "Real"), {"value": repr(float(value))})
        if bound != ANY:
            note = SubElement(SubElement(p, _q(SSV, "Annotations")), _q(SSC, "Annotation"),
                              {"type": RANGE_TYPE})
            SubElement(note, _q(RANGE, "Range"), range_attributes(bound))
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def range_attributes(bound: Bound) -> dict[str, str]:
    """The attributes of a <range:Range> element (read back by range_of)."""
    attrs = {"min": repr(float(bound.min))}
    if np.isfinite(bound.max):
        attrs["max"] = repr(float(bound.max))
    if bound.open:
        attrs["minExclusive"] = "true"
    return attrs


def range_of(element: Element) -> Bound:
    """The Bound a <range:Range> element declares (ValueError: not numbers, or min > max)."""
    lo, hi = float(element.get("min", "-inf")), float(element.get("max", "inf"))
    if np.isnan(lo) or np.isnan(hi) or lo > hi:
        raise ValueError(f"range min={element.get('min')!r} max={element.get('max')!r}")
    return Bound(element.get("minExclusive") == "true", lo, hi)


def plant_set(model: Model, traj: Trajectory) -> dict[str, tuple[float, Bound]]:
    """The plant's parameter set: every Real parameter of the plant FMU (FMI 2.0) at its start
    value, q0 and qd0 the move's start, sigma = 0; with each its declared range (the table's
    bounds, an open one's min excluded; sigma's input range)."""
    given = {**_scalars("sigma", np.zeros(6)), **_scalars("q0", traj.q[0]),
             **_scalars("qd0", traj.qd[0])}
    groups = {g.name: g for g in table.VARIABLES}
    out = {}
    for var in plant_fmu.variables(model, 2):
        if var.type == "Real" and (var.causality == "parameter" or var.name in given):
            g = groups[var.name.partition("[")[0]]
            bound = ANY if var.min is None else Bound(g.bound == table.BOUND_OPEN, var.min, var.max)
            out[var.name] = (given.get(var.name, var.start), bound)
    return out


def controller_set(start: dict[str, np.ndarray]) -> dict[str, tuple[float, Bound]]:
    """The controller's parameter set: CONTROLLER_PARAMETERS at `start` (start_values),
    reference = 1 (the carried move), with each its declared range (axis_table.h's, none for
    integral0 and current0)."""
    ident = {name: i for i, name, *_ in table_rows()["PARAMETERS"]}
    bounds = parameter_ranges()
    out = {}
    for key in CONTROLLER_PARAMETERS:
        bound = bounds.get(ident[key], ANY)
        for name, value in _scalars(key, 1.0 if key == "reference" else start[key]).items():
            out[name] = (value, bound)
    return out


def check_set(component: str, values: dict[str, tuple[float, Bound]], where: str = "") -> None:
    """ParameterRangeError for the first value outside its range (or not finite)."""
    for name, (value, bound) in values.items():
        why = bound.reason(float(value))
        if why:
            raise ParameterRangeError(component, name, float(value), why, where)


def _scalars(name: str, values) -> dict[str, float]:
    flat = np.ravel(values)
    return {name: float(flat[0])} if flat.size == 1 else {
        f"{name}[{i + 1}]": float(x) for i, x in enumerate(flat)}


def system_structure(name: str, stop_time: float, step: float) -> bytes:
    """SystemStructure.ssd: the two components, their connectors, parameter bindings and the
    wires; the default experiment with libcosim's fixed-step annotation."""
    root = Element(_q(SSD, "SystemStructureDescription"), {"version": "1.0", "name": name})
    system = SubElement(root, _q(SSD, "System"), {"name": name})
    elements = SubElement(system, _q(SSD, "Elements"))
    for component in (PLANT, CONTROLLER):
        el = SubElement(elements, _q(SSD, "Component"), {
            "name": component, "type": "application/x-fmu-sharedlibrary",
            "source": f"resources/{component}.fmu"})
        connectors = SubElement(el, _q(SSD, "Connectors"))
        for start, out, end, inp in WIRES:
            for who, group, kind in ((start, out, "output"), (end, inp, "input")):
                if who == component:
                    for i in LEGS:
                        c = SubElement(connectors, _q(SSD, "Connector"),
                                       {"name": f"{group}[{i}]", "kind": kind})
                        SubElement(c, _q(SSC, "Real"))
        bindings = SubElement(el, _q(SSD, "ParameterBindings"))
        SubElement(bindings, _q(SSD, "ParameterBinding"), {"source": f"resources/{component}.ssv"})
    connections = SubElement(system, _q(SSD, "Connections"))
    for start, out, end, inp in WIRES:
        for i in LEGS:
            SubElement(connections, _q(SSD, "Connection"), {
                "startElement": start, "startConnector": f"{out}[{i}]",
                "endElement": end, "endConnector": f"{inp}[{i}]"})
    experiment = SubElement(root, _q(SSD, "DefaultExperiment"),
                            {"startTime": "0.0", "stopTime": repr(float(stop_time))})
    notes = SubElement(experiment, _q(SSD, "Annotations"))
    note = SubElement(notes, _q(SSC, "Annotation"), {"type": "com.opensimulationplatform"})
    algorithm = SubElement(note, _q(OSP, "Algorithm"))
    SubElement(algorithm, _q(OSP, "FixedStepAlgorithm"), {"baseStepSize": repr(float(step))})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def export_ssp(model: Model, scene_text: bytes, config: ControllerConfig, traj: Trajectory,
               out_path: str | Path) -> Path:
    """Write the SSP of the closed loop along traj (sampled at the controller rate, starting at
    rest: `run`'s reference) at out_path; returns it. The loop has one period of actuation
    delay whatever config.delay (see the module doc). ParameterRangeError when a parameter
    set's value breaks its declared range; the errors of export_model and export_controller
    (UnstableLoopError: the design with that delay is unstable)."""
    out = Path(out_path)
    config = replace(config, delay=1)   # the importers' step-then-exchange
    sets = {PLANT: plant_set(model, traj), CONTROLLER: controller_set(start_values(model, config))}
    for component, values in sets.items():   # before any work: nothing written
        check_set(component, values, "export-ssp: ")
    move = move_of(model, config, traj)
    with tempfile.TemporaryDirectory(prefix="stewart_ssp_") as tmp:
        root = Path(tmp) / "ssp"
        res = root / "resources"
        res.mkdir(parents=True)
        export_model(model, scene_text, res / f"{PLANT}.fmu", 2)
        export_controller(model, config, res / f"{CONTROLLER}.fmu", 2, move)
        for component, values in sets.items():
            (res / f"{component}.ssv").write_bytes(_parameter_set(component, values))
        (root / "SystemStructure.ssd").write_bytes(system_structure(
            f"{model.name} closed loop", float(traj.t[-1] - traj.t[0]), config.dt))
        pack(root, Path(tmp) / "packed.ssp", out)
    return out
