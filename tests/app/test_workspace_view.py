"""`workspace --map` writes DIR/view.html (studies.workspace.map_view): the mechanism at the
map's start pose and the constant-orientation workspace as a closed triangle mesh
(studies.workspace.map_surface). Decoded from the page and checked here against the map.csv
written beside it, with the test's own edge count and divergence-theorem volume: every edge
bounds exactly two triangles, each way once (closed and consistently oriented); the volume the
mesh encloses is the map's to within what the page's float32 positions can move it; every vertex
is a grid corner (a cell's side) at a run's end, or a midpoint on the side of a cell whose run
holds it. A coarser drawing grid (1 column in k) keeps those claims for the columns it draws.
--no-view leaves the page out; the page draws the surface in a browser without errors."""
from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from stewart_sim import cli
from stewart_sim.studies.workspace.map_surface import surface
from stewart_sim.studies.workspace.maps import WorkspaceMap
from tests.app.test_modes_view import page_data
from tests.helpers import ROOT

MICRO = ROOT / "scenes" / "micro_manipulator.toml"
F32 = np.float32
EPS32 = float(np.finfo(F32).eps)


@pytest.fixture(scope="module")
def mapped(tmp_path_factory):
    out = tmp_path_factory.mktemp("map-view") / "m"
    assert cli.main(["workspace", str(MICRO), "--map", "--out", str(out)]) == 0
    with (out / "map.csv").open(newline="") as fh:
        runs = np.array([[float(r[c]) for c in ("x", "y", "z_low", "z_high")]
                         for r in csv.DictReader(fh)])
    return out, runs, page_data((out / "view.html").read_text(encoding="utf-8"))


def surface_mesh(data: dict, path: str = "/workspace/surface") -> tuple[np.ndarray, np.ndarray,
                                                                       np.ndarray]:
    """The page's mesh at `path`: positions (V, 3) float32, normals (V, 3), triangles (T, 3)."""
    (cmd,) = [c for c in data["scene"] if c["type"] == "set_object" and c["path"] == path]
    obj = cmd["object"]
    assert obj["object"]["type"] == "Mesh"
    assert obj["materials"][0]["transparent"] and obj["materials"][0]["opacity"] < 1
    d = obj["geometries"][0]["data"]
    pos = np.array(d["attributes"]["position"]["array"], dtype=F32).reshape(-1, 3)
    normals = np.array(d["attributes"]["normal"]["array"]).reshape(-1, 3)
    tris = np.array(d["index"]["array"], dtype=np.int64).reshape(-1, 3)
    return pos, normals, tris


def assert_closed(tris: np.ndarray) -> None:
    directed = np.vstack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    _, once = np.unique(directed, axis=0, return_counts=True)
    assert np.all(once == 1)                     # no directed edge twice: one orientation
    _, both = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(both == 2)                     # every edge bounds exactly two triangles


def volume_and_area(v: np.ndarray, tris: np.ndarray) -> tuple[float, float]:
    """Divergence theorem: the flux of x/3 through the triangles (about the centroid)."""
    p = v[tris] - v.mean(axis=0)
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    vol = np.sum(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2]))) / 6
    return float(vol), float(np.sum(np.linalg.norm(cross, axis=1)) / 2)


def assert_vertices_on_runs(v: np.ndarray, runs: np.ndarray, step: float) -> None:
    """Every vertex at a grid corner of the drawing (a side of a drawn cell), at a run's end
    or inside a run of a cell touching that corner (a midpoint keeping two cells apart)."""
    ulp = np.abs(v).max() * EPS32
    sides = np.r_[runs[:, 0] - step / 2, runs[:, 0] + step / 2], \
        np.r_[runs[:, 1] - step / 2, runs[:, 1] + step / 2]
    for axis in (0, 1):
        s = np.unique(sides[axis])
        near = np.abs(v[:, axis, None] - s[None, :]).min(axis=1)
        assert near.max() <= ulp
    ends = set(runs[:, 2:].astype(F32).ravel().tolist())
    mid = np.array([z not in ends for z in v[:, 2].tolist()])
    for x, y, z in v[mid].astype(float):
        touching = (np.abs(np.abs(runs[:, 0] - x) - step / 2) <= ulp) \
            & (np.abs(np.abs(runs[:, 1] - y) - step / 2) <= ulp)
        assert np.any(touching & (runs[:, 2] < z) & (z < runs[:, 3]))


def test_the_surface_is_closed_and_encloses_the_maps_volume(mapped):
    out, runs, data = mapped
    pos, normals, tris = surface_mesh(data)
    assert_closed(tris)
    h = float(np.min(np.diff(np.unique(runs[:, 0]))))
    volume = np.sum(runs[:, 3] - runs[:, 2]) * h * h
    # the page's volume from its float32 positions: each within half a float32 step of the
    # exact one, so the volume moves by at most the area times that step
    vol, area = volume_and_area(pos.astype(float), tris)
    bound = area * 0.5 * EPS32 * float(np.abs(pos).max()) + 1e-12 * volume
    assert abs(vol - volume) <= bound, (vol, volume, bound)
    assert vol > 0.002                            # 2.66 litres, outward normals
    text = (out / "view.html").read_text(encoding="utf-8")
    title = re.search(r"<title>(.*?)</title>", text, re.S).group(1)
    assert f"workspace {volume * 1e3:.4g} l" in title
    assert_vertices_on_runs(pos, runs, h)
    # the shading normals: unit, and on the outer side of the triangles they shade (all but a
    # few thin walls between cells touching along an edge, where the mean turns: 59 of 182,440)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=3e-3)
    p = pos.astype(float)[tris]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    dots = np.einsum("ij,ij->i", normals[tris].sum(axis=1), face)
    assert np.mean(dots > 0) > 0.999


