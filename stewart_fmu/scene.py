"""Scene files (TOML): parse, validate with errors that name the key, build the Model."""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .budget import SCENE_BYTES, InputFileError, read_input
from .errors import SceneError, SceneKeyError
from . import scene_reach, table
from .native import core
from .model import (DriveParams, FrictionParams, LegParams, Model, PayloadParams, StiffnessParams,
                    TransmissionParams)

DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
# Tables the project defines on top of the contract, each read by a command and checked where it
# is parsed, once, at load (stewart_sim.scene.load: [controller], [cueing], [case], [solver],
# [sensors]): here they are only let through into Model.extra; any other table is refused.
PROJECT_TABLES = frozenset({"controller", "case", "cueing", "solver", "sensors"})
_TOP_KEYS = {"name", "gravity", "geometry", "platform", "legs", "drive", "friction",
             "transmission", *scene_reach.REACH_TABLES, "stiffness", "payload"}
_OPTIONAL_KEYS = {"geometry.leg_min", "geometry.leg_max"}   # every other plant key is required
# Every value of a scene, in every table: nested at most MAX_DEPTH tables and arrays deep (a
# joint list is 2 inside its table; TOML readers recurse per level, so 50,000 levels are a
# RecursionError), and an integer at most 2^53 in magnitude (TOML integers are Python ints of
# any size; beyond 2^53 a float64 cannot hold them exactly, beyond ~1.8e308 not at all).
MAX_DEPTH = 16
MAX_INTEGER = 2**53


def _plant_table_keys() -> dict[str, tuple[set[str], set[str]]]:
    """(required, optional) keys of each plant table: the scene keys of the one table
    (native/include/stewart_table.h, read by table.scene_groups)."""
    out: dict[str, tuple[set[str], set[str]]] = {}
    for key in table.scene_groups():
        tab, _, name = key.rpartition(".")
        if tab:
            need, opt = out.setdefault(tab, (set(), set()))
            (opt if key in _OPTIONAL_KEYS else need).add(name)
    return out


_TABLE_KEYS = _plant_table_keys()
_VECTOR_KEYS = {k for k, g in table.scene_groups().items() if g.count > 1 and g.shape != table.PER_LEG}
# Dotted keys of the contract's tables that hold a single number (what a sweep may vary).
NUMBER_KEYS = frozenset(f"{t}.{k}" for t, (need, opt) in _TABLE_KEYS.items()
                        for k in need | opt) - _VECTOR_KEYS
# [stiffness] and [payload] (STEWART_ELASTIC of stewart_table.h: their bounds): the optional keys.
_ELASTIC_OPTIONAL = {"stiffness.joint_bending", "stiffness.joint_torsion"}
for _key in table.ELASTIC_KEYS:
    _tab, _, _name = _key.partition(".")
    _need, _opt = _TABLE_KEYS.setdefault(_tab, (set(), set()))
    (_opt if _key in _ELASTIC_OPTIONAL else _need).add(_name)


