"""design.toml read and checked: the base scene, the free parameters and their bounds, the
workspace to cover, the payload and the requirements (docs/guides/design.md). Every key is
checked against its bound; a bad one is a DesignInputError naming it (exit 2)."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stewart_fmu.budget import SCENE_BYTES, InputFileError, read_input
from stewart_fmu.errors import StewartError
from stewart_fmu.scene import read_scene_dict

from .flight_spec import Flight, flight
from .keys import DesignInputError, integer as _int, is_number as _is_number, number as _number
from .keys import only as _only

POSE = ("x", "y", "z", "thx", "thy", "thz")
# free parameter -> (unit, lowest allowed bound, highest allowed bound)
PARAMETERS = {
    "base_radius": ("m", 1e-3, 100.0),
    "platform_radius": ("m", 1e-3, 100.0),
    # a pair's joints apart, and apart from the next pair's (0 and pi/3 make joints coincide)
    "base_half_angle": ("rad", 1e-3, math.pi / 3 - 1e-3),
    "platform_half_angle": ("rad", 1e-3, math.pi / 3 - 1e-3),
    "home_height": ("m", 1e-3, 100.0),
    "platform_joint_z": ("m", -100.0, 100.0),
    "leg_min": ("m", 1e-3, 100.0),
    "stroke": ("m", 1e-4, 100.0),
    "leg_stiffness": ("N/m", 1.0, 1e12),
    "base_joint_z": ("m", -100.0, 100.0),
}
OPTIONAL = {"base_joint_z": 0.0}     # a parameter left out of [parameters] is fixed at this
DRIVE = "drive"     # the catalogue drive's parameter: its index in cost order (floored)
MAX_POSES = 200_000      # poses of one grid (the dense check's too)
MAX_POPULATION = 1000
MAX_GENERATIONS = 1000




@dataclass(frozen=True)
class Parameter:
    name: str
    low: float
    high: float          # == low: fixed

    @property
    def free(self) -> bool:
        return self.high > self.low


@dataclass(frozen=True)
class Workspace:
    """The poses to cover, about home: per-axis ranges (m, rad), how they combine ("box": every
    combination of the grid's values, "axes": one axis at a time), the points per axis of the
    search's and the dense check's grids, and orientation sets ([thx, thy, thz] rad) held at
    every position of the grid."""

    ranges: dict[str, tuple[float, float]]
    combine: str
    search_points: int
    check_points: int
    orientations: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True)
class Requirements:
    first_resonance: float | None            # Hz, least first mode over the workspace
    stiffness: tuple[float | None, ...]      # per axis x..thz (N/m, N m/rad); None: no need
    cond_limit: float                        # cond(J) limit over the workspace
    base_cone: float | None                  # rad: the joints' cones (a margin is what is left)
    platform_cone: float | None


@dataclass(frozen=True)
class Search:
    population: int
    generations: int
    seed: int
    reserve: float       # least relative margin the chosen design keeps on every requirement



@dataclass(frozen=True)
class DesignSpec:
    source: str
    base: dict[str, Any]                 # the base scene as parsed (tables)
    parameters: tuple[Parameter, ...]
    workspace: Workspace
    payload: dict[str, Any] | None
    requirements: Requirements
    search: Search
    flight: Flight | None = None         # None: no motions to fly

    @property
    def free(self) -> tuple[Parameter, ...]:
        return tuple(p for p in self.parameters if p.free)

    def values(self, x: np.ndarray) -> dict[str, float]:
        """Every parameter's value: the free ones from x (in `free` order), the fixed ones."""
        out, k = {}, 0
        for p in self.parameters:
            if p.free:
                out[p.name] = float(x[k])
                k += 1
            else:
                out[p.name] = p.low
        return out

    def drive(self, values: dict[str, float]):
        """The catalogue drive of a candidate's values (None: the base scene's drive)."""
        if self.flight is None or self.flight.drives is None:
            return None
        drives = self.flight.drives
        return drives[min(max(int(values[DRIVE]), 0), len(drives) - 1)]


def unit(name: str) -> str:
    """A parameter's unit ('' for the drive's index)."""
    return PARAMETERS[name][0] if name in PARAMETERS else ""


def load(path: str | Path) -> DesignSpec:
    """Read and check design.toml (DesignInputError naming the key)."""
    path = Path(path)
    try:
        raw = read_input(path, SCENE_BYTES).decode()
        data = tomllib.loads(raw)
    except InputFileError as exc:
        raise DesignInputError(f"{path}: cannot read: {exc.reason}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise DesignInputError(f"{path}: not a TOML file: {exc}") from None
    return parse(data, path)


def parse(data: dict, path: Path) -> DesignSpec:
    src = str(path)
    _only(data, {"design", "parameters", "workspace", "payload", "requirements", "search",
                 "motions", "drives"}, "", src)
    design = _table(data, "design", src, required=True)
    _only(design, {"base_scene"}, "design.", src)
    scene_path = (path.parent / _string(design, "base_scene", "design.", src)).resolve()
    try:
        base = read_scene_dict(scene_path)
    except StewartError as exc:
        raise DesignInputError(f"{src}: design.base_scene: {exc}") from None
    payload = _table(data, "payload", src) or None
    if payload is not None:
        _check_payload(base, payload, src)
    fl = flight(_table(data, "motions", src), _table(data, "drives", src), path, scene_path)
    parameters = _parameters(_table(data, "parameters", src, required=True), src)
    if fl is not None and fl.drives is not None:
        n = len(fl.drives)   # one drive: fixed; more: free over [0, n), floored to the index
        parameters += (Parameter(DRIVE, 0.0, float(n) if n > 1 else 0.0),)
    if not any(p.free for p in parameters):
        raise DesignInputError(f"{src}: parameters: at least one must be free ([low, high])")
    return DesignSpec(src, base, parameters,
                      _workspace(_table(data, "workspace", src, required=True), src),
                      payload,
                      _requirements(_table(data, "requirements", src, required=True), src),
                      _search(_table(data, "search", src), src), fl)


def _check_payload(base: dict, payload: dict, src: str) -> None:
    """[payload] checked as a scene's, on the base scene (SceneError naming payload.<key>)."""
    from stewart_fmu.errors import SceneError
    from stewart_fmu.scene import scene_from_dict

    try:
        scene_from_dict({**base, "payload": payload}, source=src)
    except SceneError as exc:
        if exc.key.startswith("payload"):
            raise DesignInputError(f"{src}: {exc.key}: {exc.reason}") from None
        raise DesignInputError(f"{src}: design.base_scene: {exc}") from None


def _parameters(t: dict, src: str) -> tuple[Parameter, ...]:
    _only(t, set(PARAMETERS), "parameters.", src)
    out = []
    for name, (unit, lo, hi) in PARAMETERS.items():
        key = f"parameters.{name}"
        if name not in t and name in OPTIONAL:
            out.append(Parameter(name, OPTIONAL[name], OPTIONAL[name]))
            continue
        if name not in t:
            raise DesignInputError(f"{src}: {key}: required ({unit}: a number, fixed, or "
                                   f"[low, high], free)")
        v = t[name]
        pair = [v, v] if _is_number(v) else v
        if not (isinstance(pair, list) and len(pair) == 2 and all(_is_number(x) for x in pair)):
            raise DesignInputError(f"{src}: {key}: a number or [low, high] ({unit}), got {v!r}")
        a, b = float(pair[0]), float(pair[1])
        if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi):
            raise DesignInputError(f"{src}: {key}: need {lo:g} <= low <= high <= {hi:g} "
                                   f"({unit}), got {v!r}")
        out.append(Parameter(name, a, b))
    return tuple(out)


def _workspace(t: dict, src: str) -> Workspace:
    _only(t, set(POSE) | {"combine", "search_points", "check_points", "orientations"},
          "workspace.", src)
    ranges = {}
    for axis in POSE:
        if axis in t:
            v, key = t[axis], f"workspace.{axis}"
            bound = 10.0 if axis in POSE[:3] else math.pi / 2
            if not (isinstance(v, list) and len(v) == 2 and all(_is_number(x) for x in v)
                    and -bound <= v[0] <= 0.0 <= v[1] <= bound and v[1] > v[0]):
                raise DesignInputError(f"{src}: {key}: need [low, high] with -{bound:g} <= low "
                                       f"<= 0 <= high <= {bound:g}, low < high "
                                       f"({'m' if axis in POSE[:3] else 'rad'}), got {v!r}")
            ranges[axis] = (float(v[0]), float(v[1]))
    combine = t.get("combine", "box")
    if combine not in ("box", "axes"):
        raise DesignInputError(f"{src}: workspace.combine: \"box\" or \"axes\", got {combine!r}")
    sp = _int(t, "search_points", 3, 2, 21, "workspace.", src)
    cp = _int(t, "check_points", 2 * sp - 1, sp + 1, 41, "workspace.", src)
    orient = t.get("orientations", [])
    if not (isinstance(orient, list) and len(orient) <= 64 and all(
            isinstance(o, list) and len(o) == 3 and all(_is_number(x) and abs(x) <= math.pi / 2
                                                        for x in o) for o in orient)):
        raise DesignInputError(f"{src}: workspace.orientations: a list of at most 64 "
                               f"[thx, thy, thz] (rad, each |.| <= pi/2)")
    if not ranges and not orient:
        raise DesignInputError(f"{src}: workspace: give at least one axis range or orientations")
    ws = Workspace(ranges, combine, sp, cp, tuple(tuple(float(x) for x in o) for o in orient))
    n = _count(ws, cp)
    if n > MAX_POSES:
        raise DesignInputError(f"{src}: workspace.check_points: the dense grid has {n} poses, "
                               f"more than {MAX_POSES}")
    return ws


def _count(ws: Workspace, points: int) -> int:
    k = len(ws.ranges)
    n = points ** k if ws.combine == "box" else 1 + k * (points - 1)
    return n * (1 + len(ws.orientations))


def _requirements(t: dict, src: str) -> Requirements:
    _only(t, {"first_resonance", "stiffness", "cond_limit", "base_cone", "platform_cone"},
          "requirements.", src)
    f = _number(t, "first_resonance", None, 0.0, 1e5, "requirements.", src, "Hz")
    k = t.get("stiffness", [0.0] * 6)
    if not (isinstance(k, list) and len(k) == 6 and all(_is_number(x) and 0 <= x <= 1e12
                                                         for x in k)):
        raise DesignInputError(f"{src}: requirements.stiffness: six numbers [x, y, z, thx, thy, "
                               f"thz] in [0, 1e12] (N/m, N m/rad; 0: no requirement), got {k!r}")
    cond = _number(t, "cond_limit", 100.0, 1.0, 1e10, "requirements.", src, "1")
    cones = [_number(t, c, None, 0.0, math.pi / 2, "requirements.", src, "rad")
             for c in ("base_cone", "platform_cone")]
    return Requirements(f if f else None, tuple(float(x) if x > 0 else None for x in k),
                        cond, *cones)


def with_search(spec: DesignSpec, **given) -> DesignSpec:
    """The spec with [search] keys replaced (command-line options: --population, --generations,
    --seed; None keeps the file's), checked as the file's are (DesignInputError naming the
    option)."""
    from dataclasses import asdict, replace

    t = asdict(spec.search)
    for key, value in given.items():
        if value is not None:
            t[key] = value
    try:
        search = _search(t, spec.source)
    except DesignInputError as exc:
        raise DesignInputError(str(exc).replace(f"{spec.source}: search.", "--")) from None
    return replace(spec, search=search)


def _search(t: dict, src: str) -> Search:
    _only(t, {"population", "generations", "seed", "reserve"}, "search.", src)
    return Search(_int(t, "population", 40, 4, MAX_POPULATION, "search.", src),
                  _int(t, "generations", 20, 1, MAX_GENERATIONS, "search.", src),
                  _int(t, "seed", 1, 0, 2**31 - 1, "search.", src),
                  _number(t, "reserve", 0.05, 0.0, 10.0, "search.", src, "1"))


def _table(data: dict, name: str, src: str, required: bool = False) -> dict:
    if name not in data:
        if required:
            raise DesignInputError(f"{src}: [{name}]: required table is missing")
        return {}
    if not isinstance(data[name], dict):
        raise DesignInputError(f"{src}: [{name}]: must be a table")
    return data[name]




def _string(t: dict, key: str, prefix: str, src: str) -> str:
    v = t.get(key)
    if not isinstance(v, str) or not v:
        raise DesignInputError(f"{src}: {prefix}{key}: required, a path (relative to the file)")
    return v

