"""`stewart-sim workspace --load`: each grid position's rack-force margin over the envelope's
12 signed axis corners against an independent computation here (stewart_fmu.inverse_dynamics
with the payload at the same poses and accelerations, at rest, minus the drive's force bound),
a payload that binds somewhere and one that binds nowhere, and the refusals of bad input."""
from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest

from controller.capability import drive_bounds
from stewart_fmu.dynamics import inverse_dynamics
from stewart_sim import cli
from stewart_sim.scene.load import load
from stewart_sim.studies.modes.study import payload_from, with_payload

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
ACCEL = (2.0, 2.0, 2.0, 20.0, 20.0, 20.0)   # m/s^2, rad/s^2
STEP = "0.012"                              # m: a coarse grid (a few thousand positions)
AGREE = 1e-9        # relative to the force bound: the same physics, two call paths
TIE = 1e-6          # relative: corners or legs this close are not told apart


def _run(tmp_path: Path, payload: str, capsys) -> tuple[list[dict], str]:
    out = tmp_path / "load"
    assert cli.main(["workspace", str(MICRO), "--load", "--accel", ",".join(map(str, ACCEL)),
                     "--payload", payload, "--resolution", STEP, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert (out / "load.png").stat().st_size > 0
    with open(out / "load.csv", newline="") as f:
        return list(csv.DictReader(f)), text


def _independent(payload: str, rows: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row: the least margin over the 12 corners and 6 legs, and the |sigma| of every
    corner and leg (12, 6) at the row's pose (home's angles, platform frame)."""
    scene = load(str(MICRO))
    model = with_payload(scene.model, payload_from(payload, scene.model))
    bound = drive_bounds(scene.model, scene.controller).force
    corners = np.vstack([s * a * np.eye(6)[k] for k, a in enumerate(ACCEL) for s in (1, -1)])
    q = np.array([[float(r["x"]), float(r["y"]), float(r["z"]), *model.home[3:]]
                  for r in rows])
    Q = np.repeat(q, 12, axis=0)
    sigma = np.abs(inverse_dynamics(model, Q, np.zeros_like(Q), np.tile(corners, (len(q), 1))))
    sigma = sigma.reshape(len(q), 12, 6)
    return bound - sigma.max(axis=(1, 2)), sigma, np.full(len(q), bound)


@pytest.mark.parametrize("payload, binds", [("5", True), ("0.05", False)])
def test_margins_agree_with_inverse_dynamics(payload, binds, tmp_path, capsys):
    rows, text = _run(tmp_path, payload, capsys)
    assert len(rows) > 1000
    margin = np.array([float(r["margin_n"]) for r in rows])
    expect, sigma, bound = _independent(payload, rows)
    assert np.all(np.abs(margin - expect) <= AGREE * bound)
    names = [f"{s}{a}" for a in ("ax", "ay", "az", "alx", "aly", "alz") for s in "+-"]
    for k, r in enumerate(rows):   # the named leg and corner carry the least margin
        c, leg = names.index(r["corner"]), int(r["leg"]) - 1
        assert abs(sigma[k, c, leg] - sigma[k].max()) <= TIE * bound[k]
    fraction = float(re.search(r"binds on ([0-9.e+-]+) % of the reachable volume", text)[1])
    assert fraction == pytest.approx(100 * np.mean(expect < 0), abs=1e-3)
    assert (fraction > 0) == binds
    assert np.any(expect < 0) == binds


def test_scene_payload_is_used_without_the_option(tmp_path, capsys):
    """A scene's [payload] gives the margins --payload gives with the same table."""
    table = "[payload]\nmass = 3.0\ncom = [0.0, 0.0, 0.02]\ninertia = [0.01, 0.01, 0.02]\n"
    scene = tmp_path / "micro.toml"
    scene.write_text(MICRO.read_text() + "\n" + table)
    keys = tmp_path / "payload.toml"
    keys.write_text(table)
    got = {}
    for name, args in (("scene", [str(scene)]), ("option", [str(MICRO), "--payload", str(keys)])):
        out = tmp_path / name
        assert cli.main(["workspace", *args, "--load", "--accel", "1,1,1,10,10,10",
                         "--resolution", "0.02", "--out", str(out)]) == 0
        got[name] = (out / "load.csv").read_text()
    capsys.readouterr()
    assert got["scene"] == got["option"]


@pytest.mark.parametrize("accel, reason", [
    ("1,2,3", "need six finite numbers"),
    ("1,2,3,4,5,nan", "need six finite numbers"),
    ("1,2,3,4,5,inf", "need six finite numbers"),
    ("1,2,3,4,5,-1", "must be >= 0"),
])
def test_bad_accel_is_one_line_exit_2(accel, reason, tmp_path, capsys):
    out = tmp_path / "load"
    assert cli.main(["workspace", str(MICRO), "--load", "--accel", accel,
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--accel" in err and reason in err
    assert not out.exists()


def test_load_needs_accel_and_out(tmp_path, capsys):
    assert cli.main(["workspace", str(MICRO), "--load", "--out", str(tmp_path / "o")]) == 2
    assert "--load needs --accel" in capsys.readouterr().err
    assert cli.main(["workspace", str(MICRO), "--load", "--accel", "1,1,1,1,1,1"]) == 2
    assert "--load needs --out DIR" in capsys.readouterr().err
