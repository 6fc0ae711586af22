"""What `stewart-sim modes` computes: the pose and the payload checked, the stiffness at the
pivot, the modes, and the map over a grid of poses (stewart_fmu.stiffness, the C core's
stiffness.c)."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stewart_fmu import table
from stewart_fmu.budget import SCENE_BYTES, InputFileError, read_input
from stewart_fmu.errors import SceneError, StewartError
from stewart_fmu.frames import to_platform
from stewart_fmu.kinematics import COND_LIMIT, inverse_kinematics
from stewart_fmu.model import Model, PayloadParams
from stewart_fmu.scene import scene_from_dict
from stewart_fmu.stiffness import (Modes, ModesMap, Stiffness, modes, modes_map, regular_poses,
                                   stiffness)

POSE = ("x", "y", "z", "thx", "thy", "thz")
N_MODES = 6     # the platform's six degrees of freedom
MAX_MAP = 1_000_000   # poses of one map (a 1000^2 slice)


class ModesInputError(StewartError, ValueError):
    """A command-line input of `modes` is at fault (the message names the option)."""


@dataclass(frozen=True)
class ModesResult:
    """The stiffness and the modes at one pose."""

    model: Model
    stiffness: Stiffness
    modes: Modes
    count: int          # the modes asked for (the first `count` of the six)


def parse_numbers(text: str, n: int, option: str) -> np.ndarray:
    """n comma-separated finite numbers (ModesInputError naming the option)."""
    parts = text.split(",")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise ModesInputError(f"{option}: not {n} comma-separated numbers: {text!r}") from None
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise ModesInputError(f"{option}: must be {n} finite comma-separated numbers, got {text!r}")
    return values


def check_pose(model: Model, q: np.ndarray, option: str = "--pose") -> None:
    """The pose within the stroke and away from singularities (ModesInputError saying which
    leg and which limit)."""
    kin = inverse_kinematics(model, q)
    for i, l in enumerate(kin.lengths):
        if model.leg_min is not None and l < model.leg_min:
            raise ModesInputError(f"{option}: leg {i + 1} is {l:.6g} m, below leg_min "
                                  f"{model.leg_min:g} m (outside the stroke)")
        if model.leg_max is not None and l > model.leg_max:
            raise ModesInputError(f"{option}: leg {i + 1} is {l:.6g} m, above leg_max "
                                  f"{model.leg_max:g} m (outside the stroke)")
    cond = float(np.asarray(kin.cond).ravel()[0])
    if not cond < COND_LIMIT:
        raise ModesInputError(f"{option}: the pose is singular (cond(J) = {cond:.3g} >= {COND_LIMIT:g})")
    if abs(math.cos(q[4])) < 1e-9:
        raise ModesInputError(f"{option}: thy = {q[4]!r} rad is at gimbal lock")


def payload_from(text: str, model: Model) -> PayloadParams:
    """--payload: a bare mass (kg: a point mass at C's origin), a TOML file (its [payload]
    table, or mass/com/inertia at its top level), or the keys inline ("mass = 50, com = [0, 0,
    0.3], inertia = [2, 2, 3]"); checked as the scene's [payload] (errors name payload.<key>)."""
    try:
        mass = float(text)
    except ValueError:
        mass = None
    if mass is not None:
        reason = table.bound_reason(table.ELASTIC_KEYS["payload.mass"], mass) if math.isfinite(mass) \
            else f"must be finite, got {mass}"
        if reason:
            raise SceneError("payload.mass", f"--payload {text}: {reason}")
        return PayloadParams(mass=mass, com=(0.0, 0.0, 0.0), inertia=(0.0, 0.0, 0.0))
    data = _payload_table(text)
    d = {"geometry": {"base_joints": model.base_joints.tolist(),
                      "platform_joints": model.platform_joints.tolist(), "home": model.home.tolist()},
         "platform": {"mass": model.platform_mass, "inertia": model.platform_inertia.tolist()},
         "payload": data}
    try:
        return scene_from_dict(d, source="--payload").payload
    except SceneError as exc:
        raise SceneError(exc.key, exc.reason, "--payload") from None


