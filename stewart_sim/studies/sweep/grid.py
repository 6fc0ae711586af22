"""Design-sweep specifications (GRID.toml): what each point evaluates and the points themselves,
a full grid or a seeded Latin hypercube over dotted scene, controller and trajectory keys.

    evaluation = "inverse"            # "inverse" | "closed_loop" | "envelope" | "modes"
    method = "grid"                   # "grid": every combination | "lhs": Latin hypercube
    samples = 1000                    # lhs: number of points
    seed = 1                          # lhs: the sample is reproducible from it
    batch = 250                       # points per task (default: tasks sized to a target
                                      # duration, up to MAX_BATCH points: sweep/batching.py)
    [trajectory]                      # inverse and closed_loop
    kind = "demo"                     # "demo" | "run" | "file" (see sweep_eval)
    duration = 1.0                    # s (demo, run)
    rate = 1000.0                     # Hz (demo; the closed loop runs at [controller] rate)
    file = "traj.csv"                 # kind = "file": a trajectory CSV (contract columns)
    [envelope]                        # envelope: pose grid about home (offsets, m or rad)
    x = [-0.02, 0.02]                 # any of x, y, z, thx, thy, thz; the others stay at home
    points = 5                        # per listed coordinate
    accelerations = [[0, 0, 0, 0, 0, 0]]   # load cases qdd (default: static only)
    [adaptive]                        # where `sweep --adaptive N` adds its N points
    target = "sigma_max"              # "feasible" (default): status ok/error; or a result column
    threshold = 1500.0                # a result column: the value whose crossing is sought
    [axes]
    "platform.mass" = [0.5, 1.0, 2.0]                     # values
    "pairs.base_half_angle" = [8.0, 12.0, 16.0]           # the joints (sweep/joint_layout.py)
    "drive.gear_ratio" = {min = 5, max = 40, points = 8, log = true}   # a range
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.stats import qmc

from controller.config import FEEDFORWARD
from controller.config import NUMBER_KEYS as CONTROLLER_NUMBERS
from controller.drive import MOTOR_KEYS
from stewart_fmu.budget import SCENE_BYTES, BudgetError, InputFileError, check_count, read_input
from stewart_fmu.errors import SweepError
from stewart_fmu.io import POSE
from stewart_fmu.scene import NUMBER_KEYS as SCENE_NUMBERS
from stewart_sim.studies.sweep.joint_layout import LAYOUT_KEYS

EVALUATIONS = ("inverse", "closed_loop", "envelope", "modes")
METHODS = ("grid", "lhs")
MAX_BATCH = 10_000   # the most points a sized task takes (a chunk file's bound without `batch`)
TRAJECTORY_KINDS = ("demo", "run", "file")
MAX_POINTS = 10_000_000
POINT_BYTES = 150   # a point of GridSpec.points, per axis and one more: its dict, tuple, floats
_TOP = {"evaluation", "method", "samples", "seed", "batch", "trajectory", "envelope", "adaptive",
        "axes"}
FEASIBLE = "feasible"   # the adaptive target "a point's status flips between ok and error"
_RANGE = {"min", "max", "points", "log"}
# What an axis may vary: numbers, plus the string-valued keys with their allowed values (None:
# any string).
NUMBER_AXES = (SCENE_NUMBERS | {f"controller.{k}" for k in CONTROLLER_NUMBERS}
               | {f"controller.motor.{k}" for k in MOTOR_KEYS} | {"trajectory.duration"}
               | set(LAYOUT_KEYS))
STRING_AXES = {"controller.feedforward": FEEDFORWARD, "trajectory.kind": TRAJECTORY_KINDS,
               "trajectory.file": None}


@dataclass(frozen=True)
class Axis:
    """One swept key: explicit `values`, or a range [lo, hi] (`points` of it on a grid)."""

    key: str
    values: tuple[Any, ...] | None = None
    lo: float = math.nan
    hi: float = math.nan
    points: int = 0
    log: bool = False

    def grid_values(self) -> tuple[Any, ...]:
        """The values a full grid takes along this axis."""
        if self.values is not None:
            return self.values
        space = np.geomspace if self.log else np.linspace
        return tuple(float(v) for v in space(self.lo, self.hi, self.points))

    def from_unit(self, u: float) -> Any:
        """The value at u in [0, 1): lerp of the range (log-uniform with `log`), or the value
        list's stratum."""
        if self.values is not None:
            return self.values[min(int(u * len(self.values)), len(self.values) - 1)]
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class TrajectorySettings:
    """The trajectory each inverse or closed-loop point follows."""

    kind: str = "demo"
    duration: float = 1.0
    rate: float = 1000.0
    file: str | None = None


