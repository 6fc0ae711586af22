"""The closed loop of `run` as an SSP 1.0 archive (`export-ssp`): the plant FMU and the
controller FMU (FMI 2.0, the version FMPy's simulate_ssp runs), their connections, a parameter
set per component, and the move.

    SystemStructure.ssd       the plant's l, ldot -> the controller's l, ldot; the controller's
                              tau -> the plant's tau (WIRES); DefaultExperiment 0 .. the move's end,
                              OSP annotation: fixed step = the controller period (libcosim)
    resources/plant.fmu       export-fmu of the scene (stewart_fmu.fmu.export)
    resources/controller.fmu  export-fmu --controller, carrying the move (controller.fmu: its
                              parameter reference = 1: l_ref, ldot_ref, v_ff from the move)
    resources/plant.ssv       sigma = 0 (the drives alone push), q0, qd0 the move's start
    resources/controller.ssv  the design: gains, limits, rate, the drives' start, delay = 1

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

from stewart_fmu.fmu.export import export_model, pack
from stewart_fmu.model import Model

from .config import ControllerConfig
from .drive import axis_model
from .feedforward import feedforward_voltage
from .fmu import export_controller, start_values
from .trajectory import Trajectory, leg_references

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
for _prefix, _uri in (("ssd", SSD), ("ssc", SSC), ("ssv", SSV), ("osp", OSP)):
    register_namespace(_prefix, _uri)

PLANT, CONTROLLER = "plant", "controller"
LEGS = range(1, 7)
# (start element, its output group, end element, its input group): the loop's wires
WIRES = ((PLANT, "l", CONTROLLER, "l"), (PLANT, "ldot", CONTROLLER, "ldot"),
         (CONTROLLER, "tau", PLANT, "tau"))
# the controller's parameters written into its parameter set (the design, editable there)
CONTROLLER_PARAMETERS = ("rate", "kp", "ki", "kd", "voltage_limit", "current_limit", "resistance",
                         "inductance", "torque_constant", "emf_constant", "force_per_torque",
                         "integral0", "current0", "reference", "delay")


def move_of(model: Model, config: ControllerConfig, traj: Trajectory) -> np.ndarray:
    """(n, 18): l_ref, ldot_ref and the feedforward voltage per sample of traj, as
    cosim.run_closed_loop computes them."""
    refs = leg_references(model, traj)
    axis = axis_model(model, config.motor, config.load_mass)
    v_ff, _ = feedforward_voltage(model, config, axis, traj, refs)
    return np.hstack([refs.l, refs.ldot, v_ff])


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _parameter_set(name: str, values: dict[str, float]) -> bytes:
    root = Element(_q(SSV, "ParameterSet"), {"version": "1.0", "name": name})
    params = SubElement(root, _q(SSV, "Parameters"))
    for key, value in values.items():
        p = SubElement(params, _q(SSV, "Parameter"), {"name": key})
        SubElement(p, _q(SSV, "Real"), {"value": repr(float(value))})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


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
    delay whatever config.delay (see the module doc). The errors of export_model and
    export_controller (UnstableLoopError: the design with that delay is unstable)."""
    out = Path(out_path)
    config = replace(config, delay=1)   # the importers' step-then-exchange
    move = move_of(model, config, traj)
    start = start_values(model, config)
    plant_set = {**_scalars("sigma", np.zeros(6)), **_scalars("q0", traj.q[0]),
                 **_scalars("qd0", traj.qd[0])}
    controller_set = {}
    for key in CONTROLLER_PARAMETERS:
        controller_set.update(_scalars(key, 1.0 if key == "reference" else start[key]))
    with tempfile.TemporaryDirectory(prefix="stewart_ssp_") as tmp:
        root = Path(tmp) / "ssp"
        res = root / "resources"
        res.mkdir(parents=True)
        export_model(model, scene_text, res / f"{PLANT}.fmu", 2)
        export_controller(model, config, res / f"{CONTROLLER}.fmu", 2, move)
        (res / f"{PLANT}.ssv").write_bytes(_parameter_set(PLANT, plant_set))
        (res / f"{CONTROLLER}.ssv").write_bytes(_parameter_set(CONTROLLER, controller_set))
        (root / "SystemStructure.ssd").write_bytes(system_structure(
            f"{model.name} closed loop", float(traj.t[-1] - traj.t[0]), config.dt))
        pack(root, Path(tmp) / "packed.ssp", out)
    return out
