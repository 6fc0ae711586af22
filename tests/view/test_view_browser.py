"""The written views as a person sees them: opened in headless Chromium (tests/browser.py), the
scene drawn (not a blank canvas), the platform moving between two times of a run, every object
where stewart_sim.view.geometry puts it, the legs' colours following their forces, the marks,
the controls, and the live page drawing the frames a URL serves."""
from __future__ import annotations

import dataclasses
import json
import threading
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.moves import RUN_MOVE, run_reference
from stewart_fmu import scene_from_dict
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.scene.load import scene_of
from stewart_sim.view.colours import force_colours, nice_ceiling
from stewart_sim.view.data import view_data
from stewart_sim.view.geometry import TRIAD, object_transforms, triad_transforms, view_geometry
from stewart_sim.view.html import live_view_html, write_view
from stewart_sim.view.sources import run_table_view
from tests.browser import canvas_pixels, open_view, settle
from tests.helpers import level_model, scene_dict

DURATION = 1.0   # s of closed loop: out (0.3 s), hold, back, hold


@pytest.fixture(scope="module")
def run_view(micro_model, tmp_path_factory):
    """A closed-loop run of the micro-manipulator (the `run` reference) and its view file."""
    config = controller_config(micro_model)
    result = run_closed_loop(micro_model, config, run_reference(micro_model, config, DURATION))
    view = run_table_view(micro_model, result.table, controller=config, title="test run",
                          source="run.csv")
    path = tmp_path_factory.mktemp("view") / "view.html"
    write_view(path, view)
    return view, path


@pytest.fixture(scope="module")
def micro_model():
    """The full micro-manipulator (module scope: the run above is made once)."""
    return level_model("micro", "full")


def _command(page, cmd: dict) -> None:
    page.evaluate("c => window.stewartView.viewer.handle_command(c)", cmd)


def platform_mask(page) -> np.ndarray:
    """The pixels the platform covers: the canvas with it, less the canvas without it."""
    shown = canvas_pixels(page).astype(int)
    _command(page, {"type": "set_property", "path": "/stewart/platform", "property": "visible",
                    "value": False})
    hidden = canvas_pixels(page).astype(int)
    _command(page, {"type": "set_property", "path": "/stewart/platform", "property": "visible",
                    "value": True})
    return np.max(np.abs(shown - hidden), axis=2) > 24


def world_matrices(page, keys) -> dict[str, np.ndarray]:
    """Each object's matrix in N as the viewer holds it (three.js, column by column): its
    world matrix relative to meshcat's scene root (which turns z-up N into three.js' y-up)."""
    raw = page.evaluate("""keys => {
        const v = window.stewartView.viewer, T = MeshCat.THREE;
        v.scene.updateMatrixWorld(true);
        const root = new T.Matrix4().copy(v.scene.matrixWorld).invert();
        const out = {};
        for (const k of keys) out[k] = Array.from(new T.Matrix4().multiplyMatrices(
            root, v.scene_tree.find(["stewart", ...k.split("/")]).object.matrixWorld).elements);
        return out;
    }""", list(keys))
    return {k: np.array(v).reshape(4, 4).T for k, v in raw.items()}


def show(page, k: int) -> None:
    page.evaluate("k => window.stewartView.show(k)", k)
    settle(page)


def test_platform_drawn_and_moving(browser, run_view, micro_model):
    view, path = run_view
    page = open_view(browser, path)
    try:
        assert page.errors == []
        k_goal = int(np.argmin(np.abs(view.t - RUN_MOVE * DURATION)))   # end of the move out
        show(page, 0)
        first = canvas_pixels(page)
        # not a blank canvas: the scene's pixels vary, and the platform covers a patch of them
        assert first.std() > 20
        mask0 = platform_mask(page)
        assert mask0.sum() > 5000, f"platform covers {mask0.sum()} pixels"
        show(page, k_goal)
        mask1 = platform_mask(page)
        assert mask1.sum() > 5000
        # it moved: the goal pose is 17.5 mm up and across, 0.1 rad about each axis
        ys0, xs0 = np.nonzero(mask0)
        ys1, xs1 = np.nonzero(mask1)
        shift = np.hypot(xs1.mean() - xs0.mean(), ys1.mean() - ys0.mean())
        overlap = (mask0 & mask1).sum() / (mask0 | mask1).sum()
        assert shift > 5 and overlap < 0.9, (shift, overlap)
        # every object is where geometry.object_transforms puts it for the frame's pose (the
        # page's frames are float32)
        q = view.q[k_goal].astype(np.float32).astype(float)
        expected = object_transforms(view.geometry, q)
        got = world_matrices(page, expected)
        for key, T in expected.items():
            np.testing.assert_allclose(got[key], T, atol=1e-7, err_msg=key)
        # the ghost holds the reference pose
        assert view.q_ref is not None
        assert page.evaluate("window.stewartView.shown().q_ref") is not None
    finally:
        page.close()


