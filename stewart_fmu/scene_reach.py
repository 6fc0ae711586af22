"""The scene's reach tables: [joints], [clearance] (with [[clearance.obstacles]]) and [frames],
read and checked key by key (bounds: stewart_table.h STEWART_REACH_SCENE), then the home pose
checked against the limits they declare (the engine, native/src/reach.c).

    [joints]
    base_cone = 0.5               # rad, in (0, pi/2)
    platform_cone = 0.5
    base_axes = [[x, y, z], ...]  # optional: six directions in N (default: each leg at home)
    platform_axes = [...]         # optional: six directions in C

    [clearance]
    leg_radius = 0.004            # m, > 0
    [[clearance.obstacles]]       # optional, at most 16
    shape = "box"                 # "box" (size), "cylinder" (radius, length), "sphere" (radius)
    body = "base"                 # "base": centre and angles in N; "platform": in C
    center = [0.0, 0.0, 0.02]
    angles = [0.0, 0.0, 0.0]      # optional: the shape's axes, as a pose's angles
    size = [0.04, 0.04, 0.04]     # box: edge lengths along its axes
    # radius = 0.01 / length = 0.05: a cylinder about its local z, a sphere

    [frames]
    pivot = [0.0, 0.0, 0.0]       # m, in C, each within 10 m
    user = [x, y, z, thx, thy, thz]   # optional: the user (work) frame's pose in N
    tool = [x, y, z, thx, thy, thz]   # optional: the tool frame's pose in C (default: the pivot)
    default = "platform"          # the frame poses are given in: platform, pivot, tool, user
"""
from __future__ import annotations

import re
from typing import Any, Mapping

import numpy as np

from . import table
from .native import core
from .reach_params import (BODIES, FRAME_NAMES, MAX_OBSTACLES, SHAPES, ClearanceParams,
                           FrameParams, JointParams, Obstacle)

REACH_TABLES = ("joints", "clearance", "frames")
_KEYS = {"joints": ({"base_cone", "platform_cone"}, {"base_axes", "platform_axes"}),
         "clearance": ({"leg_radius"}, {"obstacles"}),
         "frames": (set(), {"pivot", "user", "tool", "default"})}
# An obstacle's keys by shape: (required, optional), beside shape, body, center, angles.
_SHAPE_KEYS = {"box": {"size"}, "cylinder": {"radius", "length"}, "sphere": {"radius"}}


def generic_key(dotted: str) -> str:
    """The key whose bounds a key takes: an obstacle's without its index
    ('clearance.obstacles[2].radius' -> 'clearance.obstacles.radius')."""
    return re.sub(r"\[\d+\]", "", dotted)


def _table(v, data: Mapping[str, Any], name: str) -> Mapping[str, Any] | None:
    return v.table(data, name, keys=_KEYS[name])


def _directions(v, t: Mapping[str, Any], dotted: str) -> np.ndarray | None:
    if dotted.rsplit(".", 1)[-1] not in t:
        return None
    axes = v.vector(t, dotted, (6, 3))
    for i, row in enumerate(axes):
        if not np.linalg.norm(row) > 0.0:
            v.fail_key(dotted, f"row {i + 1} (leg {i + 1}) is a zero vector, not a direction")
    return axes


def joints(v, data: Mapping[str, Any]) -> JointParams | None:
    """[joints], or None when the scene has none."""
    t = _table(v, data, "joints")
    if t is None:
        return None
    return JointParams(v.number(t, "joints.base_cone"), v.number(t, "joints.platform_cone"),
                       _directions(v, t, "joints.base_axes"),
                       _directions(v, t, "joints.platform_axes"))


def _word(v, t: Mapping[str, Any], dotted: str, allowed) -> str:
    key = dotted.rsplit(".", 1)[-1]
    if key not in t:
        v.fail_key(dotted, "required key is missing")
    x = t[key]
    if not isinstance(x, str) or x not in allowed:
        v.fail_key(dotted, f"must be one of {sorted(allowed)}, got {x!r}")
    return x


