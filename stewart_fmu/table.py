"""The one table of the plant (native/include/stewart_table.h), as the compiled core holds it.

The packed parameter layout (PARAMS: offsets and counts of Model.params) and the FMU's variable
groups (VARIABLES: names, value references, shapes, units, bounds; INPUT_RANGES: the inputs'
declared ranges) are written once, as C
X-macros; this module reads them back from the core (src/table.c), as status.py reads the
status codes, so that no Python module spells an offset or a value reference.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .native.core import ffi, lib

# The kind of a parameter's bounds (stewart_table.h STEWART_BOUND_*): MIN <= x <= MAX (CLOSED),
# MIN < x <= MAX (OPEN); inputs and outputs have none (ANY).
BOUND_ANY, BOUND_CLOSED, BOUND_OPEN = lib.STEWART_BOUND_ANY, lib.STEWART_BOUND_CLOSED, lib.STEWART_BOUND_OPEN
BOUND_INTERIOR = lib.STEWART_BOUND_INTERIOR   # MIN < x < MAX (a cone inside (0, pi/2))
# Shapes beyond a group's count: a plain vector, or one value per leg (or one for all legs).
VECTOR, PER_LEG, STRING = lib.STEWART_VECTOR, lib.STEWART_PER_LEG, lib.STEWART_STRING


@dataclass(frozen=True)
class Param:
    """One entry of the packed parameter vector."""

    name: str           # STEWART_P_<name>
    offset: int
    count: int
    source: str         # the id of the FMU scene variable it holds, or "COMPUTED"
    unit: str
    description: str


@dataclass(frozen=True)
class VariableGroup:
    """One group of FMU variables: a scalar, a vector, a matrix or six per-leg values."""

    id: str             # VR_<id> of fmi/model.h
    name: str           # the dotted name (for a parameter: its scene key)
    vr: int             # the first value reference
    count: int
    shape: int          # VECTOR, PER_LEG, or the columns of a matrix
    bound: int          # BOUND_*: the kind of [min, max]
    min: float          # the physical bounds of each value, in `unit` (-inf, inf: none)
    max: float
    scene: bool         # a scene key of the plant tables (its name is the dotted key)
    fmi3_only: bool     # an FMI 3.0 array only (q, qd: the pose beside its named scalars)
    causality: str      # parameter, input or output
    unit: str           # "" none; "pose" / "rate": m or rad (/s) per pose component
    description: str


def _text(p) -> str:
    return ffi.string(p).decode()


def _read_params() -> dict[str, Param]:
    rows = (lib.stewart_param_table[k] for k in range(lib.stewart_param_table_size))
    return {_text(r.name): Param(_text(r.name), r.offset, r.count, _text(r.source),
                                 _text(r.unit), _text(r.description)) for r in rows}


def _read_variables() -> tuple[VariableGroup, ...]:
    rows = (lib.stewart_variable_table[k] for k in range(lib.stewart_variable_table_size))
    return tuple(VariableGroup(_text(r.id), _text(r.name), r.vr, r.count, r.shape, r.bound, r.min, r.max,
                               bool(r.scene), bool(r.fmi3_only), _text(r.causality), _text(r.unit),
                               _text(r.description))
                 for r in rows)


def _read_input_ranges() -> dict[str, tuple[float, float]]:
    rows = (lib.stewart_input_range_table[k] for k in range(lib.stewart_input_range_table_size))
    return {_text(r.id): (float(r.min), float(r.max)) for r in rows}


PARAMS: dict[str, Param] = _read_params()
N_PARAMS: int = lib.STEWART_N_PARAMS
VARIABLES: tuple[VariableGroup, ...] = _read_variables()
GROUPS: dict[str, VariableGroup] = {g.id: g for g in VARIABLES}
# The declared range (min, max) of each input group, by id (STEWART_FMU_INPUT_RANGES): the
# model description declares it and the FMU's setReal refuses a value outside it.
INPUT_RANGES: dict[str, tuple[float, float]] = _read_input_ranges()
VR_TIME, VR_METHOD, VR_N_PAR = lib.STEWART_VR_TIME, lib.STEWART_VR_METHOD, lib.STEWART_VR_N_PARAMETERS
VR_END: int = lib.STEWART_VR_N_OUTPUTS   # past the last value reference


def offset(name: str) -> int:
    """STEWART_P_<name>: where a packed entry starts in Model.params."""
    return PARAMS[name].offset


def vr(group_id: str) -> int:
    """VR_<id>: the first value reference of an FMU variable group."""
    return GROUPS[group_id].vr


SCENE_GROUPS: dict[str, VariableGroup] = {g.name: g for g in VARIABLES if g.scene}


@dataclass(frozen=True)
class ElasticEntry:
    """A key of [stiffness] or [payload] (STEWART_ELASTIC, STEWART_PAYLOAD_KEYS; not FMU
    variables): its shape, unit and bounds, and where its values are packed: Model.elastic
    (STEWART_E_<name>) or, for the payload, Model.params (STEWART_P_<name>)."""

    name: str
    key: str            # the dotted scene key, "" for a computed entry
    in_params: bool     # packed in Model.params (else in Model.elastic)
    offset: int
    count: int
    shape: int          # VECTOR or PER_LEG
    bound: int
    min: float
    max: float
    unit: str
    description: str


def _read_elastic() -> dict[str, ElasticEntry]:
    rows = (lib.stewart_elastic_table[k] for k in range(lib.stewart_elastic_table_size))
    return {_text(r.name): ElasticEntry(_text(r.name), _text(r.key), bool(r.in_params), r.offset,
                                        r.count, r.shape, r.bound, r.min, r.max, _text(r.unit),
                                        _text(r.description))
            for r in rows}


ELASTIC: dict[str, ElasticEntry] = _read_elastic()
N_ELASTIC: int = lib.STEWART_N_ELASTIC
# The scene keys of [stiffness] and [payload], by dotted key (bound_reason takes them).
ELASTIC_KEYS: dict[str, ElasticEntry] = {e.key: e for e in ELASTIC.values() if e.key}


# The FMU's solver settings by key (rtol, atol, max_step): a scene's [solver] takes their bounds.
SOLVER_GROUPS: dict[str, VariableGroup] = {g.name.removeprefix("solver."): g for g in VARIABLES
                                           if g.name.startswith("solver.") and g.shape != STRING}


_BY_VR: dict[int, VariableGroup] = {g.vr: g for g in VARIABLES}


def group_at(first_vr: int) -> VariableGroup:
    """The FMU variable group whose first value reference is first_vr (a rule's report names
    its key so: native/src/rules.c)."""
    return _BY_VR[first_vr]


def scene_groups() -> dict[str, VariableGroup]:
    """The FMU parameters that are scene keys ("platform.mass", ...), by dotted key."""
    return SCENE_GROUPS


def unit_text(unit: str) -> str:
    """A unit after a bound: " kg", " (m, rad)" for a pose, "" for none (as fmi/model.c words it)."""
    return {"pose": " (m, rad)", "rate": " (m/s, rad/s)", "": "", "1": ""}.get(unit, f" {unit}")


def bound_reason(group: VariableGroup | ElasticEntry, values) -> str | None:
    """Why values (a number or an array) break their group's bounds, None when they do not: the
    words of the FMU's validation (fmi/model.c validate), e.g. "must be > 0, got -0.5" or
    "must be <= 1e+06 kg, got 1e+308"."""
    if group.bound == BOUND_ANY:
        return None
    open_ = group.bound in (BOUND_OPEN, BOUND_INTERIOR)
    top_open = group.bound == BOUND_INTERIOR
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 0:   # one number: compared as a float (NaN fails both, as below)
        x = float(arr)
        if (x > group.min if open_ else x >= group.min) and (x < group.max if top_open
                                                             else x <= group.max):
            return None
    unit = unit_text(group.unit)
    low = ~(arr > group.min) if open_ else ~(arr >= group.min)
    got = arr.tolist()
    if np.any(low):
        return f"must be {'>' if open_ else '>='} {group.min:g}{'' if group.min == 0 else unit}, got {got}"
    if np.any(~(arr < group.max) if top_open else ~(arr <= group.max)):
        return f"must be {'<' if top_open else '<='} {group.max:g}{unit}, got {got}"
    return None


# --- reach: the scene keys of [joints], [clearance], [frames], the packed reach vector and the
# limits of the feasibility engine (stewart_table.h STEWART_REACH_SCENE, _REACH_PARAMS, _LIMITS)

@dataclass(frozen=True)
class ReachKey:
    """A scene key of the reach tables and its bounds (an obstacle's under
    'clearance.obstacles.<key>')."""

    id: str
    name: str
    count: int
    bound: int
    min: float
    max: float
    unit: str
    description: str


@dataclass(frozen=True)
class Limit:
    """One limit of the engine: its index is its place in report order."""

    index: int
    id: str
    name: str       # the column name of `workspace --check`
    kind: int       # LIMIT_LEG, LIMIT_PAIR, LIMIT_OBSTACLE, LIMIT_POSE
    unit: str
    description: str


LIMIT_LEG, LIMIT_PAIR, LIMIT_OBSTACLE, LIMIT_POSE = (
    lib.STEWART_LIMIT_KIND_LEG, lib.STEWART_LIMIT_KIND_PAIR, lib.STEWART_LIMIT_KIND_OBSTACLE,
    lib.STEWART_LIMIT_KIND_POSE)


def _read_reach() -> tuple[dict[str, Param], dict[str, ReachKey], tuple[Limit, ...]]:
    params = {}
    for k in range(lib.stewart_reach_param_table_size):
        r = lib.stewart_reach_param_table[k]
        params[_text(r.name)] = Param(_text(r.name), r.offset, r.count, "", _text(r.unit),
                                      _text(r.description))
    keys = {}
    for k in range(lib.stewart_reach_key_table_size):
        r = lib.stewart_reach_key_table[k]
        keys[_text(r.name)] = ReachKey(_text(r.id), _text(r.name), r.count, r.bound, r.min, r.max,
                                       _text(r.unit), _text(r.description))
    limits = tuple(Limit(k, _text(r.id), _text(r.name), r.kind, _text(r.unit), _text(r.description))
                   for k, r in ((k, lib.stewart_limit_table[k])
                                for k in range(lib.stewart_limit_table_size)))
    return params, keys, limits


REACH_PARAMS, REACH_KEYS, LIMITS = _read_reach()
N_REACH: int = lib.STEWART_N_REACH


def reach_offset(name: str) -> int:
    """STEWART_R_<name>: where an entry starts in the packed reach vector (Model.reach)."""
    return REACH_PARAMS[name].offset


def key_group(dotted: str) -> VariableGroup | ReachKey | ElasticEntry:
    """The bounds of a scene key: a plant key's FMU group, a reach table's key (an obstacle's
    keys by their generic name, 'clearance.obstacles.radius'), or a key of [stiffness] or
    [payload]."""
    if dotted in SCENE_GROUPS:
        return SCENE_GROUPS[dotted]
    return REACH_KEYS[dotted] if dotted in REACH_KEYS else ELASTIC_KEYS[dotted]
