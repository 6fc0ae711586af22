"""`stewart-sim design` writes DIR/view.html with its result set (studies.design.workspace_view):
the chosen design at home, its constant-orientation workspace drawn as the workspace engine's
map of the written best.toml (the closed surface `workspace --map` draws: every run's two ends,
a wall on each side run's open side, the map's volume enclosed), the dense
check's required poses at their positions, coloured by the least relative margin the engine
gives there (computed here from the limits' margins and the requirement's scales), and a frame
for home and each required pose. --no-view leaves it out; a view that fails leaves no result
set; the page draws the objects in a browser without errors."""
from __future__ import annotations

import base64
import re
import subprocess
import sys

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu.reach import Engine
from stewart_sim.studies.design import spec as S
from stewart_sim.studies.design.candidate import workspace_poses
from stewart_sim.studies.design.workspace_view import GOOD, MAP_STEPS, OUT, SHORT
from stewart_sim.studies.workspace.maps import constant_orientation
from tests.app.test_design import EXAMPLE, REDUCED, cli
from tests.app.test_modes_view import page_data
from tests.app.test_workspace_view import (
    EPS32,
    assert_closed,
    assert_vertices_on_runs,
    surface_mesh,
    volume_and_area,
)

F32 = np.float32


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    out = tmp_path_factory.mktemp("design-view") / "d"
    r = cli("design", EXAMPLE, "--out", out, *REDUCED, "--workers", "2",
            env={"OPENBLAS_NUM_THREADS": "1"})
    assert r.returncode == 0, r.stderr
    assert f"{out}/view.html (chosen candidate" in r.stdout
    return out, page_data((out / "view.html").read_text(encoding="utf-8"))


def _object(data: dict, path: str) -> dict:
    (cmd,) = [c for c in data["scene"] if c["type"] == "set_object" and c["path"] == path]
    return cmd["object"]


def _attribute(obj: dict, name: str) -> np.ndarray:
    a = obj["geometries"][0]["data"]["attributes"][name]
    assert a["type"] == "Float32Array" and a["itemSize"] == 3
    return np.array(a["array"], dtype=F32).reshape(-1, 3)


def _frames(data: dict, key: str, cols: int) -> np.ndarray:
    return np.frombuffer(base64.b64decode(data["frames"][key]), dtype="<f4").reshape(-1, cols)


def test_the_boundary_drawn_is_the_maps_of_the_written_design(designed):
    out, data = designed
    spec = S.load(EXAMPLE)
    model = load_scene(out / "best.toml")
    eng = Engine(model, None, spec.requirements.cond_limit)
    m = constant_orientation(eng, np.asarray(model.home, dtype=float), "platform",
                             model.characteristic_length / MAP_STEPS)
    runs = m.runs
    assert len(runs) > 100
    # the surface of `workspace --map` (tests/app/test_workspace_view.py): closed, every vertex
    # on a cell's side at a run's end of this map, enclosing its volume
    pos, _, tris = surface_mesh(data, "/design/workspace/surface")
    assert_closed(tris)
    assert_vertices_on_runs(pos, runs, m.h)
    vol, area = volume_and_area(pos.astype(float), tris)
    assert abs(vol - m.volume) <= area * 0.5 * EPS32 * float(np.abs(pos).max()) + 1e-12 * m.volume
    # each run's two ends are drawn: a vertex at each corner of its cell at z_low and z_high
    drawn = {tuple(v) for v in pos.tolist()}
    for dx, dy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        for z in (2, 3):
            corner = np.column_stack([runs[:, 0] + dx * m.h / 2, runs[:, 1] + dy * m.h / 2,
                                      runs[:, z]]).astype(F32)
            assert all(tuple(c) in drawn for c in corner.tolist())
    # the columns at the rim of the map's x-y extent are side columns: a wall on the outer
    # side of each, over its whole run (upright triangles at that side from z_low to z_high)
    v = pos.astype(float)[tris]
    ulp = float(np.abs(pos).max()) * EPS32
    upright = np.abs(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])[:, 2]) <= ulp * m.h
    rims = 0
    for axis, sign in ((0, -1), (0, 1), (1, -1), (1, 1)):
        edge = runs[:, axis].min() if sign < 0 else runs[:, axis].max()
        side = edge + sign * m.h / 2
        wall = v[upright & np.all(np.abs(v[:, :, axis] - side) <= ulp, axis=1)]
        other = 1 - axis
        for r in runs[runs[:, axis] == edge]:
            near = wall[np.all(np.abs(wall[:, :, other] - r[other]) <= m.h / 2 + ulp, axis=1)
                        & np.all((wall[:, :, 2] >= F32(r[2])) & (wall[:, :, 2] <= F32(r[3])),
                                 axis=1)]
            assert near[:, :, 2].min() == F32(r[2]) and near[:, :, 2].max() == F32(r[3])
            rims += 1
    assert rims >= 4
    assert f"workspace ({m.volume * 1e3:.4g} l, blue)" in _title(out)


