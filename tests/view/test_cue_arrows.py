"""The specific-force arrows of the 3D views (the vehicle's and the delivered specific force at the
pilot's head): geometry.arrow_transforms puts each arrow from the head point along R f at the
geometry's scale; the live page and the `cue` command's static view carry the arrow objects,
their legend and scale; in headless Chromium (tests/browser.py) the page draws each arrow where
arrow_transforms puts it for the frame, from /state's f_vehicle and f_delivered (hidden when
they are null) and from the static view's frames."""
from __future__ import annotations

import json
import re
import time

import numpy as np
import pytest

from hil.observe import Latest, Snapshot
from stewart_fmu import scene_from_dict
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.cueing.motion import read_motion
from stewart_sim.cueing.report import cue_view
from stewart_sim.cueing.study import cue_study
from stewart_sim.scene.load import scene_of
from stewart_sim.view.geometry import (
    CUES,
    arrow_transforms,
    part_ends,
    rotation,
    view_geometry,
)
from stewart_sim.view.html import static_view_html, write_view
from stewart_sim.view.live_server import LiveView, live_page
from tests.browser import VIEWPORT, open_view, settle
from tests.helpers import ROOT, scene_dict

HEAD = [0.1, -0.2, 0.8]            # m, in C
POSE = np.array([0.05, -0.03, 2.35, 0.04, -0.06, 0.2])
F_VEHICLE = (-2.0, 0.5, 9.81)      # m/s^2, in C
F_DELIVERED = (-1.2, 0.3, 9.7)
WAIT = 60.0                        # s, the longest wait for a page


@pytest.fixture(scope="module")
def model():
    data = scene_dict("sim")
    data["cueing"]["head"] = HEAD
    return scene_from_dict(data)


def page_data(html: str) -> dict:
    return json.loads(re.search(r'<script type="application/json" id="view-data">(.*?)</script>',
                                html, re.S).group(1).replace("<\\/", "</"))


def test_an_arrow_runs_from_the_head_along_the_rotated_force_at_the_scale(model):
    g = view_geometry(model, controller=None)
    np.testing.assert_array_equal(g.head, HEAD)
    assert g.arrow_scale > 0 and g.arrow_tip > 0
    R = rotation(POSE)
    start = POSE[:3] + R @ np.array(HEAD)
    for f in (F_VEHICLE, (0.0, 0.0, 0.01)):         # longer and shorter than the tip
        T = arrow_transforms(g, POSE, f)
        end = start + g.arrow_scale * R @ np.array(f)
        lo, hi = part_ends(T["shaft"], 1.0)          # the shaft is a unit cylinder, stretched
        tip_lo, tip_hi = part_ends(T["tip"], g.arrow_tip)
        np.testing.assert_allclose(lo, start, atol=1e-12)
        np.testing.assert_allclose(hi, tip_lo, atol=1e-12)
        np.testing.assert_allclose(tip_hi, end, atol=1e-12)
    assert arrow_transforms(g, POSE, (0.0, 0.0, 0.0)) is None


def test_the_live_page_holds_the_arrows_their_legend_and_scale(model):
    html = live_page(model, scene_of(model).controller)
    data = page_data(html)
    assert data["cues"] is True
    paths = {c["path"] for c in data["scene"] if c["type"] == "set_object"}
    assert {f"/cues/{name}/{part}" for name in CUES for part in ("shaft", "tip")} <= paths
    hidden = {c["path"] for c in data["scene"]
              if c["type"] == "set_property" and c["property"] == "visible" and not c["value"]}
    assert {"/cues/head", "/cues/f_vehicle", "/cues/f_delivered"} <= hidden
    assert data["geometry"]["head"] == HEAD
    assert set(data["cue_rgb"]) == set(CUES)
    for needle in ('id="cue-legend"', "specific force at the head", 'id="cue-dot-f_vehicle"',
                   'id="cue-dot-f_delivered"', 'id="cue-scale"', "arrowTransforms"):
        assert needle in html


def test_the_cue_commands_view_has_the_arrows_of_every_frame(model):
    study = cue_study(scene_of(model), read_motion(ROOT / "scenes" / "motions" / "braking_car.csv"))
    view = cue_view(study, "t", scene_of(model).controller)
    p = study.runs[0].perception
    idx = np.searchsorted(p.t, view.t)
    np.testing.assert_array_equal(view.f_vehicle, p.vehicle_f[idx])
    np.testing.assert_array_equal(view.f_delivered, p.delivered_f[idx])
    data = page_data(static_view_html(view))
    assert data["cues"] is True and data["frames"]["f_delivered"] is not None
    # a view without specific forces (e.g. `view` of a run) has no arrows at all
    plain = page_data(static_view_html(type(view)(**{**vars(view), "f_vehicle": None,
                                                      "f_delivered": None})))
    assert plain["cues"] is False and plain["frames"]["f_vehicle"] is None
    assert not any(c.get("path", "").startswith("/cues") for c in plain["scene"])