@dataclass(frozen=True)
class EnvelopeSettings:
    """The pose grid (offsets from home) and load cases of an envelope evaluation."""

    ranges: tuple[tuple[str, float, float], ...] = (("x", -0.01, 0.01), ("y", -0.01, 0.01))
    points: int = 5
    accelerations: tuple[tuple[float, ...], ...] = ((0.0,) * 6,)

    def offsets(self) -> np.ndarray:
        """(P, 6) pose offsets: the product grid over the listed coordinates."""
        axes = [np.zeros(1)] * 6
        for name, lo, hi in self.ranges:
            axes[POSE.index(name)] = np.linspace(lo, hi, self.points)
        return np.array(list(itertools.product(*axes)), dtype=float)


@dataclass(frozen=True)
class AdaptiveSettings:
    """What `sweep --adaptive N` refines (stewart_sim/studies/sweep/adaptive.py): where a point's
    feasibility flips (target FEASIBLE), or where a result column crosses `threshold`."""

    target: str = FEASIBLE
    threshold: float = math.nan


@dataclass(frozen=True)
class GridSpec:
    """A parsed, checked GRID.toml."""

    evaluation: str
    method: str
    axes: tuple[Axis, ...]
    samples: int
    seed: int
    batch: int
    trajectory: TrajectorySettings
    envelope: EnvelopeSettings
    raw: Mapping[str, Any]   # the TOML as read (the sweep's fingerprint)
    source: str | None = None
    adaptive: AdaptiveSettings = AdaptiveSettings()
    sized: bool = False      # no `batch` given: tasks sized to a target duration, up to `batch`

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(a.key for a in self.axes)

    def size(self) -> int:
        """The number of points."""
        if self.method == "lhs":
            return self.samples
        return math.prod(len(a.grid_values()) for a in self.axes)

    def points(self) -> list[tuple[int, dict[str, Any]]]:
        """(point id, {key: value}) for every point, ids 0..size-1 in a fixed order (grid: the
        last axis fastest; lhs: the sample's rows)."""
        return list(self.point_sequence())

    def point_sequence(self) -> "PointSequence":
        """The points as `points` gives them, each made when asked for (a sweep of millions of
        points holds none of them at once)."""
        return PointSequence(self)

    def fingerprint(self, scene: Mapping[str, Any]) -> str:
        """A hash of the grid and the scene: a directory holds the rows of one sweep only."""
        text = json.dumps({"grid": self.raw, "scene": scene}, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()


class PointSequence(Sequence):
    """GridSpec.points without the list: point i decoded from its id (grid: mixed radix, the
    last axis fastest, as itertools.product orders them), or read from the Latin hypercube's
    unit sample (lhs: 8 bytes per axis and point)."""

    def __init__(self, spec: GridSpec) -> None:
        self.axes, self.keys, self.n = spec.axes, spec.keys, spec.size()
        self.values = [a.grid_values() for a in spec.axes] if spec.method == "grid" else None
        self.unit = (None if self.values is not None else
                     qmc.LatinHypercube(d=len(spec.axes), seed=spec.seed).random(spec.samples))

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> tuple[int, dict[str, Any]]:   # type: ignore[override]
        if not isinstance(i, (int, np.integer)) or not 0 <= i < self.n:
            raise IndexError(f"point {i!r}: not 0 to {self.n - 1}")
        i = int(i)
        if self.values is None:
            combo: Sequence[Any] = [a.from_unit(float(x)) for a, x in zip(self.axes, self.unit[i])]
        else:
            rest, picked = i, []
            for vals in reversed(self.values):
                rest, k = divmod(rest, len(vals))
                picked.append(vals[k])
            combo = picked[::-1]
        return i, dict(zip(self.keys, combo))


def load_grid(path: str | Path) -> GridSpec:
    """Read and check GRID.toml (SweepError names the key)."""
    path = Path(path)
    try:
        data = tomllib.loads(read_input(path, SCENE_BYTES).decode())
    except InputFileError as exc:
        if exc.kind == "missing":
            raise SweepError(None, f"no such grid file: {path}") from None
        reason = {"directory": "is a directory, not a grid file",
                  "special": "is a device, pipe or socket, not a grid file"}.get(
                      exc.kind, f"cannot read the grid file: {exc.reason}")
        raise SweepError(None, reason, str(path)) from None
    except UnicodeDecodeError as exc:
        raise SweepError(None, f"not a text (TOML) file: {exc.reason} at byte {exc.start}",
                         str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(None, f"not valid TOML: {exc}", str(path)) from None
    return grid_from_dict(data, str(path))


def grid_from_dict(data: Mapping[str, Any], source: str | None = None) -> GridSpec:
    """Check a parsed grid and build its GridSpec; every error names the key."""
    def fail(key: str, reason: str):
        raise SweepError(key, reason, source)

    for key in sorted(set(data) - _TOP):
        fail(key, f"unknown key (allowed: {sorted(_TOP)})")
    evaluation = _choice(data, "evaluation", EVALUATIONS, None, fail)
    method = _choice(data, "method", METHODS, "grid", fail)
    axes_table = data.get("axes")
    if not isinstance(axes_table, Mapping) or not axes_table:
        fail("axes", "required table with at least one axis is missing")
    axes = tuple(_axis(k, v, method, fail) for k, v in _flatten(axes_table))
    for a in axes:
        _check_relevant(a.key, evaluation, fail)
    samples = _integer(data, "samples", 1, MAX_POINTS, None if method == "lhs" else 0, fail)
    if method == "grid" and "samples" in data:
        fail("samples", "only for method = \"lhs\"")
    seed = _integer(data, "seed", 0, 2**63 - 1, 0, fail)
    batch = _integer(data, "batch", 1, 100_000, MAX_BATCH, fail)
    spec = GridSpec(evaluation, method, axes, samples, seed, batch, _trajectory(data, fail),
                    _envelope(data, fail), dict(data), source, _adaptive(data, fail),
                    sized="batch" not in data)
    if spec.size() > MAX_POINTS:
        fail("axes", f"{spec.size():,} points: more than {MAX_POINTS:,}")
    try:    # GridSpec.points holds every point (its index and its values) at once
        check_count("grid points", spec.size(), POINT_BYTES * (1 + len(axes)))
    except BudgetError as exc:
        fail("axes", str(exc))
    return spec


def _flatten(table: Mapping[str, Any], prefix: str = ""):
    """(dotted key, axis value) pairs: `"platform.mass" = ...` and `platform.mass = ...` alike."""
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping) and not (set(v) & _RANGE):
            yield from _flatten(v, key + ".")
        else:
            yield key, v


def _axis(key: str, value: Any, method: str, fail) -> Axis:
    """Check one axis: a known key; a non-empty list of values of its type, or a range."""
    where = f"axes.{key}"
    if key not in NUMBER_AXES and key not in STRING_AXES:
        fail(where, "not a key a sweep can vary (numbers of the scene's tables, controller.*, "
                    "controller.motor.*, trajectory.duration|kind|file)")
    if isinstance(value, list):
        if not value:
            fail(where, "empty list of values")
        for v in value:
            _check_value(key, v, where, fail)
        return Axis(key, values=tuple(float(v) if key in NUMBER_AXES else v for v in value))
    if not isinstance(value, Mapping):
        fail(where, f"must be a list of values or a range {{min, max, points}}, got {value!r}")
    if key not in NUMBER_AXES:
        fail(where, "a range needs a numeric key; give a list of values")
    for k in sorted(set(value) - _RANGE):
        fail(f"{where}.{k}", f"unknown key (allowed: {sorted(_RANGE)})")
    lo, hi = (_number(value, k, f"{where}.{k}", fail) for k in ("min", "max"))
    if not lo < hi:
        fail(where, f"min must be below max, got {lo} and {hi}")
    log = value.get("log", False)
    if not isinstance(log, bool):
        fail(f"{where}.log", f"must be true or false, got {log!r}")
    if log and lo <= 0:
        fail(f"{where}.min", f"a log range needs min > 0, got {lo}")
    if method == "lhs":
        if "points" in value:
            fail(f"{where}.points", "a Latin hypercube takes `samples` points in all, not per axis")
        return Axis(key, lo=lo, hi=hi, log=log)
    points = _integer(value, "points", 1, MAX_POINTS, None, fail, f"{where}.points")
    return Axis(key, lo=lo, hi=hi, points=points, log=log)


def _check_relevant(key: str, evaluation: str, fail) -> None:
    """Controller keys act only in the closed loop; trajectory keys not in the envelope nor
    the modes."""
    if key.startswith("controller.") and evaluation != "closed_loop":
        fail(f"axes.{key}", f"controller settings have no effect on evaluation '{evaluation}'")
    if key.startswith("trajectory.") and evaluation == "envelope":
        fail(f"axes.{key}", "the envelope follows no trajectory (see [envelope])")
    if key.startswith("trajectory.") and evaluation == "modes":
        fail(f"axes.{key}", "the modes are taken at home: no trajectory")


def _check_value(key: str, v: Any, where: str, fail) -> None:
    if key in NUMBER_AXES:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            fail(where, f"values must be finite numbers, got {v!r}")
        return
    allowed = STRING_AXES[key]
    if not isinstance(v, str) or (allowed is not None and v not in allowed):
        fail(where, f"values must be {'one of ' + repr(allowed) if allowed else 'strings'}, got {v!r}")


def _number(t: Mapping[str, Any], k: str, where: str, fail, default: float | None = None) -> float:
    if k not in t:
        if default is None:
            fail(where, "required key is missing")
        return default
    v = t[k]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        fail(where, f"must be a finite number, got {v!r}")
    return float(v)


def _integer(t: Mapping[str, Any], k: str, lo: int, hi: int, default: int | None, fail,
             where: str | None = None) -> int:
    where = where or k
    if k not in t:
        if default is None:
            fail(where, "required key is missing")
        return default
    v = t[k]
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        fail(where, f"must be an integer from {lo} to {hi}, got {v!r}")
    return v


def _choice(t: Mapping[str, Any], k: str, allowed, default, fail, where: str | None = None) -> str:
    where = where or k
    if k not in t:
        if default is None:
            fail(where, f"required key is missing (one of {allowed})")
        return default
    if t[k] not in allowed:
        fail(where, f"must be one of {allowed}, got {t[k]!r}")
    return t[k]


def _table(data: Mapping[str, Any], name: str, allowed: set[str], fail) -> Mapping[str, Any]:
    t = data.get(name, {})
    if not isinstance(t, Mapping):
        fail(name, f"must be a table, got {t!r}")
    for k in sorted(set(t) - allowed):
        fail(f"{name}.{k}", f"unknown key (allowed: {sorted(allowed)})")
    return t


def _positive(t: Mapping[str, Any], k: str, where: str, fail, default: float) -> float:
    v = _number(t, k, where, fail, default)
    if v <= 0:
        fail(where, f"must be > 0, got {v}")
    return v


def _trajectory(data: Mapping[str, Any], fail) -> TrajectorySettings:
    t = _table(data, "trajectory", {"kind", "duration", "rate", "file"}, fail)
    kind = _choice(t, "kind", TRAJECTORY_KINDS, "demo", fail, "trajectory.kind")
    file = t.get("file")
    if file is not None and not isinstance(file, str):
        fail("trajectory.file", f"must be a path (string), got {file!r}")
    if kind == "file" and file is None:
        fail("trajectory.file", "kind = \"file\" needs the trajectory CSV's path")
    return TrajectorySettings(kind, _positive(t, "duration", "trajectory.duration", fail, 1.0),
                              _positive(t, "rate", "trajectory.rate", fail, 1000.0), file)


def _envelope(data: Mapping[str, Any], fail) -> EnvelopeSettings:
    t = _table(data, "envelope", {*POSE, "points", "accelerations"}, fail)
    if not t:
        return EnvelopeSettings()
    ranges = []
    for name in POSE:
        if name not in t:
            continue
        r = t[name]
        if (not isinstance(r, list) or len(r) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and math.isfinite(v) for v in r) or not r[0] <= r[1]):
            fail(f"envelope.{name}", f"must be [low, high] offsets from home, got {r!r}")
        ranges.append((name, float(r[0]), float(r[1])))
    if not ranges:
        fail("envelope", f"give the range of at least one of {POSE}")
    points = _integer(t, "points", 1, 1000, 5, fail, "envelope.points")
    acc = t.get("accelerations", [[0.0] * 6])
    try:
        arr = np.array(acc, dtype=float)
    except (TypeError, ValueError):
        arr = np.empty(0)
    if arr.ndim != 2 or arr.shape[1] != 6 or not arr.size or not np.all(np.isfinite(arr)):
        fail("envelope.accelerations", f"must be a list of 6-vectors qdd, got {acc!r}")
    return EnvelopeSettings(tuple(ranges), points, tuple(tuple(map(float, a)) for a in arr))


def _adaptive(data: Mapping[str, Any], fail) -> AdaptiveSettings:
    """The [adaptive] table's form; whether the target is a result of the evaluation is
    adaptive.check_adaptive's (the results are evaluate.py's, which imports this module)."""
    t = _table(data, "adaptive", {"target", "threshold"}, fail)
    target = t.get("target", FEASIBLE)
    if not isinstance(target, str):
        fail("adaptive.target", f"must be \"{FEASIBLE}\" or a result column's name, got {target!r}")
    if target == FEASIBLE:
        if "threshold" in t:
            fail("adaptive.threshold", f"only for a result column as target, not \"{FEASIBLE}\"")
        return AdaptiveSettings()
    return AdaptiveSettings(target, _number(t, "threshold", "adaptive.threshold", fail))
