"""`stewart-sim modes` writes DIR/view.html with its result set: one cycle per mode, every
frame on the mode's line through the pose (x - x0 along v, R R0^T a rotation about omega, by
the same sin(2 pi k / CYCLE_FRAMES) scale), checked against modes.csv's shape columns; the
title names each mode's frequency; a failing view leaves no result set."""
from __future__ import annotations

import base64
import csv
import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stewart_fmu.errors import StewartError
from stewart_sim import cli
from stewart_sim.studies.modes import animation as modes_view_module
from stewart_sim.studies.modes.animation import AMPLITUDE, CYCLE_FRAMES, EULER
from tests.app.test_modes_command import SIM

POSE = "0.05,-0.02,2.35,0.02,-0.03,0.04"
EPS32 = float(np.finfo(np.float32).eps)


def page_data(html: str) -> dict:
    return json.loads(re.search(r'<script type="application/json" id="view-data">(.*?)</script>',
                                html, re.S).group(1).replace("<\\/", "</"))


def _floats(b64: str, cols: int) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype="<f4").astype(float).reshape(-1, cols)


def test_view_holds_one_cycle_per_mode_along_its_twist(tmp_path):
    out = tmp_path / "m"
    assert cli.main(["modes", str(SIM), "--pose", POSE, "--modes", "4", "--out", str(out)]) == 0
    with (out / "modes.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    shapes = np.array([[float(r[c]) for c in ("dx", "dy", "dz", "dthx", "dthy", "dthz")]
                       for r in rows])
    data = page_data((out / "view.html").read_text(encoding="utf-8"))
    frames = data["frames"]
    assert frames["count"] == len(rows) * CYCLE_FRAMES == 4 * CYCLE_FRAMES
    q = _floats(frames["q"], 6).reshape(len(rows), CYCLE_FRAMES, 6)
    t = _floats(frames["t"], 1).ravel()
    assert np.allclose(t, np.arange(t.size) / CYCLE_FRAMES, rtol=0, atol=4 * EPS32 * t.size)
    q0 = np.array([float(v) for v in POSE.split(",")])
    R0 = Rotation.from_euler(EULER, q0[3:])
    phase = np.sin(2 * np.pi * np.arange(CYCLE_FRAMES) / CYCLE_FRAMES)
    size = max(data["geometry"]["base_radius"], data["geometry"]["home"][2])
    r_p = data["geometry"]["platform_radius"]
    # the page's float32: a pose of |q| <= 3 holds to ~ 3 eps32 per component
    tol = 8 * EPS32 * max(1.0, float(np.max(np.abs(q0))))
    for j, shape in enumerate(shapes):
        moved = np.column_stack([q[j, :, :3] - q0[:3],
                                 (Rotation.from_euler(EULER, q[j, :, 3:]) * R0.inv()).as_rotvec()])
        scale = moved @ shape / (shape @ shape)          # each frame's multiple of the shape
        assert np.allclose(moved, np.outer(scale, shape), rtol=0, atol=tol), f"mode {j + 1}"
        a = float(np.max(np.abs(scale)))
        assert np.allclose(scale, a * phase, rtol=0, atol=tol / np.linalg.norm(shape) * 4)
        reach = a * (np.linalg.norm(shape[:3]) + r_p * np.linalg.norm(shape[3:]))
        assert abs(reach - AMPLITUDE * size) <= 1e-6 * size
        # and not along another mode's shape (the check tells the modes apart)
        other = shapes[(j + 1) % len(shapes)]
        off = moved - np.outer(moved @ other / (other @ other), other)
        assert np.max(np.abs(off)) > 1e3 * tol
    title = _title(out)
    for r in rows:
        assert f"mode {r['mode']} {float(r['frequency_hz']):.4g} Hz" in title


def _title(out) -> str:
    return re.search(r"<title>(.*?)</title>", (out / "view.html").read_text(encoding="utf-8"),
                     re.S).group(1)


def test_no_view_and_a_failing_view_keep_the_set_whole(tmp_path, monkeypatch):
    out = tmp_path / "plain"
    assert cli.main(["modes", str(SIM), "--pose", POSE, "--no-view", "--out", str(out)]) == 0
    assert (out / "modes.csv").is_file() and not (out / "view.html").exists()

    def broken(*_a, **_k):
        raise StewartError("view: broken on purpose")

    monkeypatch.setattr(modes_view_module, "modes_view", broken)
    failed = tmp_path / "failed"
    assert cli.main(["modes", str(SIM), "--pose", POSE, "--out", str(failed)]) != 0
    assert not failed.exists()


