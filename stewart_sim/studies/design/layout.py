"""The six joints from a few numbers, laid out as the shipped scenes are: joints in three pairs
about pair centres at 0, 120 and 240 deg, leg 2k+1 at centre_k - half angle and leg 2k+2 at
centre_k + half angle, on the base (radius, z = 0 in N) and on the platform (radius, at
platform_joint_z in C). scenes/micro_manipulator.toml is (0.10 m, 10 deg; 0.06 m, 50 deg,
z -0.01 m); scenes/motion_simulator.toml (2.2 m, 12 deg; 1.4 m, 48 deg, z -0.35 m). The layout
is the sweep's (stewart_sim.studies.sweep.joint_layout.joints), one implementation for both."""
from __future__ import annotations

import copy
from typing import Any

import numpy as np

from stewart_sim.studies.sweep.joint_layout import joints


def scene_dict(base: dict[str, Any], p: dict[str, float], payload: dict | None = None,
               cones: tuple[float | None, float | None] = (None, None),
               drive: dict[str, float] | None = None) -> dict[str, Any]:
    """The base scene with the candidate's geometry (the parameters `p` of spec.PARAMETERS:
    the base joints at base_joint_z in N, 0 when not given, home_height above them), leg
    stiffness, payload, joint cones and drive (a catalogue drive's [drive] table; None: the
    base's) in place (the base's [joints] axes dropped: they belong to its own legs; the
    default axes are the legs' directions at home)."""
    d = copy.deepcopy(base)
    g = d.setdefault("geometry", {})
    z0 = p.get("base_joint_z", 0.0)
    g["base_joints"] = _rounded(joints(p["base_radius"], p["base_half_angle"], z0))
    g["platform_joints"] = _rounded(joints(p["platform_radius"], p["platform_half_angle"],
                                           p["platform_joint_z"]))
    g["home"] = [0.0, 0.0, z0 + p["home_height"], 0.0, 0.0, 0.0]
    if drive is not None:
        d["drive"] = dict(drive)
    g["leg_min"] = p["leg_min"]
    g["leg_max"] = p["leg_min"] + p["stroke"]
    stiff = d.setdefault("stiffness", {})
    stiff["leg"] = p["leg_stiffness"]
    if payload is not None:
        d["payload"] = copy.deepcopy(payload)
    d.pop("joints", None)
    if cones[0] is not None or cones[1] is not None:
        d["joints"] = {k: v for k, v in zip(("base_cone", "platform_cone"), cones) if v is not None}
    return d


def _rounded(a: np.ndarray) -> list[list[float]]:
    # plain floats (a scene written from the dict reads back the same numbers)
    return [[float(v) for v in row] for row in a]
