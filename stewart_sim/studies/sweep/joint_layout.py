"""The joints as a sweep varies them: pairs on two circles (the usual hexapod layout, the
shipped scenes' own). Joint i (0..5) lies at the angle 120 deg floor(i / 2) -+ the half-angle
(minus for even i, plus for odd i), on the base at its radius and half-angle, on the platform at its
own; each joint keeps its z. The axes pairs.base_radius (m),
pairs.base_half_angle (deg), pairs.platform_radius (m), pairs.platform_half_angle (deg) rewrite
geometry.base_joints or geometry.platform_joints; the one a point does not set keeps the
scene's. A scene whose joints are not so laid out cannot take these axes (SceneError).
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from stewart_fmu.errors import SceneError

LAYOUT_KEYS = {"pairs.base_radius": "m", "pairs.base_half_angle": "deg",
               "pairs.platform_radius": "m", "pairs.platform_half_angle": "deg"}
JOINTS = {"base": "geometry.base_joints", "platform": "geometry.platform_joints"}
FIT = 1e-5    # m: a scene's joints within this of the layout follow it (its files' 6 digits)


PAIR_CENTRES = np.radians([0.0, 120.0, 240.0])


def joint_angles(half_angle: float) -> np.ndarray:
    """The six joints' azimuths (rad), legs 1..6: centre_k - half_angle, centre_k + half_angle."""
    return np.column_stack([PAIR_CENTRES - half_angle, PAIR_CENTRES + half_angle]).ravel()


def joints(radius: float, half_angle: float, z=0.0) -> np.ndarray:
    """Six joints (6, 3) on a circle of `radius` in pairs of `half_angle` (rad), at height z
    (one for all, or one per joint)."""
    a = joint_angles(half_angle)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.broadcast_to(z, (6,))])


def circle_joints(radius: float, angle_deg: float, z: np.ndarray) -> np.ndarray:
    """(6, 3): the layout's joints at `radius`, pairs -+ `angle_deg` about 0, 120, 240 deg."""
    return joints(radius, math.radians(angle_deg), z)


def scene_layout(joints: np.ndarray, key: str) -> tuple[float, float]:
    """The radius and half-angle (deg) of a scene's joints; SceneError naming `key` when they
    are not so laid out."""
    radius = float(np.hypot(*joints[1, :2]))
    angle = math.degrees(math.atan2(joints[1, 1], joints[1, 0]))
    if not np.allclose(circle_joints(radius, angle, joints[:, 2]), joints, rtol=0.0, atol=FIT):
        raise SceneError(key, "the joints are not pairs at one radius about 0, 120 and 240 deg: "
                              "the sweep's pairs.* axes cannot vary them")
    return radius, angle


def apply_layout(data: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """The scene dict with the joints the pairs.* values set (a copy of [geometry]; SceneError
    for a radius not above 0 or a half-angle outside (0, 60) deg)."""
    geometry = dict(data["geometry"])
    for side, key in JOINTS.items():
        r_key, a_key = f"pairs.{side}_radius", f"pairs.{side}_half_angle"
        if r_key not in values and a_key not in values:
            continue
        joints = np.asarray(geometry[f"{side}_joints"], dtype=float)
        radius, angle = scene_layout(joints, key)
        radius, angle = float(values.get(r_key, radius)), float(values.get(a_key, angle))
        if not radius > 0:
            raise SceneError(r_key, f"must be > 0 m, got {radius!r}")
        if not 0 < angle < 60:
            raise SceneError(a_key, f"must lie within (0, 60) deg, got {angle!r}")
        geometry[f"{side}_joints"] = circle_joints(radius, angle, joints[:, 2]).tolist()
    return {**data, "geometry": geometry}