def _obstacle(v, t: Any, k: int) -> Obstacle:
    where = f"clearance.obstacles[{k}]"
    if not isinstance(t, Mapping):
        v.fail_key(where, f"must be a table, got {type(t).__name__}")
    shape = _word(v, t, f"{where}.shape", SHAPES)
    body = _word(v, t, f"{where}.body", BODIES)
    need = _SHAPE_KEYS[shape]
    for key in sorted(set(t) - need - {"shape", "body", "center", "angles"}):
        v.fail_key(f"{where}.{key}", f"unknown key for a {shape} (allowed: "
                                     f"{sorted(need | {'shape', 'body', 'center', 'angles'})})")
    center = tuple(v.vector(t, f"{where}.center", 3))
    angles = tuple(v.vector(t, f"{where}.angles", 3, default=(0.0, 0.0, 0.0)))
    size = tuple(v.vector(t, f"{where}.size", 3)) if "size" in need else None
    radius = v.number(t, f"{where}.radius") if "radius" in need else None
    length = v.number(t, f"{where}.length") if "length" in need else None
    return Obstacle(shape, body, center, angles, size, radius, length)


def clearance(v, data: Mapping[str, Any]) -> ClearanceParams | None:
    """[clearance] and its obstacles, or None when the scene has none."""
    t = _table(v, data, "clearance")
    if t is None:
        return None
    radius = v.number(t, "clearance.leg_radius")
    obstacles = t.get("obstacles", [])
    if not isinstance(obstacles, list):
        v.fail_key("clearance.obstacles", "must be an array of tables ([[clearance.obstacles]])")
    if len(obstacles) > MAX_OBSTACLES:
        v.fail_key("clearance.obstacles",
                   f"at most {MAX_OBSTACLES} obstacles, got {len(obstacles)}")
    return ClearanceParams(radius, tuple(_obstacle(v, o, k) for k, o in enumerate(obstacles)))


def frames(v, data: Mapping[str, Any]) -> FrameParams | None:
    """[frames], or None when the scene has none."""
    t = _table(v, data, "frames")
    if t is None:
        return None
    pivot = tuple(v.vector(t, "frames.pivot", 3, default=(0.0, 0.0, 0.0)))
    user = tuple(v.vector(t, "frames.user", 6, default=(0.0,) * 6))
    tool = tuple(v.vector(t, "frames.tool", 6)) if "tool" in t else None
    default = _word(v, t, "frames.default", FRAME_NAMES) if "default" in t else "platform"
    return FrameParams(pivot, user, tool, default)


# The key a broken limit at home names: the table's key that sets the limit.
_LIMIT_KEYS = {"base_cone": "joints.base_cone", "platform_cone": "joints.platform_cone",
               "leg_clearance": "clearance.leg_radius"}


def check_home(v, model) -> None:
    """The home pose inside the limits of the reach tables the scene has (SceneError naming the
    key: the cone, the leg radius, the obstacle)."""
    if model.joints is None and model.clearance is None:
        return
    n = core.lib.STEWART_N_LIMITS
    margin, where = np.empty(n), np.empty(n, np.intc)
    ffi = core.ffi
    home = np.ascontiguousarray(model.home, dtype=float)
    core.lib.stewart_reach_margins(model.native.ptr, ffi.from_buffer(model.reach),
                                   ffi.from_buffer(home), ffi.NULL, ffi.NULL,
                                   ffi.from_buffer(margin), ffi.from_buffer("int[]", where))
    for lim in table.LIMITS:
        if lim.name not in (*_LIMIT_KEYS, "obstacle") or not margin[lim.index] < 0.0:
            continue
        w = int(where[lim.index])
        if lim.name == "obstacle":
            o, leg = divmod(w, 6)
            v.fail(f"clearance.obstacles[{o}]", f"touches leg {leg + 1} at the home pose "
                   f"(clearance {margin[lim.index]:.6g} m with the leg's radius)")
        what = f"legs {'-'.join(map(str, pair_legs(w)))}" if lim.kind == table.LIMIT_PAIR \
            else f"leg {w + 1}"
        v.fail(_LIMIT_KEYS[lim.name], f"the home pose violates the limit {lim.name} at {what} "
               f"(margin {margin[lim.index]:.6g} {lim.unit})")


def pair_legs(pair: int) -> tuple[int, int]:
    """Legs (1..6) of pair index 0..14 in the engine's order (1,2), (1,3) .. (5,6)."""
    k = 0
    for i in range(6):
        for j in range(i + 1, 6):
            if k == pair:
                return i + 1, j + 1
            k += 1
    raise ValueError(f"no pair {pair}")
