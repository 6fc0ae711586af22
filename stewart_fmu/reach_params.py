"""The reach tables of a scene as the model holds them: [joints] (joint cones), [clearance] (leg
capsules and obstacles), [frames] (pivot point, user and tool frames), and their packed form
for the C engine (native/src/reach.c, the layout STEWART_REACH_PARAMS of stewart_table.h).

The scene reader (stewart_fmu/scene_reach.py) checks each key; the model packs them once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import table
from .native import core
from .rotations import euler_motion

SHAPES = {"sphere": core.lib.STEWART_SHAPE_SPHERE, "box": core.lib.STEWART_SHAPE_BOX,
          "cylinder": core.lib.STEWART_SHAPE_CYLINDER}
BODIES = {"base": core.lib.STEWART_BODY_BASE, "platform": core.lib.STEWART_BODY_PLATFORM}
MAX_OBSTACLES = core.lib.STEWART_MAX_OBSTACLES
OBSTACLE_SIZE = core.lib.STEWART_OBSTACLE_SIZE
# The frames a pose may be given in (stewart_fmu/frames.py): C in N (the contract's pose), the
# pivot point in N, the tool frame in N, the tool frame in the user frame.
FRAME_NAMES = ("platform", "pivot", "tool", "user")
COND_LIMIT = float(core.lib.STEWART_REACH_COND_LIMIT)


@dataclass(frozen=True)
class JointParams:
    """[joints]: the cones (rad) and the joints' axes (six unit rows each; None: each leg's
    direction at home)."""

    base_cone: float
    platform_cone: float
    base_axes: np.ndarray | None = None       # (6, 3) in N
    platform_axes: np.ndarray | None = None   # (6, 3) in C


@dataclass(frozen=True)
class Obstacle:
    """A box, cylinder or sphere fixed to the base (centre and angles in N) or to the platform
    (in C). Box: size (3 edge lengths, local axes); cylinder: radius and length along local z;
    sphere: radius."""

    shape: str
    body: str
    center: tuple[float, float, float]
    angles: tuple[float, float, float] = (0.0, 0.0, 0.0)
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None

    def half_extents(self) -> tuple[float, float, float]:
        if self.shape == "box":
            return tuple(0.5 * s for s in self.size)
        if self.shape == "cylinder":
            return (self.radius, self.radius, 0.5 * self.length)
        return (self.radius, self.radius, self.radius)


@dataclass(frozen=True)
class ClearanceParams:
    """[clearance]: each leg a capsule of leg_radius about its joints' segment; obstacles."""

    leg_radius: float
    obstacles: tuple[Obstacle, ...] = ()


@dataclass(frozen=True)
class FrameParams:
    """[frames]: the pivot point (in C), the user frame (a pose in N), the tool frame (a pose in
    C; None: at the pivot, axes of C) and the frame poses are given in by default."""

    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    user: tuple[float, ...] = (0.0,) * 6
    tool: tuple[float, ...] | None = None
    default: str = "platform"

    @property
    def tool_pose(self) -> np.ndarray:
        return np.array(self.tool if self.tool is not None else (*self.pivot, 0.0, 0.0, 0.0))


def rotation(angles) -> np.ndarray:
    """R = Rz Ry Rx of three angles, row-major (9,) (rotations.euler_motion, the numpy form of
    the core's)."""
    pose, z = np.zeros((1, 6)), np.zeros((1, 6))
    pose[0, 3:] = angles
    R = np.empty((1, 3, 3))
    euler_motion(pose, z, z, R, np.empty((1, 3)), np.empty((1, 3)))
    return R[0].ravel()


def _unit_rows(axes: np.ndarray) -> np.ndarray:
    return axes / np.linalg.norm(axes, axis=1)[:, None]


def pack_reach(params: np.ndarray, home: np.ndarray, joints: JointParams | None,
               clearance: ClearanceParams | None) -> np.ndarray:
    """The packed reach vector (read-only): the tables' values, the default cond(J) limit, and
    the drives' bounds inf (not limited: reach.Engine sets them)."""
    r = np.zeros(table.N_REACH)
    off = table.reach_offset
    if joints is not None:
        base, top = np.empty(18), np.empty(18)
        core.lib.stewart_leg_axes(core.ffi.from_buffer(np.ascontiguousarray(params)),
                                  core.ffi.from_buffer(np.ascontiguousarray(home, dtype=float)),
                                  core.ffi.from_buffer(base), core.ffi.from_buffer(top))
        if joints.base_axes is not None:
            base = _unit_rows(np.asarray(joints.base_axes, dtype=float)).ravel()
        if joints.platform_axes is not None:
            top = _unit_rows(np.asarray(joints.platform_axes, dtype=float)).ravel()
        r[off("HAS_JOINTS")] = 1.0
        r[off("BASE_CONE")], r[off("PLATFORM_CONE")] = joints.base_cone, joints.platform_cone
        r[off("BASE_AXES"):off("BASE_AXES") + 18] = base
        r[off("PLATFORM_AXES"):off("PLATFORM_AXES") + 18] = top
    if clearance is not None:
        r[off("HAS_CLEARANCE")] = 1.0
        r[off("LEG_RADIUS")] = clearance.leg_radius
        r[off("N_OBSTACLES")] = len(clearance.obstacles)
        for k, o in enumerate(clearance.obstacles):
            at = off("OBSTACLES") + OBSTACLE_SIZE * k
            r[at:at + OBSTACLE_SIZE] = (SHAPES[o.shape], BODIES[o.body], *o.center,
                                        *rotation(o.angles), *o.half_extents())
    r[off("COND_LIMIT")] = COND_LIMIT
    for name in ("SPEED", "ACCELERATION", "FORCE"):
        r[off(name)] = np.inf
    r.flags.writeable = False
    return r