def load_scene(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Model:
    """Read a scene file and build its Model; `overrides` maps 'table.key' to a new value."""
    data = read_scene_dict(path)
    if overrides:
        data = apply_overrides(data, overrides)
    return scene_from_dict(data, source=str(path))


def read_scene_dict(path: str | Path) -> dict[str, Any]:
    """The parsed TOML of a scene file, not yet checked (SceneError: missing, not TOML)."""
    return parse_scene_bytes(read_scene_bytes(path), path)


def read_scene_bytes(path: str | Path) -> bytes:
    """A scene file's bytes, as given: a regular file of at most budget.SCENE_BYTES, read
    with that bound (SceneError: missing, a directory, a device, pipe or socket, too large,
    unreadable)."""
    try:
        return read_input(path, SCENE_BYTES)
    except InputFileError as exc:
        reason = {"missing": f"no such scene file: {path}",
                  "directory": "is a directory, not a scene file",
                  "special": "is a device, pipe or socket, not a scene file"}.get(
                      exc.kind, f"cannot read the scene file: {exc.reason}")
        raise SceneError("<file>", reason, None if exc.kind == "missing" else str(path)) \
            from None


def parse_scene_bytes(text: bytes, path: str | Path) -> dict[str, Any]:
    """The parsed TOML of a scene file's bytes, not yet checked (SceneError: not TOML; a value
    nested beyond MAX_DEPTH, SceneKeyError naming its key)."""
    try:
        decoded = text.decode()
    except UnicodeDecodeError as exc:
        raise SceneError("<file>", f"not a text (TOML) file: {exc.reason} at byte {exc.start}",
                         str(path)) from None
    try:
        return tomllib.loads(decoded)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("<file>", f"not valid TOML: {exc}", str(path)) from None
    except ValueError:   # an integer of more digits than Python converts (4300)
        digits = re.search(r"\d{4000,}", decoded)
        where = _key_at(decoded, digits.start()) if digits else "<file>"
        raise SceneKeyError(where, "integer of over 4000 digits is beyond 2^53, what a float64 "
                            "holds exactly", str(path)) from None
    except RecursionError:   # the reader recurses per level: find the key without recursing
        deep = _deep_key(decoded)
        if deep is None:
            raise SceneError("<file>", "nested too deep to read", str(path)) from None
        raise SceneKeyError(deep, f"nested more than {MAX_DEPTH} arrays or tables deep",
                            str(path)) from None


# The tokens that open or close a value's nesting, or hide brackets (strings, comments): what
# _deep_key reads of the text before the TOML reader recurses into it.
_NESTING = re.compile(r'"""|\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}=\n]')


def _deep_key(text: str) -> str | None:
    """The dotted key of the first value nested more than MAX_DEPTH arrays or inline tables
    deep, None when there is none (or the text is not TOML: the reader says so). One pass over
    the tokens, the nesting counted, never recursing."""
    table, key, depth, pos = "", "", 0, 0
    while pos < len(text):
        m = _NESTING.search(text, pos)
        if m is None:
            return None
        tok, pos = m.group(0), m.end()
        if tok in ('"""', "'''"):   # a multi-line string: skip to its end
            end = text.find(tok, pos)
            if end < 0:
                return None
            pos = end + 3
        elif tok == "=" and depth == 0:
            key = _line_before(text, m.start()).strip().strip('"\'')
        elif tok == "[" and depth == 0 and not _line_before(text, m.start()).strip():
            end = text.find("\n", pos)   # a table header [name] or [[name]]
            end = len(text) if end < 0 else end
            table, pos = text[pos:end].strip("[] \t").split("]")[0], end
        elif tok in "[{":
            depth += 1
            if depth > MAX_DEPTH:
                return f"{table}.{key}" if table else key
        elif tok in "]}":
            depth = max(0, depth - 1)
    return None


def _key_at(text: str, at: int) -> str:
    """The dotted key whose value holds the character at `at`: the last table header and the
    last `key =` at a line's start before it."""
    headers = re.findall(r"^\s*\[+\s*([A-Za-z_\"\'][\w.\"\' -]*?)\s*\]+\s*(?:#.*)?$", text[:at], re.M)
    keys = re.findall(r"^\s*([\w.\"\'-]+)\s*=", text[:at], re.M)
    key = keys[-1].strip("\"\'") if keys else "<file>"
    return f"{headers[-1].strip()}.{key}" if headers else key


def _line_before(text: str, at: int) -> str:
    """The text of at's line before it."""
    return text[text.rfind("\n", 0, at) + 1:at]


def apply_overrides(data: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Return a copy of a scene dict with dotted keys ('drive.gear_ratio') replaced."""
    out = _copy_tables(data)
    for dotted, value in overrides.items():
        *tables, key = dotted.split(".")
        node = out
        for t in tables:
            node = node.setdefault(t, {})
            if not isinstance(node, dict):
                raise SceneError(dotted, "override path runs through a non-table value")
        node[key] = value
    return out


def _copy_tables(data: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of nested tables (values other than tables are shared, as they are replaced)."""
    return {k: (_copy_tables(v) if isinstance(v, Mapping) else v) for k, v in data.items()}


def scene_from_dict(data: Mapping[str, Any], source: str | None = None) -> Model:
    """Validate a parsed scene and build its Model: each key's own rules here (the bounds of the
    one table), then the rules between keys on the packed Model (native/src/rules.c, which the
    FMU's validation calls too)."""
    v = _Validator(source)
    _check_values(v, data)
    unknown = set(data) - _TOP_KEYS - PROJECT_TABLES
    if unknown:
        v.fail_key(sorted(unknown)[0], f"unknown key (allowed: {sorted(_TOP_KEYS | PROJECT_TABLES)})")
    name = data.get("name", Path(source).stem if source else "scene")
    if not isinstance(name, str):
        v.fail("name", "must be a string")
    gravity = v.vector(data, "gravity", 3, default=DEFAULT_GRAVITY)
    geo = v.table(data, "geometry", required=True)
    plat = v.table(data, "platform", required=True)
    base = v.vector(geo, "geometry.base_joints", (6, 3))
    top = v.vector(geo, "geometry.platform_joints", (6, 3))
    home = v.vector(geo, "geometry.home", 6)
    leg_min = v.number(geo, "geometry.leg_min", optional=True)
    leg_max = v.number(geo, "geometry.leg_max", optional=True)
    mass = v.number(plat, "platform.mass")
    inertia = v.vector(plat, "platform.inertia", 3)
    model = Model(
        name=name, gravity=gravity, base_joints=base, platform_joints=top, home=home,
        leg_min=leg_min, leg_max=leg_max, platform_mass=mass, platform_inertia=inertia,
        legs=_legs(v, data), drive=_drive(v, data), friction=_friction(v, data),
        extra={k: data[k] for k in PROJECT_TABLES if k in data}, source=source,
        transmission=_transmission(v, data), **_reach_tables(v, data),
        stiffness=_stiffness(v, data), payload=_payload(v, data),
    )
    _check_rules(v, model)
    scene_reach.check_home(v, model)
    return model


def _reach_tables(v: "_Validator", data: Mapping[str, Any]) -> dict[str, Any]:
    """The Model's [joints], [clearance] and [frames] (stewart_fmu/scene_reach.py)."""
    return {"joints": scene_reach.joints(v, data), "clearance": scene_reach.clearance(v, data),
            "frames": scene_reach.frames(v, data)}


def _check_values(v: "_Validator", data: Mapping[str, Any]) -> None:
    """Every value of every table, before any is read: nested at most MAX_DEPTH deep, integers
    at most MAX_INTEGER (SceneKeyError naming the dotted key). Iterative: a walk of a value
    nested deeper than the interpreter's recursion limit must not recurse."""
    stack: list[tuple[str, Any, int]] = [("", data, 0)]
    while stack:
        key, value, depth = stack.pop()
        if depth > MAX_DEPTH:
            v.fail_key(key, f"nested more than {MAX_DEPTH} arrays or tables deep")
        if type(value) is float or type(value) is str:  # most values; nothing to look into
            continue
        if isinstance(value, Mapping):
            stack += [(f"{key}.{k}" if key else str(k), x, depth + 1) for k, x in value.items()]
        elif isinstance(value, (list, tuple)):
            stack += [(key, x, depth + 1) for x in value]
        elif isinstance(value, int) and not isinstance(value, bool) and abs(value) > MAX_INTEGER:
            digits = len(str(abs(value))) if abs(value) < 10**4300 else "over 4300"
            v.fail_key(key, f"integer of {digits} digits is beyond 2^53, what a float64 holds "
                            "exactly: write a float (1e30), within the key's bounds")


def _legs(v: "_Validator", data: Mapping[str, Any]) -> LegParams | None:
    t = v.table(data, "legs")
    if t is None:
        return None
    parts = {}
    for part in ("lower", "upper"):
        parts[f"{part}_mass"] = v.number(t, f"legs.{part}_mass")
        parts[f"{part}_com"] = v.number(t, f"legs.{part}_com")
        trans, axial = v.vector(t, f"legs.{part}_inertia", 2)
        parts[f"{part}_inertia"] = (trans, axial)
    return LegParams(**parts)


def _drive(v: "_Validator", data: Mapping[str, Any]) -> DriveParams | None:
    return _params(v, data, "drive", DriveParams)


def _friction(v: "_Validator", data: Mapping[str, Any]) -> FrictionParams | None:
    return _params(v, data, "friction", FrictionParams)


def _params(v: "_Validator", data: Mapping[str, Any], name: str, cls):
    """A plant table whose keys are the fields of its parameter class, each read as the table
    declares it (a number, six per-leg values or one for all, a vector); None when absent."""
    t = v.table(data, name)
    if t is None:
        return None
    return cls(**{f.name: v.value(t, f"{name}.{f.name}") for f in fields(cls)})


def _transmission(v: "_Validator", data: Mapping[str, Any]) -> TransmissionParams | None:
    """[transmission]: a spring-damper between each motor and its leg (needs the [drive])."""
    t = v.table(data, "transmission")
    if t is None:
        return None
    if data.get("drive") is None:
        v.fail("transmission", "needs the [drive] table: the motor side moves the drive inertia")
    return _params(v, data, "transmission", TransmissionParams)


def _stiffness(v: "_Validator", data: Mapping[str, Any]) -> StiffnessParams | None:
    """[stiffness]: each leg's axial stiffness (one number or six), the joints' optional
    bending and torsion stiffness; each > 0 (STEWART_ELASTIC)."""
    t = v.table(data, "stiffness")
    if t is None:
        return None
    return StiffnessParams(
        leg=v.per_leg(t, "stiffness.leg"),
        joint_bending=v.number(t, "stiffness.joint_bending", optional=True),
        joint_torsion=v.number(t, "stiffness.joint_torsion", optional=True))


def _payload(v: "_Validator", data: Mapping[str, Any]) -> PayloadParams | None:
    """[payload]: mass (> 0), com ([x, y, z] in C), inertia about the com in C: three principal
    moments or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], a tensor a rigid body can have (positive
    definite, its principal moments within the triangle inequality)."""
    t = v.table(data, "payload")
    if t is None:
        return None
    mass = v.number(t, "payload.mass")
    com = tuple(float(c) for c in v.vector(t, "payload.com", 3))
    raw = t["inertia"]
    n = len(raw) if isinstance(raw, list) else 0
    if n not in (3, 6):
        v.fail_key("payload.inertia", "must be 3 principal moments [Ixx, Iyy, Izz] or 6 values "
                   f"[Ixx, Iyy, Izz, Ixy, Ixz, Iyz], got {raw!r}")
    inertia = tuple(float(x) for x in v.vector(t, "payload.inertia", n))
    payload = PayloadParams(mass=mass, com=com, inertia=inertia)
    moments = np.linalg.eigvalsh(payload.inertia_tensor)
    if not moments[0] > 0.0:
        v.fail_key("payload.inertia", "must be positive definite (principal moments "
                   f"{[float(f'{m:.6g}') for m in moments]})")
    if moments[2] > (moments[0] + moments[1]) * (1.0 + 1e-12):
        v.fail_key("payload.inertia", "no rigid body has these principal moments: the largest "
                   f"{moments[2]:.6g} exceeds the sum of the others {moments[0] + moments[1]:.6g}")
    return payload


def _check_rules(v: "_Validator", model: Model) -> None:
    """The rules between keys, once every key has passed its own (native/src/rules.c, the
    FMU's validation too): coincident joints, leg_min below leg_max, the inertias a rigid body
    can have, a home pose within the stroke and away from singularities."""
    if model.drive is not None:   # its derived quantities first, as the FMU's validation
        d = model.drive
        rule, vr, reason = core.check_drive(d.gear_ratio, d.pinion_radius, d.rotor_inertia)
        if rule != core.RULE_OK:
            v.fail(table.group_at(vr).name, reason)
    rule, vr, _, reason = core.check_rules(model.native, model.home)
    if rule != core.RULE_OK:
        v.fail(table.group_at(vr).name, reason)


class _Validator:
    """Typed accessors that raise SceneError naming the dotted key."""

    def __init__(self, source: str | None):
        self.source = source

    def fail(self, key: str, reason: str) -> None:
        """A relation between keys is broken (SceneError)."""
        raise SceneError(key, reason, self.source)

    def fail_key(self, key: str, reason: str) -> None:
        """A key breaks its own rule (SceneKeyError)."""
        raise SceneKeyError(key, reason, self.source)

    def table(self, data: Mapping[str, Any], name: str, required: bool = False,
              keys: tuple[set, set] | None = None):
        """The table `name` of `data` (None when left out), its keys checked against `keys`
        (required, optional), by default the scene's own _TABLE_KEYS."""
        t = data.get(name)
        if t is None:
            if required:
                self.fail_key(name, "required table is missing")
            return None
        if not isinstance(t, Mapping):
            self.fail_key(name, f"must be a table, got {type(t).__name__}")
        need, optional = _TABLE_KEYS[name] if keys is None else keys
        for key in sorted(set(t) - need - optional):
            self.fail_key(f"{name}.{key}", f"unknown key (allowed: {sorted(need | optional)})")
        for key in sorted(need - set(t)):
            self.fail_key(f"{name}.{key}", "required key is missing")
        return t

    def number(self, t: Mapping[str, Any], dotted: str, optional: bool = False) -> float | None:
        key = dotted.rsplit(".", 1)[-1]
        if key not in t:
            if optional:
                return None
            self.fail_key(dotted, "required key is missing")
        x = t[key]
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            self.fail_key(dotted, f"must be a number, got {x!r}")
        x = float(x)
        if not math.isfinite(x):
            self.fail_key(dotted, f"must be finite, got {x}")
        self._bound(dotted, np.array(x))
        return x

    def value(self, t: Mapping[str, Any], dotted: str):
        """A plant key read as the table declares it (table.scene_groups)."""
        g = table.scene_groups()[dotted]
        if g.shape == table.PER_LEG:
            return self.per_leg(t, dotted)
        return self.number(t, dotted) if g.count == 1 else tuple(self.vector(t, dotted, g.count))

    def per_leg(self, t: Mapping[str, Any], dotted: str) -> float | tuple[float, ...]:
        """A per-leg key: one number for all legs, or a list of six (legs 1..6)."""
        x = t.get(dotted.rsplit(".", 1)[-1])
        if not isinstance(x, list):
            return self.number(t, dotted)
        if len(x) != 6:
            self.fail_key(dotted, f"must be one number, or six (one per leg), got {len(x)} values")
        return tuple(float(e) for e in self._array(x, dotted, (6,)))

    def vector(self, t: Mapping[str, Any], dotted: str, n: int | tuple[int, ...],
               default=None) -> np.ndarray:
        """An array of shape (n,) (or the shape n), each value within the key's bound."""
        key = dotted.rsplit(".", 1)[-1]
        if key not in t:
            if default is None:
                self.fail_key(dotted, "required key is missing")
            return np.array(default, dtype=float)
        return self._array(t[key], dotted, n if isinstance(n, tuple) else (n,))

    def _array(self, x: Any, dotted: str, shape: tuple[int, ...]) -> np.ndarray:
        def bad(reason: str):
            self.fail_key(dotted, reason)

        try:
            arr = np.array(x, dtype=float)
        except (TypeError, ValueError):
            bad(f"must be numbers of shape {shape}, got {x!r}")
        for e in np.ravel(np.array(x, dtype=object)):
            if isinstance(e, bool):
                bad("must be numbers, not booleans")
            if not isinstance(e, (int, float)):
                bad(f"must be numbers, got {e!r} in {x!r}")
        if arr.shape != shape:
            bad(f"wrong shape: expected {shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            bad(f"must be finite, got {np.asarray(x).tolist()}")
        self._bound(dotted, arr)
        return arr

    def _bound(self, dotted: str, arr: np.ndarray) -> None:
        """The key's physical bounds: the one table's (native/include/stewart_table.h)."""
        reason = table.bound_reason(table.key_group(scene_reach.generic_key(dotted)), arr)
        if reason is not None:
            self.fail_key(dotted, reason)
