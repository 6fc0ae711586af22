"""The [case] table of the stiff and extreme scenes (scenes/stiff, scenes/extreme), read and
checked once (case_of, called by stewart_sim.scene.load when the scene is loaded; SceneError
names the dotted key):

    [case]
    kind = "stiff"                 # "stiff" | "extreme"
    description = "..."
    motion = "hold"                # what runs, see below
    duration = 0.2                 # s
    expect = "ok"                  # "ok" | "StrokeLimitError" | "SingularityError"
    step = 1e-3                    # optional: communication step / sample period (s)
    force_scale = 1.05             # hold: rack forces = force_scale x the hold at home
    start_rates = [0, ...]         # hold: initial pose rates (default rest)
    acceleration = [10, 0, ...]    # accelerate: constant pose acceleration from rest at home
    target = [0, 0, 0.12, ...]     # ramp: quintic move from home to this pose

What each motion runs: stewart_sim.studies.cases.outcome.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from stewart_fmu.errors import SceneError, SceneKeyError, StewartError
from stewart_fmu.model import Model

DEFAULT_STEP = 1e-3
# The [case] table's keys: the required ones, the optional ones and the words a string key takes.
REQUIRED = ("kind", "description", "motion", "duration", "expect")
OPTIONAL = ("step", "force_scale", "start_rates", "acceleration", "target")
CHOICES = {"kind": ("stiff", "extreme"),
           "motion": ("hold", "accelerate", "ramp", "closed_loop"),
           "expect": ("ok", "StrokeLimitError", "SingularityError")}
_POSITIVE = ("duration", "step")                               # s
_VECTORS = ("start_rates", "acceleration", "target")           # six numbers each (a pose's)
_MOTION_NEEDS = {"accelerate": "acceleration", "ramp": "target"}  # motion -> required key


@dataclass(frozen=True)
class Case:
    """A scene's [case] table with its defaults filled in."""

    kind: str
    description: str
    motion: str
    duration: float
    expect: str
    step: float = DEFAULT_STEP
    force_scale: float = 1.0
    start_rates: np.ndarray = field(default_factory=lambda: np.zeros(6))
    acceleration: np.ndarray | None = None
    target: np.ndarray | None = None


def case_of(model: Model) -> Case:
    """The model's [case] table, checked, as a Case: SceneKeyError names a key that breaks its
    own rule (unknown, missing, wrong type, out of range), SceneError one that breaks a rule
    between keys (a motion's required vector, a closed loop without [controller])."""
    table = model.extra.get("case")
    if table is None:
        raise StewartError(f"scene {model.source or model.name} has no [case] table")
    source = model.source
    if not isinstance(table, Mapping):
        raise SceneKeyError("case", f"must be a table, got {type(table).__name__}", source)
    allowed = sorted(REQUIRED + OPTIONAL)
    for key in sorted(set(table) - set(allowed)):
        raise SceneKeyError(f"case.{key}", f"unknown key (allowed: {allowed})", source)
    for key in sorted(set(REQUIRED) - set(table)):
        raise SceneKeyError(f"case.{key}", "required key is missing", source)
    for key, choices in CHOICES.items():
        if not isinstance(table[key], str) or table[key] not in choices:
            raise SceneKeyError(f"case.{key}", f"must be one of {list(choices)}, got "
                                f"{table[key]!r}", source)
    if not isinstance(table["description"], str):
        raise SceneKeyError("case.description", "must be a string", source)
    scalars = {k: _number(table, k, source) for k in ("duration", "step", "force_scale")
               if k in table}
    vectors = {k: _vector(table, k, source) for k in _VECTORS if k in table}
    motion = table["motion"]
    need = _MOTION_NEEDS.get(motion)
    if need is not None and need not in table:
        raise SceneError(f"case.{need}", f"required for motion '{motion}'", source)
    if motion == "closed_loop" and "controller" not in model.extra:
        raise SceneError("case.motion", "'closed_loop' needs the scene's [controller] table",
                         source)
    return Case(table["kind"], table["description"], motion, expect=table["expect"],
                **scalars, **vectors)


def _number(table: Mapping[str, Any], key: str, source: str | None) -> float:
    """A finite number ( > 0 for the times)."""
    x = table[key]
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise SceneKeyError(f"case.{key}", f"must be a number, got {x!r}", source)
    if not np.isfinite(x):
        raise SceneKeyError(f"case.{key}", f"must be finite, got {x}", source)
    if key in _POSITIVE and x <= 0:
        raise SceneKeyError(f"case.{key}", f"must be > 0, got {x}", source)
    return float(x)


def _vector(table: Mapping[str, Any], key: str, source: str | None) -> np.ndarray:
    """Six finite numbers (a pose's, or its rates or accelerations)."""
    x = table[key]
    if not isinstance(x, list) or len(x) != 6 or any(
            isinstance(e, bool) or not isinstance(e, (int, float)) for e in x):
        raise SceneKeyError(f"case.{key}", f"must be six numbers, got {x!r}", source)
    arr = np.array(x, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise SceneKeyError(f"case.{key}", f"must be finite, got {arr.tolist()}", source)
    return arr