def test_the_page_selects_a_mode_and_plays_it_in_a_loop(browser, tmp_path):
    """The page's selector lists each mode with its frequency; picking mode 3 plays its cycle
    (t in [2, 3) s) in a loop: every frame shown within [2, 3) s, wrapping
    back; the time line names the mode shown (a run's view has no selector: test_view_browser)."""
    from tests.browser import open_view, settle

    out = tmp_path / "m"
    assert cli.main(["modes", str(SIM), "--pose", POSE, "--out", str(out)]) == 0
    with (out / "modes.csv").open(newline="") as fh:
        hz = [float(r["frequency_hz"]) for r in csv.DictReader(fh)]
    page = open_view(browser, out / "view.html")
    try:
        assert page.errors == [] and page.is_visible("#chapter")
        labels = page.eval_on_selector_all("#chapter option", "os => os.map(o => o.textContent)")
        assert labels == ["all, in turn", *(f"mode {j + 1}: {f:.4g} Hz" for j, f in enumerate(hz))]
        page.select_option("#chapter", "2")
        settle(page)
        assert 2.0 <= page.evaluate("window.stewartView.shown().t") < 3.0   # playing mode 3
        assert "mode 3:" in page.inner_text("#time")
        # record every frame shown until the cycle has wrapped (the page plays on the real
        # clock: the wait is bounded generously, the assertions are on what was shown)
        page.evaluate("""() => { window.seen = [];
            (function rec() { window.seen.push(window.stewartView.shown().t);
                              requestAnimationFrame(rec); })(); }""")
        page.wait_for_function("""() => { const s = window.seen;
            const top = s.findIndex(t => t > 2.5);
            return top >= 0 && s.slice(top).some(t => t < 2.5); }""", timeout=60_000)
        seen = np.array(page.evaluate("window.seen"))
        assert np.all((seen >= 2.0) & (seen < 3.0)), seen
        assert np.any(np.diff(seen) < 0), seen   # it wrapped within mode 3's cycle
        assert page.errors == []
    finally:
        page.close()


def _rows(path):
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def test_frame_gives_the_pose_and_the_grid_in_the_scenes_frames(tmp_path, capsys):
    """--frame tool: --pose is the tool frame's pose (stewart_fmu.frames, the core's frames.c);
    the modes are those of the platform pose it names, and --map's grid is in the same frame
    (map.csv's pose columns as given, each value that of its platform pose). An unknown frame
    is refused in one line, exit 2, nothing written."""
    from stewart_fmu import load_scene
    from stewart_fmu.frames import to_platform

    scene = tmp_path / "framed.toml"
    scene.write_text(SIM.read_text(encoding="utf-8")
                     + "\n[frames]\npivot = [0.0, 0.0, 0.4]\ntool = [0.1, 0.0, 0.5, 0.0, 0.0, 0.2]\n")
    model = load_scene(scene)
    given = np.array([0.05, -0.02, 2.9, 0.02, -0.03, 0.04])
    q = to_platform(model, given, "tool")
    assert np.max(np.abs(q - given)) > 0.1          # the frame makes a difference
    framed, plain = tmp_path / "framed", tmp_path / "plain"
    text = ",".join(repr(float(v)) for v in given)
    assert cli.main(["modes", str(scene), "--frame", "tool", f"--pose={text}", "--no-view",
                     "--map", "z=2.85:2.95:3", "--out", str(framed)]) == 0
    assert cli.main(["modes", str(scene), "--pose=" + ",".join(repr(float(v)) for v in q), "--no-view",
                     "--out", str(plain)]) == 0
    assert _rows(framed / "modes.csv") == _rows(plain / "modes.csv")
    rows = _rows(framed / "map.csv")
    assert [float(r["z"]) for r in rows] == np.linspace(2.85, 2.95, 3).tolist()
    from stewart_fmu.stiffness import modes
    for r in rows:
        p = given.copy()
        p[2] = float(r["z"])
        assert r["inside"] == "1"
        lowest = modes(model, to_platform(model, p, "tool")).frequency_hz[0]
        assert float(r["lowest_hz"]) == pytest.approx(lowest, rel=1e-12)
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert cli.main(["modes", str(scene), "--frame", "hand", "--out", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "hand" in err[0] and not bad.exists()
