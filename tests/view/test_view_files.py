"""The view's files without a browser: decimation, what the page embeds (one file, offline,
the frames as written), its size, and `stewart-sim view` and the commands that write a view
by default, with their one-line refusals."""
from __future__ import annotations

import base64
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.moves import DEMO_DURATION, DEMO_RATE, demo_trajectory, run_reference
from stewart_fmu import io
from stewart_sim.cli import main
from stewart_sim.scene.load import scene_of
from stewart_sim.view.data import DEFAULT_FPS, frame_indices
from stewart_sim.view.geometry import view_geometry
from stewart_sim.view.html import live_view_html, static_view_html
from stewart_sim.view.sources import run_table_view, trajectory_view
from tests.helpers import SCENE_FILES, level_model

MICRO = str(SCENE_FILES["micro"])


@pytest.fixture(scope="module")
def model():
    return level_model("micro", "full")


def page_data(text: str) -> dict:
    """The JSON the page embeds."""
    match = re.search(r'<script type="application/json" id="view-data">(.*?)</script>', text, re.S)
    return json.loads(match.group(1))


def floats(b64: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype="<f4")


@pytest.mark.parametrize("rate, duration, fps", [(1000.0, 4.0, 30.0), (1000.0, 4.0, 60.0),
                                                 (237.0, 1.3, 30.0), (10.0, 5.0, 30.0)])
def test_frame_indices(rate, duration, fps):
    t = np.arange(int(round(duration * rate)) + 1) / rate
    idx = frame_indices(t, fps)
    assert idx[0] == 0 and idx[-1] == t.size - 1
    assert np.all(np.diff(idx) > 0)
    if rate >= fps:
        # one frame per 1/fps of simulated time: the first sample at or after each grid time
        grid = np.arange(int(np.floor(t[-1] * fps + 1e-9)) + 1) / fps
        chosen = idx[:grid.size]
        assert np.all(t[chosen] >= grid - 1e-9) and np.all(t[chosen] - grid < 1 / rate + 1e-9)
    else:
        np.testing.assert_array_equal(idx, np.arange(t.size))   # fewer samples: all shown
    # decimating the frames again changes nothing (the sources pre-decimate)
    np.testing.assert_array_equal(idx[frame_indices(t[idx], fps)], idx)


def test_page_is_one_offline_file_with_the_frames(model):
    config = controller_config(model)
    result = run_closed_loop(model, config, run_reference(model, config, DEMO_DURATION))
    view = run_table_view(model, result.table, controller=config, title="run", source="run.csv")
    text = static_view_html(view)
    # one file: no script, style sheet or image fetched from anywhere
    assert not re.search(r'<(script|link|img)[^>]+(src|href)=', text)
    assert "MeshCat" in text and "new MeshCat.Viewer" in text
    # the 4 s run at 1 kHz: 121 frames at 30 fps, stated, and the file well under a few MB
    assert len(result.table) == int(DEMO_DURATION * DEMO_RATE) + 1
    assert view.frames == int(DEMO_DURATION * DEFAULT_FPS) + 1
    assert f"{view.frames} frames at 30 frames/s of simulated time from {len(result.table)} samples" in text
    assert len(text.encode()) < 1.5e6
    data = page_data(text)
    frames = data["frames"]
    assert frames["count"] == view.frames
    np.testing.assert_array_equal(floats(frames["q"]).reshape(-1, 6), view.q.astype("<f4"))
    np.testing.assert_array_equal(floats(frames["q_ref"]).reshape(-1, 6), view.q_ref.astype("<f4"))
    np.testing.assert_array_equal(floats(frames["forces"]).reshape(-1, 6),
                                  view.forces.astype("<f4"))
    # the forces are the rack forces: motor torque x zeta / r, at the frames' samples
    idx = frame_indices(result.table["time"], DEFAULT_FPS)
    tau = np.column_stack([result.table[f"torque{i}"] for i in range(1, 7)])[idx]
    np.testing.assert_allclose(view.forces, tau * model.drive.force_per_torque, rtol=1e-15)
    assert data["meta"]["source_samples"] == len(result.table) and data["meta"]["fps"] == 30.0


def test_trajectory_view_forces_are_the_inverse_commands(model, tmp_path):
    """A trajectory's view computes sigma at its frames only: the numbers `inverse` writes."""
    t, q, qd, qdd = demo_trajectory(model, 1.0)
    traj = tmp_path / "traj.csv"
    io.write_csv(traj, io.trajectory_table(t, q, qd, qdd))
    assert main(["inverse", MICRO, "--trajectory", str(traj), "--out", str(tmp_path / "F.csv")]) == 0
    sigma = io.read_samples(tmp_path / "F.csv", io.FORCE_COLUMNS, "forces", prefix=True)[:, 1:]
    view = trajectory_view(model, t, q, qd, qdd, controller=scene_of(model).controller,
                           title="demo")
    np.testing.assert_allclose(view.forces, sigma[frame_indices(t, DEFAULT_FPS)], rtol=1e-12)
    assert (tmp_path / "F.html").is_file()                      # written by default
    assert main(["inverse", MICRO, "--trajectory", str(traj), "--out", str(tmp_path / "G.csv"),
                 "--no-view"]) == 0
    assert not (tmp_path / "G.html").exists()
    # and `view` of the forces with their trajectory shows the same frames
    out = tmp_path / "v.html"
    assert main(["view", str(tmp_path / "F.csv"), "--trajectory", str(traj), "--scene", MICRO,
                 "-o", str(out)]) == 0
    data = page_data(out.read_text())
    np.testing.assert_array_equal(floats(data["frames"]["forces"]).reshape(-1, 6),
                                  view.forces.astype("<f4"))


