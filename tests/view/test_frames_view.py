"""The 3D view draws the scene's [frames]: the pivot point as a sphere on the
platform and the user and tool frames as triads. The scene commands hold their objects; the
nodes' transforms put the pivot at x + R pivot, the tool triad at the tool frame's pose in N
as the core's frames.c computes it (stewart_fmu.frames.from_platform), and the user triad so
that it composed with the tool's pose in the user frame (again frames.c) gives the tool triad;
each triad axis runs from its frame's origin along that frame's axis."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest

from stewart_fmu import scene_from_dict
from stewart_fmu.frames import from_platform
from stewart_sim.view.geometry import (
    TRIAD,
    object_transforms,
    part_ends,
    rotation,
    triad_transforms,
    view_geometry,
)
from stewart_sim.view.html import live_view_html
from stewart_sim.view.meshcat_scene import scene_commands
from tests.helpers import scene_dict

PIVOT = [0.01, -0.02, 0.15]                      # m, in C
TOOL = [0.03, 0.01, 0.2, 0.1, -0.2, 0.3]         # pose in C
USER = [0.2, -0.1, 0.05, -0.05, 0.15, 0.4]       # pose in N
POSE_OFFSET = np.array([0.02, -0.01, 0.03, 0.05, -0.08, 0.12])
EXACT = 1e-12                                    # m: composition of a few 4x4s of O(1)


@pytest.fixture(scope="module")
def model():
    data = scene_dict("sim")
    data["frames"] = {"pivot": PIVOT, "tool": TOOL, "user": USER}
    return scene_from_dict(data)


def page_data(html: str) -> dict:
    return json.loads(re.search(r'<script type="application/json" id="view-data">(.*?)</script>',
                                html, re.S).group(1).replace("<\\/", "</"))


def paths(cmds, kind):
    return {c["path"] for c in cmds if c["type"] == kind}


def test_the_scene_holds_the_pivot_and_both_triads(model):
    g = view_geometry(model, controller=None)
    cmds = scene_commands(g, with_ghost=True)
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    assert objects["/stewart/frames/pivot"]["geometries"][0]["type"] == "SphereGeometry"
    for frame in ("user", "tool"):
        for axis in TRIAD:
            geo = objects[f"/stewart/frames/{frame}/{axis}"]["geometries"][0]
            assert geo["type"] == "CylinderGeometry"
            assert geo["height"] == g.frames["axis_length"] > 0
    moved = paths(cmds, "set_transform")
    assert {"/stewart/frames/pivot", "/stewart/frames/tool", "/stewart/frames/user"} <= moved
    # the triads' colours differ per axis
    colours = {objects[f"/stewart/frames/tool/{a}"]["materials"][0]["color"] for a in TRIAD}
    assert len(colours) == 3
    # not on the ghost: it shows the reference pose of the mechanism only
    assert not any(p.startswith("/ghost/frames") for p in objects)


def test_a_scene_without_frames_draws_none():
    g = view_geometry(scene_from_dict(scene_dict("sim")), controller=None)
    assert g.frames is None
    cmds = scene_commands(g, with_ghost=False)
    assert not any("/frames" in c["path"] for c in cmds)


def test_the_nodes_sit_where_the_core_puts_the_frames(model):
    g = view_geometry(model, controller=None)
    q = np.asarray(model.home) + POSE_OFFSET
    T = object_transforms(g, q)
    R = rotation(q)
    np.testing.assert_allclose(T["frames/pivot"][:3, 3], q[:3] + R @ PIVOT, atol=EXACT)
    np.testing.assert_allclose(T["frames/pivot"][:3, :3], np.eye(3))
    tool = from_platform(model, q, "tool")           # the tool frame's pose in N (frames.c)
    np.testing.assert_allclose(T["frames/tool"][:3, 3], tool[:3], atol=EXACT)
    np.testing.assert_allclose(T["frames/tool"][:3, :3], rotation(tool), atol=EXACT)
    in_user = from_platform(model, q, "user")        # the tool's pose in the user frame
    composed = T["frames/user"] @ np.block([[rotation(in_user), in_user[:3, None]],
                                            [np.zeros((1, 3)), np.ones((1, 1))]])
    np.testing.assert_allclose(composed, T["frames/tool"], atol=EXACT)
    # the user frame is fixed to the base: the same at home
    np.testing.assert_array_equal(T["frames/user"],
                                  object_transforms(g, model.home)["frames/user"])


def test_each_triad_axis_runs_from_the_origin_along_its_axis(model):
    g = view_geometry(model, controller=None)
    q = np.asarray(model.home) + POSE_OFFSET
    node = object_transforms(g, q)["frames/tool"]
    length = g.frames["axis_length"]
    for k, (axis, T) in enumerate(triad_transforms(length).items()):
        lo, hi = part_ends(node @ T, length)
        np.testing.assert_allclose(lo, node[:3, 3], atol=EXACT)
        np.testing.assert_allclose(hi, node[:3, 3] + length * node[:3, k], atol=EXACT)


def test_the_page_carries_the_frames(model):
    """The live page's embedded data: the geometry's frames (page.js places the nodes from
    them each frame) and the scene commands with the marks."""
    data = page_data(live_view_html(view_geometry(model, controller=None)))
    assert data["geometry"]["frames"]["pivot"] == PIVOT
    assert data["geometry"]["frames"]["tool"] == TOOL
    assert data["geometry"]["frames"]["user"] == USER
    assert {"/stewart/frames/pivot", "/stewart/frames/user/x",
            "/stewart/frames/tool/z"} <= paths(data["scene"], "set_object")
