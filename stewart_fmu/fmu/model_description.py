"""modelDescription.xml of the native FMU, FMI 2.0 or 3.0, generated from the variable table
(variables.py). FMI 2.0 declares scalars (sigma[1] .. sigma[6]); FMI 3.0 the same groups as
array variables with their <Dimension>s (sigma, six values), adds the independent variable
`time` and the pose arrays q, qd; outputs are calculated, parameters fixed and exact."""
from __future__ import annotations

import datetime
from typing import Iterable
from xml.etree.ElementTree import Element, SubElement, indent, tostring

from ..model import Model
from . import variables as V

GENERATION_TOOL = "stewart-sim native FMU export"
DESCRIPTION = "Stewart platform plant (Kane's method): rack forces in, leg and pose states out"


def _num(x: float) -> str:
    return repr(float(x))


def _units(root: Element, used: Iterable[str]) -> None:
    units = SubElement(root, "UnitDefinitions")
    for name in sorted(set(used)):
        unit = SubElement(units, "Unit", {"name": name})
        SubElement(unit, "BaseUnit", {k: str(v) for k, v in V.UNITS[name].items()})


def _log_categories(root: Element) -> None:
    cats = SubElement(root, "LogCategories")
    for name, what in V.LOG_CATEGORIES.items():
        SubElement(cats, "Category", {"name": name, "description": what})


def fmi_root(fmi_version: int, attrs: dict[str, str], token: str, model_identifier: str,
             sources: list[str], serializes: bool) -> Element:
    """The <fmiModelDescription> element of a co-simulation FMU (FMI 2.0 or 3.0, this
    package's plant and controller alike) with its <CoSimulation> capabilities: variable
    communication steps, get and set state, serialized state when `serializes`, no event mode;
    FMI 2.0 lists the shipped `sources`. `attrs`: modelName, description and the like."""
    if fmi_version == 2:
        root = Element("fmiModelDescription", {"fmiVersion": "2.0", "guid": token, **attrs,
                                               "numberOfEventIndicators": "0"})
        cs = SubElement(root, "CoSimulation", {
            "modelIdentifier": model_identifier, "canHandleVariableCommunicationStepSize": "true",
            "canGetAndSetFMUstate": "true", "canSerializeFMUstate": _flag(serializes),
            "canNotUseMemoryManagementFunctions": "true", "canInterpolateInputs": "false"})
        files = SubElement(cs, "SourceFiles")
        for name in sources:
            SubElement(files, "File", {"name": name})
    else:
        root = Element("fmiModelDescription", {"fmiVersion": "3.0", **attrs,
                                               "instantiationToken": token})
        SubElement(root, "CoSimulation", {
            "modelIdentifier": model_identifier, "canHandleVariableCommunicationStepSize": "true",
            "canGetAndSetFMUState": "true", "canSerializeFMUState": _flag(serializes),
            "hasEventMode": "false", "providesIntermediateUpdate": "false",
            "canReturnEarlyAfterIntermediateUpdate": "false"})
    return root


def _flag(value: bool) -> str:
    return "true" if value else "false"


def build(model: Model, table: list[V.Variable], fmi_version: int, model_identifier: str,
          sources: list[str]) -> bytes:
    """The model description of a scene's Model with its variables (V.variables(model,
    fmi_version)), as UTF-8 XML bytes."""
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    attrs = {"modelName": model.name, "description": DESCRIPTION,
             "generationTool": GENERATION_TOOL, "generationDateAndTime": stamp,
             "variableNamingConvention": "structured"}
    rtol = next(x.start for x in table if x.vr == V.VR_RTOL and x.causality == "parameter")
    root = fmi_root(fmi_version, attrs, V.token(table, fmi_version), model_identifier, sources,
                    serializes=True)
    _units(root, [x.unit for x in table if x.unit])
    _log_categories(root)
    SubElement(root, "DefaultExperiment", {
        "startTime": "0.0", "stopTime": _num(V.STOP_TIME),
        "tolerance": _num(rtol), "stepSize": _num(V.STEP_SIZE)})
    mv = SubElement(root, "ModelVariables")
    outputs, index = [], {}
    for k, var in enumerate(table):
        common = {"name": var.name, "valueReference": str(var.vr), "description": var.description,
                  "causality": var.causality, "variability": var.variability}
        if var.initial:
            common["initial"] = var.initial
        index[var.vr] = k + 1
        if var.causality == "output":
            outputs.append(var)
        if fmi_version == 2:
            sv = SubElement(mv, "ScalarVariable", common)
            if var.type == "String":
                SubElement(sv, "String", {"start": str(var.start)})
            else:
                real = {}
                if var.unit:
                    real["unit"] = var.unit
                if var.min is not None:
                    real.update(min=_num(var.min), max=_num(var.max))
                if var.start is not None:
                    real["start"] = _num(var.start)
                SubElement(sv, "Real", real)
        elif var.type == "String":
            el = SubElement(mv, "String", common)
            SubElement(el, "Start", {"value": str(var.start)})
        else:
            attrs3 = dict(common)
            if var.unit:
                attrs3["unit"] = var.unit
            if var.min is not None:
                attrs3.update(min=_num(var.min), max=_num(var.max))
            if var.start is not None:   # an array's start: its values, row-major
                attrs3["start"] = " ".join(map(_num, var.start)) if var.shape else _num(var.start)
            el = SubElement(mv, "Float64", attrs3)
            for n in var.shape:
                SubElement(el, "Dimension", {"start": str(n)})
    ms = SubElement(root, "ModelStructure")
    if fmi_version == 2:
        outs = SubElement(ms, "Outputs")
        for var in outputs:
            SubElement(outs, "Unknown", {"index": str(index[var.vr])})
        init = SubElement(ms, "InitialUnknowns")
        for var in outputs:
            SubElement(init, "Unknown", {"index": str(index[var.vr])})
    else:
        for var in outputs:
            SubElement(ms, "Output", {"valueReference": str(var.vr)})
        for var in outputs:
            SubElement(ms, "InitialUnknown", {"valueReference": str(var.vr)})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"


def build_description_xml(model_identifier: str, sources: list[str]) -> bytes:
    """sources/buildDescription.xml (FMI 3.0, section 2.4.9): one build configuration."""
    root = Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    cfg = SubElement(root, "BuildConfiguration", {"modelIdentifier": model_identifier})
    fs = SubElement(cfg, "SourceFileSet", {"language": "C99"})
    for name in sources:
        SubElement(fs, "SourceFile", {"name": name})
    for directory in (".",):
        SubElement(fs, "IncludeDirectory", {"name": directory})
    SubElement(cfg, "Library", {"name": "m"})
    indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8") + b"\n"