def _payload_table(text: str) -> dict:
    path = Path(text)
    if text.endswith(".toml") or path.is_file():
        try:
            raw = read_input(path, SCENE_BYTES).decode()
        except InputFileError as exc:
            raise ModesInputError(f"--payload: cannot read {text}: {exc.reason}") from None
        except UnicodeDecodeError:
            raise ModesInputError(f"--payload: {text} is not a text (TOML) file") from None
    else:
        raw = _inline_lines(text)
    try:
        data = tomllib.loads(raw)
    except tomllib.TOMLDecodeError as exc:
        raise ModesInputError(f"--payload: neither a mass, a TOML file nor inline keys: {exc}") from None
    table_ = data.get("payload", data)
    if not isinstance(table_, dict):
        raise ModesInputError("--payload: [payload] must be a table")
    return table_


def _inline_lines(text: str) -> str:
    """'mass = 5, com = [0, 0, 1], inertia = [1, 1, 1]' as TOML lines: split at the commas
    outside brackets."""
    out, depth = [], 0
    for ch in text:
        depth += ch == "["
        depth -= ch == "]"
        out.append("\n" if ch == "," and depth == 0 else ch)
    return "".join(out)


def with_payload(model: Model, payload: PayloadParams | None) -> Model:
    """The model with the given payload in place of the scene's (None: the scene's kept)."""
    return model if payload is None else replace(model, payload=payload)


def check_count(count: int) -> int:
    if not 1 <= count <= N_MODES:
        raise ModesInputError(f"--modes: the system has {N_MODES} modes (the platform's six degrees "
                              f"of freedom on its legs), asked for {count}")
    return count


def compute(model: Model, q: np.ndarray, pivot: np.ndarray, count: int = N_MODES) -> ModesResult:
    """The stiffness at the pivot and the modes at pose q, the inputs checked first."""
    if model.stiffness is None:
        raise SceneError("stiffness", "the scene has no [stiffness] table: the modes need each "
                         "leg's axial stiffness (leg = N/m)", model.source)
    check_count(count)
    check_pose(model, q)
    return ModesResult(model, stiffness(model, q, pivot), modes(model, q), count)


@dataclass(frozen=True)
class Grid:
    """A grid of poses: axes varied (pose component -> values), the others at the base pose."""

    axes: dict[str, np.ndarray]
    base: np.ndarray

    def poses(self) -> np.ndarray:
        names = list(self.axes)
        mesh = np.meshgrid(*(self.axes[n] for n in names), indexing="ij")
        Q = np.tile(self.base, (mesh[0].size, 1))
        for n, m in zip(names, mesh):
            Q[:, POSE.index(n)] = m.ravel()
        return Q


def parse_grid(text: str, base: np.ndarray) -> Grid:
    """--map 'x=-0.01:0.01:11,z=0.11:0.13:5': per pose component, start:stop:count (linspace)."""
    axes: dict[str, np.ndarray] = {}
    for part in text.split(","):
        name, _, spec = part.partition("=")
        name = name.strip()
        if name not in POSE or name in axes:
            raise ModesInputError(f"--map: {name!r} is not a pose component {POSE} (or repeated)")
        try:
            start, stop, count = spec.split(":")
            a, b, n = float(start), float(stop), int(count)
        except ValueError:
            raise ModesInputError(f"--map: {part!r} is not NAME=START:STOP:COUNT") from None
        if not (math.isfinite(a) and math.isfinite(b)) or not 1 <= n <= 1000:
            raise ModesInputError(f"--map: {part!r}: finite bounds and 1 <= COUNT <= 1000")
        axes[name] = np.linspace(a, b, n)
    grid = Grid(axes, base)
    if math.prod(len(v) for v in axes.values()) > MAX_MAP:
        raise ModesInputError(f"--map: more than {MAX_MAP} poses")
    return grid


@dataclass(frozen=True)
class MapResult:
    """The map over a grid: the poses inside the stroke and regular, their values."""

    poses: np.ndarray        # (N, 6) every pose of the grid (in the frame it was given in)
    inside: np.ndarray       # (N,) bool: within the stroke, regular
    values: ModesMap | None  # over poses[inside]


def compute_map(model: Model, grid: Grid, pivot: np.ndarray, frame: str = "platform") -> MapResult:
    """The lowest frequency and the weakest translational stiffness at each pose of the grid
    (given in `frame`: stewart_fmu.frames) within the stroke and away from singularities (the
    others are left out, marked)."""
    Q = grid.poses()
    P = to_platform(model, Q, frame)
    inside = regular_poses(model, P)
    values = modes_map(model, P[inside], pivot) if inside.any() else None
    return MapResult(Q, inside, values)
