"""Check an SSP archive's parameter sets against the ranges it declares, before any importer
instantiates an FMU (`stewart-sim check-ssp`).

An FMU refuses a parameter outside its bounds with fmi2Error at initialisation; libcosim then
aborts the importing process (SIGABRT, exit 134: the error is thrown on a worker thread, see
docs/guides/fmu-and-ssp.md, "The closed loop as an SSP"). This check reads, for every component
of the SystemStructure.ssd, each value of its parameter sets (ssd:ParameterBinding, a resource or
inline) and refuses, in one line naming the component, the parameter and the bound:
- a name that is no Real parameter or input of the component's FMU (its modelDescription.xml);
- a value outside that variable's min and max (FMI: both inclusive), or not finite;
- a value outside the range the parameter's annotation declares (controller.ssp.RANGE_TYPE:
  what export-ssp writes, where an open bound's min itself is refused, as the FMU does).
Archives and their members are read with bounded sizes; XML with a DOCTYPE is refused.
"""
from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, ParseError, fromstring

from stewart_fmu.budget import read_input
from stewart_fmu.errors import StewartError

from .fmu import Bound
from .ssp import RANGE, SSD, SSV, ParameterRangeError, range_of

MAX_ARCHIVE = 256 << 20   # bytes of the archive (export-ssp's: about 0.4 MB)
MAX_XML = 16 << 20        # bytes of one XML member (an ssd, an ssv, a model description)
MAX_FMU = MAX_ARCHIVE     # bytes of one FMU inside the archive, uncompressed
MAX_MEMBERS = 10_000  # entries of the archive or of an FMU


class SspError(StewartError, ValueError):
    """The archive cannot be checked (not a zip, a member missing, too large or malformed)."""


@dataclass(frozen=True)
class CheckResult:
    """What check_ssp read: the components and how many parameter values it checked."""

    components: tuple[str, ...]
    parameters: int


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _member(z: zipfile.ZipFile, name: str, limit: int, where: str) -> bytes:
    try:
        info = z.getinfo(name)
    except KeyError:
        raise SspError(f"{where}: no member {name!r}") from None
    if info.file_size > limit:
        raise SspError(f"{where}: {name} is {info.file_size} bytes, more than {limit}")
    with z.open(info) as fh:
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise SspError(f"{where}: {name} holds more than {limit} bytes")
    return data


def _xml(data: bytes, name: str, where: str) -> Element:
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise SspError(f"{where}: {name} declares a DOCTYPE or an entity: refused")
    try:
        return fromstring(data)
    except ParseError as exc:
        raise SspError(f"{where}: {name} is not well-formed XML ({exc})") from None


def _zip(data: bytes, where: str) -> zipfile.ZipFile:
    try:
        z = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, OSError) as exc:
        raise SspError(f"{where}: not a zip archive ({exc})") from None
    if len(z.infolist()) > MAX_MEMBERS:
        raise SspError(f"{where}: more than {MAX_MEMBERS} members")
    return z


def fmu_ranges(fmu: bytes, where: str) -> dict[str, Bound]:
    """The declared range (min and max, inclusive; none: infinite) of every Real parameter and
    input of an FMU (FMI 2.0 ScalarVariable/Real or FMI 3.0 Float64), by name."""
    with _zip(fmu, where) as z:
        root = _xml(_member(z, "modelDescription.xml", MAX_XML, where), "modelDescription.xml", where)
    out = {}
    for var in root.iter():
        real = var.find("Real") if var.tag == "ScalarVariable" else var if var.tag == "Float64" else None
        if real is None or var.get("causality") not in ("parameter", "input"):
            continue
        try:
            lo, hi = float(real.get("min", "-inf")), float(real.get("max", "inf"))
        except ValueError:
            raise SspError(f"{where}: variable {var.get('name')!r} declares a min or max that is "
                           f"not a number") from None
        out[var.get("name")] = Bound(False, lo, hi)
    return out


def _parameter_sets(z: zipfile.ZipFile, component: Element, where: str):
    """(the set's name, its ssv:ParameterSet element, the binding's prefix) per binding."""
    for binding in component.iter(_q(SSD, "ParameterBinding")):
        prefix, source = binding.get("prefix", ""), binding.get("source")
        if source is None:
            for inline in binding.iter(_q(SSV, "ParameterSet")):
                yield "an inline parameter set", inline, prefix
        else:
            yield source, _xml(_member(z, source, MAX_XML, where), source, where), prefix


def check_ssp(path: str | Path) -> CheckResult:
    """Check every parameter value of the archive at path (see the module doc); returns what
    was checked. ParameterRangeError (a value out of its range), SspError (anything else),
    InputFileError (path is no regular file, or too large)."""
    where = str(path)
    with _zip(read_input(path, MAX_ARCHIVE), where) as z:
        ssd = _xml(_member(z, "SystemStructure.ssd", MAX_XML, where), "SystemStructure.ssd", where)
        names, count = [], 0
        for component in ssd.iter(_q(SSD, "Component")):
            name, source = component.get("name", "?"), component.get("source", "")
            ranges = fmu_ranges(_member(z, source, MAX_FMU, where), f"{where}: {source}")
            names.append(name)
            for set_name, ssv, prefix in _parameter_sets(z, component, where):
                for p in ssv.iter(_q(SSV, "Parameter")):
                    count += _check_parameter(p, name, prefix, ranges, f"{where}: {set_name}: ")
    return CheckResult(tuple(names), count)


def _check_parameter(p: Element, component: str, prefix: str, ranges: dict[str, Bound],
                     where: str) -> int:
    """Check one ssv:Parameter (1 when it is a Real, 0 otherwise: the FMU checks the others)."""
    real = p.find(_q(SSV, "Real"))
    if real is None:
        return 0
    name = p.get("name", "")
    variable = name[len(prefix):] if prefix and name.startswith(prefix) else name
    try:
        value = float(real.get("value", ""))
    except ValueError:
        raise SspError(f"{where}parameter {component}.{name}: value {real.get('value')!r} is not "
                       f"a number") from None
    if variable not in ranges:
        raise SspError(f"{where}parameter {component}.{name} is no Real parameter or input of "
                       f"the component's FMU")
    declared = [ranges[variable]]
    for element in p.iter(_q(RANGE, "Range")):
        try:
            declared.append(range_of(element))
        except ValueError as exc:
            raise SspError(f"{where}parameter {component}.{name}: its declared {exc} is no "
                           f"range") from None
    for bound in declared:
        why = bound.reason(value)
        if why:
            raise ParameterRangeError(component, name, value, why, where)
    return 1

