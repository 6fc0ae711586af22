"""The live view as a person sees it: headless Chromium (the session's `browser` fixture,
tests/browser.py) loads the page of `stewart_sim.view.live_server` while the device is ticked by
hand (device time, deterministic), and sees the platform move when a setpoint arrives: the
platform's transform the page shows is the geometry's for the published pose (the same 4x4 as
Python's
`object_transforms`), and the pixels around the platform's projection change. Skipped, with the
reason, where Chromium or Playwright cannot be had."""
from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil.device import Device  # noqa: E402
from hil.observe import Latest, Snapshot  # noqa: E402
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from stewart_sim.scene.load import scene_of  # noqa: E402
from stewart_sim.view.geometry import object_transforms, view_geometry  # noqa: E402
from stewart_sim.view.live_server import LiveView, live_page  # noqa: E402
from tests.browser import VIEWPORT, canvas_pixels, settle  # noqa: E402
from tests.hil.test_device import SCENE, arm, setpoint  # noqa: E402

MOVE = np.array([0.0, 0.0, 0.012, 0.0, 0.0, 0.35])   # 12 mm up and 20 deg about z: visible
WAIT = 60.0                                           # s, the longest wait for the page


def _wait_shown(page, t: float) -> dict:
    """The frame the page shows once it shows device time `t` (bounded wait)."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        shown = page.evaluate("() => window.stewartView && window.stewartView.ready "
                              "&& window.stewartView.shown()")
        if shown and abs(shown["t"] - t) < 1e-9:
            settle(page)                                  # drawn, not only set
            return shown
        time.sleep(0.05)
    raise AssertionError(f"the page did not show t = {t} within {WAIT} s")


# where the platform's centre is drawn, in the canvas's pixels (the viewer's camera projection)
PLATFORM_PIXEL = """() => {
  const v = window.stewartView.viewer;
  const o = v.scene_tree.find(["stewart", "platform"]).object;
  const p = o.getWorldPosition(new o.position.constructor()).project(v.camera);
  const c = v.renderer.domElement.getBoundingClientRect();
  return [(p.x + 1) / 2 * c.width, (1 - p.y) / 2 * c.height];
}"""


def _patch(img: np.ndarray, centre, half: int = 60) -> np.ndarray:
    """The pixels of a square around `centre` in the canvas image."""
    x, y = int(round(centre[0])), int(round(centre[1]))
    return img[max(0, y - half): y + half, max(0, x - half): x + half].astype(int)


def test_live_page_shows_the_platform_move_when_a_setpoint_arrives(browser):
    model = load_scene(SCENE)
    geometry = view_geometry(model, controller=scene_of(model).controller)
    dev = Device(model, watchdog=5.0)
    latest = Latest()
    dev.observe(latest)
    target = np.asarray(model.home, dtype=float) + MOVE
    with LiveView(live_page(model, scene_of(model).controller), latest, 0) as view:
        view.start()
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(view.url)
        # the text panels hidden: the pixels compared are the 3D scene's, not changing text
        page.add_style_tag(content=".panel, .dg.ac { visibility: hidden !important; }")
        before = _wait_shown(page, 0.0)
        shot0 = canvas_pixels(page)
        pixel0 = page.evaluate(PLATFORM_PIXEL)
        assert before["q_ref"] is None
        dev.receive(arm())
        dev.receive(setpoint(0, inverse_kinematics(model, target).lengths))
        for _ in range(1020):                     # ~1 s of device time: the platform arrives
            dev.tick()
        t1 = latest.latest().t
        after = _wait_shown(page, t1)
        shot1 = canvas_pixels(page)
        pixel1 = page.evaluate(PLATFORM_PIXEL)
        page.close()
    q1 = np.array(after["q"])
    assert np.max(np.abs(q1 - target)) < 1e-6                  # the page shows the arrived pose
    assert np.max(np.abs(np.array(after["q_ref"]) - target)) < 1e-9
    # the platform drawn where the geometry puts it: the page's 4x4 = Python's, before and after
    for shown, q in ((before, model.home), (after, q1)):
        T = np.array(shown["transforms"]["platform"], dtype=float).reshape(4, 4).T  # column-major
        assert np.allclose(T, object_transforms(geometry, q)["platform"], atol=1e-9)
    # and it moved on the screen: its centre's projection and the pixels around it changed
    assert np.hypot(pixel1[0] - pixel0[0], pixel1[1] - pixel0[1]) > 3.0
    p0, p1 = _patch(shot0, pixel0), _patch(shot1, pixel0)
    assert p0.std() > 5.0, "a blank canvas where the platform should be"
    changed = np.mean(np.any(np.abs(p1 - p0) > 24, axis=2))
    assert changed > 0.05, changed


def test_live_page_keeps_the_last_good_picture_when_the_state_is_not_finite(browser):
    """/state sends a non-finite number as null (live_server.state_document): the page keeps drawing
    the last finite state and says why in its status line, without a page error."""
    model = load_scene(SCENE)
    latest = Latest()
    home = tuple(float(v) for v in model.home)
    kin = inverse_kinematics(model, np.asarray(model.home, dtype=float))
    good = Snapshot(tick=1, t=0.001, q=home, q_ref=None, lengths=tuple(kin.lengths.tolist()),
                    forces=(1.0,) * 6, cond=float(kin.cond), armed=True)
    with LiveView(live_page(model, scene_of(model).controller), latest, 0) as view:
        view.start()
        page = browser.new_page(viewport=VIEWPORT)
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(view.url)
        page.wait_for_function("() => document.getElementById('status').textContent"
                               ".includes('no state from the device yet')", timeout=WAIT * 1e3)
        latest.publish(good)
        _wait_shown(page, 0.001)
        bad = Snapshot(tick=2, t=0.002, q=(float("nan"),) * 6, q_ref=None,
                       lengths=(float("nan"),) * 6, forces=(float("inf"),) * 6,
                       cond=float("inf"), armed=False)
        latest.publish(bad)
        page.wait_for_function("() => document.getElementById('status').textContent"
                               ".includes('not finite, not drawn')", timeout=WAIT * 1e3)
        shown = page.evaluate("window.stewartView.shown()")
        status = page.evaluate("document.getElementById('status').textContent")
        page.close()
    assert shown["t"] == 0.001 and np.allclose(shown["q"], home)
    assert "(disarmed)" in status and "t = 0.002" in status
    assert errors == []
