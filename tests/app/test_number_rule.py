"""The number rule past the scene: a run whose state turns non-finite stops with one line naming
the sample, the time and the quantity (never a LinAlgError); inputs beyond what a computation
holds are refused by their bounds; derived quantities are checked after they are computed
(the issue's "other inputs" row and the derived checks, each a regression test)."""
from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from controller.design import DesignError, tune_pid
from controller.drive import axis_model
from stewart_fmu import table
from stewart_fmu.native import core
from stewart_sim import cli
from stewart_sim.scene.load import load
from tests.helpers import SCENE_FILES, SCENES_DIR, shipped_scenes


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("stewart-sim: error: ") and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def micro_forces(tmp_path_factory) -> Path:
    """The forces of a short demo move of the micro scene (inverse's output)."""
    folder = tmp_path_factory.mktemp("forces")
    micro = str(SCENE_FILES["micro"])
    assert cli.main(["trajectory", micro, "--move", "demo", "--duration", "0.1",
                     "--out", str(folder / "t.csv")]) == 0
    assert cli.main(["inverse", micro, "--trajectory", str(folder / "t.csv"), "--out",
                     str(folder / "f.csv"), "--no-view"]) == 0
    return folder / "f.csv"


def test_simulate_with_one_force_of_1e308_stops_naming_sample_time_and_quantity(
        tmp_path, capsys, micro_forces):
    """One force of 1e308 N at sample 50: exit 2, one line naming the forces sample, its time
    and what overflowed (was: LinAlgError from the stability advice), nothing written."""
    rows = list(csv.reader(micro_forces.open()))
    rows[51][1] = "1e308"                      # sample 50 (row 0 is the header)
    forces = tmp_path / "f.csv"
    with forces.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    out = tmp_path / "sim"
    assert cli.main(["simulate", str(SCENE_FILES["micro"]), "--forces", str(forces),
                     "--out", str(out)]) == 2
    err = _one_line(capsys)
    assert f"forces sample 50 (t = {float(rows[51][0])!r} s)" in err and "overflowed" in err, err
    assert not out.exists()


def test_cue_with_times_times_1e_300_is_refused_by_the_step_bound(tmp_path, capsys):
    """A vehicle motion whose times are multiplied by 1e-300: exit 2, one line naming the file,
    the line and the step's bounds (was: LinAlgError, a singular filter)."""
    rows = list(csv.reader((SCENES_DIR / "motions" / "braking_car.csv").open()))
    for r in rows[1:]:
        r[0] = repr(float(r[0]) * 1e-300)
    motion = tmp_path / "m.csv"
    with motion.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    out = tmp_path / "cue"
    assert cli.main(["cue", str(SCENE_FILES["sim"]), "--motion", str(motion), "--out", str(out),
                     "--no-view"]) == 2
    err = _one_line(capsys)
    assert str(motion) in err and "line 3, column 't'" in err and "[1e-06, 10] s" in err, err
    assert not out.exists()


@pytest.mark.parametrize("bandwidth", [1e308, 1e200, float("inf")])
def test_gains_from_a_huge_bandwidth_are_a_design_error_not_linalg(bandwidth):
    """The gain computation itself (below the key's bound): DesignError naming the [controller]
    bandwidth, never LinAlgError."""
    scene = load(SCENE_FILES["micro"])
    axis = axis_model(scene.model, scene.controller.motor)
    with pytest.raises(DesignError, match="controller.bandwidth"):
        tune_pid(axis, bandwidth, 60.0)


def test_moving_mass_is_checked_after_it_is_computed():
    """A Model built past the scene reader (dataclasses.replace) with a platform mass of 1e308:
    the core's rules refuse the moving mass it gives, naming platform.mass and the keys."""
    model = load(SCENE_FILES["micro"]).model
    heavy = dataclasses.replace(model, platform_mass=1e308, legs=dataclasses.replace(
        model.legs, lower_mass=1e308))
    rule, vr, _, reason = core.check_rules(heavy.native, heavy.home)
    assert rule == core.RULE_DERIVED and table.group_at(vr).name == "platform.mass"
    assert "moving mass" in reason and "legs.lower_mass 1e+308" in reason and "inf kg" in reason


def test_every_shipped_scene_lies_within_the_bounds():
    """Every scene of scenes/ loads: each value within its key's bounds, every derived
    quantity within its own."""
    for path in shipped_scenes():
        load(path)