def _title(out) -> str:
    return re.search(r"<title>(.*?)</title>", (out / "view.html").read_text(encoding="utf-8"),
                     re.S).group(1)


def test_the_required_poses_are_the_specs_coloured_by_the_engines_margin(designed):
    out, data = designed
    spec = S.load(EXAMPLE)
    model = load_scene(out / "best.toml")
    home = np.asarray(model.home, dtype=float)
    Q = workspace_poses(spec.workspace, home, spec.workspace.check_points)
    req = _object(data, "/design/required")
    assert np.array_equal(_attribute(req, "position"), Q[:, :3].astype(F32))
    # the least relative margin over the engine's limits, each over its scale
    r = spec.requirements
    stroke = model.leg_max - model.leg_min
    scale = {"stroke_min": stroke, "stroke_max": stroke, "base_cone": r.base_cone,
             "platform_cone": r.platform_cone, "cond": r.cond_limit}
    eng = Engine(model, None, r.cond_limit)
    res = eng.check(Q)
    assert {lim.name for lim in eng.present()} == set(scale)
    least = np.min([res[name] / s for name, s in scale.items()], axis=0)
    want = np.where(least[:, None] < 0, OUT, np.where(least[:, None] < spec.search.reserve,
                                                      SHORT, GOOD)).astype(F32)
    assert np.array_equal(_attribute(req, "color"), want)
    assert np.all(least >= 0)            # the chosen design passed the dense check
    # frames: home, then each required pose; the title names the chosen candidate
    q = _frames(data, "q", 6)
    assert np.array_equal(q, np.vstack([home, Q]).astype(F32))
    chosen = re.search(r"Chosen: candidate (\d+)", (out / "summary.md").read_text()).group(1)
    assert _title(out).startswith(f"chosen candidate {chosen}: workspace (")
    assert f"{len(Q)} required poses" in _title(out)


def test_no_view_and_a_failing_view_leave_the_set_as_it_should_be(tmp_path):
    plain = tmp_path / "plain"
    r = cli("design", EXAMPLE, "--out", plain, "--population", "8", "--generations", "2",
            "--no-view", "--workers", "1")
    assert r.returncode in (0, 3), r.stderr
    assert (plain / "summary.md").is_file() and not (plain / "view.html").exists()
    failed = tmp_path / "failed"
    script = ("import sys\n"
              "from stewart_fmu.errors import StewartError\n"
              "import stewart_sim.studies.design.workspace_view as v\n"
              "def broken(*a, **k):\n"
              "    raise StewartError('view: broken on purpose')\n"
              "v.design_view = broken\n"
              "from stewart_sim import cli\n"
              f"sys.exit(cli.main(['design', {str(EXAMPLE)!r}, '--out', {str(failed)!r}, "
              "'--population', '8', '--generations', '2', '--workers', '1']))\n")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 2 and "broken on purpose" in r.stderr
    # no result set: the search's checkpoint alone (what --resume would continue from)
    assert sorted(p.name for p in failed.iterdir()) == ["design-checkpoint.npz"]


def test_the_page_draws_the_workspace_and_the_poses(browser, designed):
    from tests.browser import canvas_pixels, open_view

    out, data = designed
    page = open_view(browser, out / "view.html")
    try:
        assert page.errors == []
        counts = page.evaluate("""() => {
            const v = window.stewartView.viewer, out = {};
            for (const p of [["design", "workspace", "surface"], ["design", "required"]]) {
                let n = 0, kind = null;
                v.scene_tree.find(p).object.traverse(o => {
                    if (o.isPoints || o.isMesh) {
                        n += o.isMesh ? o.geometry.index.count
                                      : o.geometry.attributes.position.count;
                        kind = o.type; }
                });
                out[p.join("/")] = [kind, n];
            }
            return out; }""")
        _, _, tris = surface_mesh(data, "/design/workspace/surface")
        req = len(_attribute(_object(data, "/design/required"), "position"))
        assert counts == {"design/workspace/surface": ["Mesh", 3 * len(tris)],
                          "design/required": ["Points", req]}
        shown = canvas_pixels(page)
        page.evaluate("""() => window.stewartView.viewer.handle_command(
            {type: "set_property", path: "/design", property: "visible", value: false})""")
        hidden = canvas_pixels(page)
        # the workspace and the poses cover part of the picture: hiding them changes it
        changed = np.any(shown.astype(int) != hidden.astype(int), axis=2)
        assert changed.mean() > 1e-3
        assert page.errors == []
    finally:
        page.close()