def test_a_coarser_drawing_keeps_its_columns_closed_and_exact(mapped):
    _, runs, _ = mapped
    h = float(np.min(np.diff(np.unique(runs[:, 0]))))
    lo = np.r_[runs[:, 0].min() - h / 2, runs[:, 1].min() - h / 2, 0.0]
    m = WorkspaceMap(np.zeros(3), "platform", h, runs, 0.0, lo, lo, 0.0)
    s = surface(m, 3)
    assert_closed(s.triangles)
    cell = np.rint((runs[:, :2] - lo[:2]) / h - 0.5).astype(int)
    drawn = runs[np.all(cell % 3 == 1, axis=1)]
    assert s.columns == len(np.unique(drawn[:, :2], axis=0)) > 100
    vol, area = volume_and_area(s.vertices, s.triangles)
    want = np.sum(drawn[:, 3] - drawn[:, 2]) * (3 * h) ** 2
    assert abs(vol - want) <= 1e-12 * want
    assert_vertices_on_runs(s.vertices.astype(F32), drawn, 3 * h)


def test_no_view_leaves_the_page_out(tmp_path):
    out = tmp_path / "m"
    assert cli.main(["workspace", str(MICRO), "--map", "--out", str(out), "--resolution",
                     "0.012", "--no-view"]) == 0
    shown = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert shown == ["map.csv", "slices.png", "tilt.csv", "tilt.png"]


def test_the_page_draws_the_surface(browser, mapped):
    from tests.browser import canvas_pixels, open_view

    out, _, data = mapped
    _, _, tris = surface_mesh(data)
    page = open_view(browser, out / "view.html")
    try:
        assert page.errors == []
        got = page.evaluate("""() => {
            const out = [];
            window.stewartView.viewer.scene_tree.find(["workspace", "surface"]).object
                .traverse(o => { if (o.isMesh) out.push([o.geometry.index.count,
                                                         !!o.geometry.attributes.normal]); });
            return out; }""")
        assert got == [[3 * len(tris), True]]
        shown = canvas_pixels(page)
        page.evaluate("""() => window.stewartView.viewer.handle_command(
            {type: "set_property", path: "/workspace", property: "visible", value: false})""")
        hidden = canvas_pixels(page)
        changed = np.any(shown.astype(int) != hidden.astype(int), axis=2)
        assert changed.mean() > 1e-2
        assert page.errors == []
    finally:
        page.close()


def _winding(v: np.ndarray, tris: np.ndarray, at: np.ndarray) -> float:
    """The mesh's winding number about `at` (its triangles' solid angles over 4 pi,
    Van Oosterom and Strackee): 1 inside a closed outward mesh, 0 outside."""
    a, b, c = (v[tris[:, k]] - at for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2 * np.arctan2(num, den)) / (4 * np.pi))


def test_a_map_in_a_user_frame_is_drawn_where_c_goes(tmp_path):
    """In a user frame rotated and shifted from N, the surface is drawn in N about C's
    positions: closed, the map's volume (a rigid motion keeps it), C's home inside, and the
    user frame's coordinates of C's home (where a surface left in the frame's coordinates would
    sit) outside."""
    from stewart_fmu import load_scene
    from stewart_fmu.frames import from_platform
    from tests.app.test_frame_option import FRAMES

    scene = tmp_path / "framed.toml"
    scene.write_text(MICRO.read_text(encoding="utf-8") + FRAMES, encoding="utf-8")
    out = tmp_path / "m"
    assert cli.main(["workspace", str(scene), "--map", "--out", str(out), "--frame", "user",
                     "--resolution", "0.008"]) == 0
    with (out / "map.csv").open(newline="") as fh:
        runs = np.array([[float(r[c]) for c in ("z_low", "z_high")] for r in csv.DictReader(fh)])
    pos, _, tris = surface_mesh(page_data((out / "view.html").read_text(encoding="utf-8")))
    assert_closed(tris)
    volume = np.sum(runs[:, 1] - runs[:, 0]) * 0.008 ** 2
    vol, area = volume_and_area(pos.astype(float), tris)
    assert abs(vol - volume) <= area * 0.5 * EPS32 * float(np.abs(pos).max()) + 1e-12 * volume
    model = load_scene(scene)
    home = np.asarray(model.home, dtype=float)
    assert _winding(pos.astype(float), tris, home[:3]) == pytest.approx(1, abs=1e-6)
    in_frame = from_platform(model, home, "user")[:3]
    assert np.linalg.norm(in_frame - home[:3]) > 0.2
    assert _winding(pos.astype(float), tris, in_frame) == pytest.approx(0, abs=1e-6)