def test_live_page_polls_the_url(model):
    geometry = view_geometry(model, controller=scene_of(model).controller)
    text = live_view_html(geometry, "/state.json")
    data = page_data(text)
    assert data["live"]["state_url"] == "/state.json" and data["live"]["period_ms"] == 50
    assert "frames" not in data and data["force_scale"] == pytest.approx(160.0)


def test_run_writes_its_view_and_view_reads_the_run(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", MICRO, "--out", str(out), "--duration", "0.5"]) == 0
    assert f"wrote {out / 'view.html'}" in capsys.readouterr().out
    assert (out / "view.html").is_file()
    # the run recorded its scene (summary.md): view needs no --scene from where it ran
    again = tmp_path / "again.html"
    assert main(["view", str(out), "-o", str(again), "--fps", "60"]) == 0
    said = capsys.readouterr().out
    match = re.match(rf"wrote {again}: ([0-9.]+) MB, 31 frames at 60 frames/s from 501 samples",
                     said)
    assert match and float(match.group(1)) == pytest.approx(again.stat().st_size / 1e6, abs=0.006)
    assert main(["run", MICRO, "--out", str(out), "--duration", "0.5", "--no-view"]) == 0
    assert not (out / "view.html").exists()     # the new set took the earlier one's place whole


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("stewart-sim: error: "), err
    return err


def test_view_refuses_bad_input_in_one_line(tmp_path, capsys, model):
    out = str(tmp_path / "v.html")
    assert main(["view", str(tmp_path / "nope"), "--scene", MICRO, "-o", out]) == 2
    assert "no such file or directory" in _error(capsys)
    assert main(["view", str(tmp_path), "--scene", MICRO, "-o", out]) == 2
    assert "no run.csv" in _error(capsys)
    assert main(["view", str(tmp_path), "-o", out]) == 2
    assert "give --scene SCENE" in _error(capsys)
    forces = tmp_path / "f.csv"
    forces.write_text("t,sigma1,sigma2,sigma3,sigma4,sigma5,sigma6\n0,1,2,3,4,5,6\n")
    assert main(["view", str(forces), "--scene", MICRO, "-o", out]) == 2
    assert "give --trajectory" in _error(capsys)
    junk = tmp_path / "junk.csv"
    junk.write_text("a,b\n1,2\n")
    assert main(["view", str(junk), "--scene", MICRO, "-o", out]) == 2
    assert "not a trajectory" in _error(capsys)
    bad = tmp_path / "bad.csv"
    bad.write_text(",".join(io.TRAJECTORY_COLUMNS) + "\n" + ",".join(["0"] * 18) + ",x\n")
    assert main(["view", str(bad), "--scene", MICRO, "-o", out]) == 2
    assert f"{bad}: line 2, column 'ddthz': not a number: 'x'" in _error(capsys)
    table = tmp_path / "table.csv"      # a run table: its columns by name, in any order
    names = ["torque2", "time", *io.POSE, *(f"{c}_ref" for c in io.POSE),
             *(f"torque{i}" for i in (1, 3, 4, 5, 6))]
    table.write_text(",".join(names) + "\n" + ",".join(["1"] + ["0"] * 18) + "\n"
                     + ",".join(["nan", "0.1"] + ["0"] * 17) + "\n")
    assert main(["view", str(table), "--scene", MICRO, "-o", out]) == 2
    assert f"{table}: line 3, column 'torque2': non-finite value nan" in _error(capsys)
    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.md").write_text("- scene: `no/such/scene.toml`\n")
    shutil.copy(bad, run / "run.csv")
    assert main(["view", str(run), "-o", out]) == 2
    assert "no/such/scene.toml, is not there" in _error(capsys)
    traj = tmp_path / "traj.csv"
    io.write_csv(traj, io.trajectory_table(*demo_trajectory(model, 0.2)))
    assert main(["view", str(traj), "--scene", MICRO, "-o", str(tmp_path)]) == 2
    assert "is a directory" in _error(capsys)
    assert main(["view", str(traj), "--scene", MICRO, "-o", out, "--fps", "0"]) == 2
    assert "--fps" in capsys.readouterr().err        # argparse's usage error
    assert main(["view", str(traj), "--scene", MICRO, "-o", out]) == 0