ARROW_MATRICES = """() => {
    const v = window.stewartView.viewer, T = MeshCat.THREE;
    v.scene.updateMatrixWorld(true);
    const root = new T.Matrix4().copy(v.scene.matrixWorld).invert();
    const out = {};
    for (const name of ["f_vehicle", "f_delivered"]) {
        const node = v.scene_tree.find(["cues", name]);
        out[name] = {visible: node.object.visible};
        for (const part of ["shaft", "tip"]) out[name][part] = Array.from(
            new T.Matrix4().multiplyMatrices(root,
                v.scene_tree.find(["cues", name, part]).object.matrixWorld).elements);
    }
    return out;
}"""


def _arrows(page) -> dict:
    raw = page.evaluate(ARROW_MATRICES)
    return {name: {"visible": a["visible"],
                   **{part: np.array(a[part]).reshape(4, 4).T for part in ("shaft", "tip")}}
            for name, a in raw.items()}


def _wait_shown(page, t: float) -> None:
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        shown = page.evaluate("() => window.stewartView && window.stewartView.ready "
                              "&& window.stewartView.shown()")
        if shown and abs(shown["t"] - t) < 1e-9:
            settle(page)
            return
        time.sleep(0.05)
    raise AssertionError(f"the page did not show t = {t} within {WAIT} s")


def test_the_live_page_draws_the_published_forces_as_arrows(browser, model):
    g = view_geometry(model, controller=scene_of(model).controller)
    kin = inverse_kinematics(model, POSE)
    common = dict(q=tuple(POSE.tolist()), q_ref=None, lengths=tuple(kin.lengths.tolist()),
                  forces=(100.0,) * 6, cond=float(kin.cond), armed=True)
    latest = Latest()
    latest.publish(Snapshot(tick=1, t=0.001, f_vehicle=F_VEHICLE, f_delivered=F_DELIVERED,
                            **common))
    with LiveView(live_page(model, scene_of(model).controller), latest, 0) as view:
        view.start()
        page = browser.new_page(viewport=VIEWPORT)
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(view.url)
        _wait_shown(page, 0.001)
        drawn = _arrows(page)
        legend = page.is_visible("#cue-legend")
        scale = page.inner_text("#cue-scale")
        info = page.inner_text("#info")
        latest.publish(Snapshot(tick=2, t=0.002, **common))     # a device alone: no forces
        _wait_shown(page, 0.002)
        gone = _arrows(page)
        legend_after = page.is_visible("#cue-legend")
        page.close()
    for name, f in (("f_vehicle", F_VEHICLE), ("f_delivered", F_DELIVERED)):
        expected = arrow_transforms(g, POSE, f)
        assert drawn[name]["visible"]
        for part in ("shaft", "tip"):
            np.testing.assert_allclose(drawn[name][part], expected[part], atol=1e-9)
        assert not gone[name]["visible"]
    assert legend and not legend_after
    assert f"1 m/s\u00b2 = {1000 * g.arrow_scale:.3g} mm" in scale
    assert "specific force at the head" in info and "-2.000" in info
    assert errors == []


def test_the_cue_view_draws_each_frames_arrows(browser, model, tmp_path):
    study = cue_study(scene_of(model), read_motion(ROOT / "scenes" / "motions" / "braking_car.csv"))
    view = cue_view(study, "t", scene_of(model).controller)
    path = tmp_path / "view.html"
    write_view(path, view)
    page = open_view(browser, path)
    try:
        for k in (0, view.frames // 3, view.frames - 1):
            page.evaluate("k => window.stewartView.show(k)", k)
            settle(page)
            drawn = _arrows(page)
            q = view.q[k].astype(np.float32).astype(float)      # the page's frames are float32
            for name in CUES:
                f = getattr(view, name)[k].astype(np.float32).astype(float)
                expected = arrow_transforms(view.geometry, q, f)
                assert drawn[name]["visible"]
                for part in ("shaft", "tip"):
                    np.testing.assert_allclose(drawn[name][part], expected[part], atol=1e-9)
        assert page.is_visible("#cue-legend")
        assert page.errors == []
    finally:
        page.close()