def test_controls_and_text(browser, run_view):
    view, path = run_view
    page = open_view(browser, path)
    try:
        for sel in ("#play", "#slider", "#time", "#bar", "#info"):
            assert page.is_visible(sel), sel
        assert not page.is_visible("#chapter")     # a run has no chapters: no selector
        assert page.inner_text("#tick-max").endswith(" N")
        sub = page.inner_text("#head .sub")
        assert f"{view.frames} frames at 30 frames/s" in sub and str(view.source_samples) in sub
        assert int(page.get_attribute("#slider", "max")) == view.frames - 1
        page.evaluate("""n => { const s = document.getElementById('slider'); s.value = n;
                                s.dispatchEvent(new Event('input')); }""", view.frames // 2)
        settle(page)
        shown = page.evaluate("window.stewartView.shown()")
        assert shown["t"] == pytest.approx(view.t[view.frames // 2], abs=1e-6)
        info = page.inner_text("#info")
        assert f"t = {view.t[view.frames // 2]:.3f} s" in info
        assert "cond(J)" in info and "force [N]" in info and "length [mm]" in info
        # play advances the time
        page.evaluate("window.stewartView.show(0)")
        page.click("#play")
        page.wait_for_function("window.stewartView.shown().t > 0.05", timeout=20_000)
    finally:
        page.close()


def test_leg_colour_follows_its_force(browser, micro_model, tmp_path):
    n = 31
    t = np.linspace(0.0, 1.0, n)
    q = np.tile(micro_model.home, (n, 1))
    forces = np.zeros((n, 6))
    forces[:, 0] = 40.0          # leg 1 pushes hard
    forces[:, 3] = -40.0         # leg 4 pulls as hard
    forces[:, 1] = np.linspace(-20.0, 20.0, n)   # leg 2 sweeps through zero
    view = view_data(micro_model, t, q, forces, controller=scene_of(micro_model).controller,
                     fps=30.0, title="colours")
    path = tmp_path / "colours.html"
    write_view(path, view)
    scale = nice_ceiling(40.0)
    page = open_view(browser, path)
    try:
        for k in (0, n // 2, n - 1):
            show(page, k)
            colours = np.array(page.evaluate("""() => [1, 2, 3, 4, 5, 6].map(i =>
                window.stewartView.viewer.scene_tree.find(["stewart", "legs", String(i),
                    "cylinder"]).object.children[0].material.color.toArray())"""))
            np.testing.assert_allclose(colours, force_colours(view.forces[k], scale), atol=1e-6)
        # and on screen: the pusher's cylinder is red, the puller's blue
        pixels = canvas_pixels(page)
        at = page.evaluate("""() => {
            const v = window.stewartView.viewer, T = MeshCat.THREE;
            const c = v.renderer.domElement;
            return [1, 4].map(i => {
                const p = new T.Vector3();
                v.scene_tree.find(["stewart", "legs", String(i), "cylinder"]).object
                    .getWorldPosition(p);
                p.project(v.camera);
                return [Math.round((p.x + 1) / 2 * c.clientWidth),
                        Math.round((1 - p.y) / 2 * c.clientHeight)];
            });
        }""")
        for (x, y), sign in zip(at, (1, -1)):
            patch = pixels[y - 2:y + 3, x - 2:x + 3].reshape(-1, 3).astype(int).mean(axis=0)
            assert sign * (patch[0] - patch[2]) > 40, (sign, patch)
    finally:
        page.close()


def test_marks_stroke_limit_and_near_singular(browser, micro_model, tmp_path):
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    # the platform lowered until its legs are within the margin of leg_min: every leg marked
    q = np.tile(micro_model.home, (3, 1))
    # lower the platform until every leg is 0.5 mm above leg_min (within 1 % of the 120 mm
    # stroke): legs at home reach sqrt(h^2 + dz^2), h their horizontal span (all equal here)
    home = inverse_kinematics(micro_model, micro_model.home, with_cond=False)
    h = np.hypot(home.leg_vectors[0, 0], home.leg_vectors[0, 1])
    joint_z = micro_model.platform_joints[0, 2]
    q[1, 2] = -joint_z + np.sqrt((micro_model.leg_min + 0.0005) ** 2 - h**2)
    view = view_data(micro_model, np.array([0.0, 0.5, 1.0]), q, np.zeros((3, 6)),
                     controller=scene_of(micro_model).controller, fps=2.0)
    assert view.at_limit[1].all() and not view.at_limit[0].any()
    # a threshold below home's cond(J) marks every frame near-singular
    view = dataclasses.replace(view, geometry=dataclasses.replace(g, cond_warn=1.5))
    path = tmp_path / "marks.html"
    write_view(path, view)
    page = open_view(browser, path)
    try:
        limit_visible = """() => [1, 2, 3, 4, 5, 6].map(i =>
            window.stewartView.viewer.scene_tree.find(["stewart", "limits", String(i)]).object.visible)"""
        show(page, 0)
        assert page.evaluate(limit_visible) == [False] * 6
        show(page, 1)
        assert page.evaluate(limit_visible) == [True] * 6
        alert = page.inner_text("#alert")
        assert "legs 1, 2, 3, 4, 5, 6 at a stroke limit" in alert
        assert "near-singular" in alert
        colour = page.evaluate("""() => window.stewartView.viewer.scene_tree.find(
            ["stewart", "platform"]).object.children[0].material.color.toArray()""")
        assert colour[0] > 0.8 and colour[1] < 0.2     # the platform turns red
    finally:
        page.close()


class _State(BaseHTTPRequestHandler):
    page = b""
    state: dict = {}

    def do_GET(self):  # noqa: N802 (http.server's name)
        body, kind = ((self.page, "text/html") if self.path == "/" else
                      (json.dumps(self.state).encode(), "application/json"))
        self.send_response(200)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


@contextmanager
def live_page(browser, g, state: dict):
    """A page of live_view_html(g) loaded from a loopback server answering /state with `state`,
    ready; the server and the page closed after."""
    handler = type("Handler", (_State,), {"page": live_view_html(g, "/state").encode(),
                                          "state": state})
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    page = browser.new_page()
    try:
        page.goto(f"http://127.0.0.1:{server.server_address[1]}/")
        page.wait_for_function("window.stewartView && window.stewartView.ready", timeout=60_000)
        yield page
    finally:
        page.close()
        server.shutdown()


def test_live_page_draws_what_the_url_serves(browser, micro_model):
    g = view_geometry(micro_model, controller=scene_of(micro_model).controller)
    q = micro_model.home + np.array([0.01, -0.005, 0.01, 0.05, 0.0, -0.05])
    state = {"t": 1.25, "q": q.tolist(), "q_ref": None, "lengths": [0.13] * 6,
             "forces": [10.0, -10.0, 0.0, 0.0, 0.0, 0.0], "cond": 2.5}
    with live_page(browser, g, state) as page:
        got = world_matrices(page, ["platform"])["platform"]
        np.testing.assert_allclose(got, object_transforms(g, q)["platform"], atol=1e-9)
        assert page.evaluate("window.stewartView.forceScale()") == pytest.approx(g.force_scale)
        assert not page.is_visible("#player")
        assert "t = 1.250 s" in page.inner_text("#info")


def test_live_page_draws_the_pivot_and_the_frames_where_geometry_puts_them(browser):
    """A scene with [frames]: the page (page.js) moves the pivot's sphere and the tool triad
    with the platform, and keeps the user triad on the base, as geometry.frame_transforms and
    triad_transforms place them."""
    data = scene_dict("micro")
    data["frames"] = {"pivot": [0.001, -0.002, 0.01], "tool": [0.003, 0.001, 0.02, 0.1, -0.2, 0.3],
                      "user": [0.02, -0.01, 0.005, -0.05, 0.15, 0.4]}
    model = scene_from_dict(data)
    g = view_geometry(model, controller=None)
    q = model.home + np.array([0.01, -0.005, 0.01, 0.05, 0.0, -0.05])
    state = {"t": 0.5, "q": q.tolist(), "q_ref": None, "lengths": [0.13] * 6,
             "forces": [0.0] * 6, "cond": 2.5}
    with live_page(browser, g, state) as page:
        page.wait_for_function("window.stewartView.shown() !== null", timeout=60_000)
        expected = object_transforms(g, q)
        axes = triad_transforms(g.frames["axis_length"])
        keys = ["frames/pivot"] + [f"frames/{f}/{a}" for f in ("user", "tool") for a in TRIAD]
        got = world_matrices(page, keys)
        np.testing.assert_allclose(got["frames/pivot"], expected["frames/pivot"], atol=1e-9)
        for f in ("user", "tool"):
            for a in TRIAD:
                np.testing.assert_allclose(got[f"frames/{f}/{a}"],
                                           expected[f"frames/{f}"] @ axes[a], atol=1e-9,
                                           err_msg=f"{f}/{a}")
