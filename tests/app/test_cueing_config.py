"""The scene's [cueing.optimal] sub-table (stewart_sim/scene/cueing_config.py `optimal_options`):
every
OptimalOptions field is a key; a scene without the sub-table gives OptimalOptions() exactly and
the shipped simulator's written-out sub-table is those defaults; each bad value is refused
naming `cueing.optimal.<key>` (also by the `cue` command: one line, exit 2); a changed option
reaches the solver (the MPC steps of `cue --mode optimal` follow the scene's rate); scene-info
shows the sub-table."""
from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from stewart_fmu import load_scene, scene_from_dict
from stewart_fmu.errors import SceneError
from stewart_sim.cueing.optimal import optimal_cueing
from stewart_sim.cueing.study import make_cue
from stewart_sim.scene.cueing_config import (
    DEFAULTS,
    MPC_STEPS,
    OptimalOptions,
    cueing_config,
    optimal_options,
)
from stewart_sim.scene.describe import describe
from stewart_sim.scene.load import scene_of
from tests.helpers import ROOT, scene_dict
from tests.helpers import vehicle_motion as motion

SIM = ROOT / "scenes" / "motion_simulator.toml"


def with_optimal(**keys) -> dict:
    """The simulator's scene dict with these [cueing.optimal] keys set over the shipped ones."""
    data = scene_dict("sim")
    data["cueing"]["optimal"].update(keys)
    return data


def test_every_option_is_a_scene_key():
    """All OptimalOptions fields are tuning parameters: none is left out of the table."""
    every = {f.name: getattr(OptimalOptions(), f.name) for f in dataclasses.fields(OptimalOptions)}
    data = scene_dict("sim")
    data["cueing"]["optimal"] = {k: (list(v) if isinstance(v, tuple) else v)
                                 for k, v in every.items() if v is not None}
    data["cueing"]["optimal"]["tilt_rate_limit"] = 0.1
    assert optimal_options(scene_from_dict(data)) == OptimalOptions(tilt_rate_limit=0.1)


def test_no_sub_table_is_the_defaults_exactly():
    data = scene_dict("sim")
    del data["cueing"]["optimal"]
    assert optimal_options(scene_from_dict(data)) == OptimalOptions()
    data["cueing"]["optimal"] = {}
    assert optimal_options(scene_from_dict(data)) == OptimalOptions()
    del data["cueing"]
    assert optimal_options(scene_from_dict(data)) == OptimalOptions()


def test_the_shipped_scene_writes_out_the_defaults():
    """scenes/motion_simulator.toml's [cueing] (classical) and [cueing.optimal] are the
    defaults written out: every figure made on it is the defaults' figure."""
    model = load_scene(SIM)
    assert set(model.extra["cueing"]["optimal"]) == (
        {f.name for f in dataclasses.fields(OptimalOptions)} - {"tilt_rate_limit"})
    assert optimal_options(model) == OptimalOptions()
    assert cueing_config(model) == DEFAULTS


def test_changed_options_are_read():
    data = with_optimal(rate=10, horizon=1.5, preview=False, stroke_margin=0.05,
                        force_margin=0.0, tilt_rate_limit=0.1,
                        perception_weight=[2, 2, 1, 1, 1, 0.5], slack_weight=[10, 20],
                        tolerance=1e-4, max_iter=500)
    options = optimal_options(scene_from_dict(data))
    assert options == dataclasses.replace(
        OptimalOptions(), rate=10.0, horizon=1.5, preview=False, stroke_margin=0.05,
        force_margin=0.0, tilt_rate_limit=0.1, perception_weight=(2.0, 2.0, 1.0, 1.0, 1.0, 0.5),
        slack_weight=(10.0, 20.0), tolerance=1e-4, max_iter=500)
    assert isinstance(options.rate, float) and isinstance(options.max_iter, int)


@pytest.mark.parametrize("key, value, reason", [
    ("step", 0.1, "unknown key"),
    ("rate", 0.0, "finite number > 0"),
    ("rate", -20.0, "finite number > 0"),
    ("rate", float("nan"), "finite number > 0"),
    ("rate", "20", "finite number > 0"),
    ("rate", True, "finite number > 0"),
    ("horizon", 0.0, "finite number > 0"),
    ("horizon", float("inf"), "finite number > 0"),
    ("horizon", 0.05, f"{MPC_STEPS[0]} to {MPC_STEPS[1]} MPC steps, got 0.05 s x 20 Hz = 1"),
    ("horizon", 10.5, "MPC steps, got 10.5 s x 20 Hz = 210"),
    ("preview", 1, "true or false"),
    ("preview", "yes", "true or false"),
    ("stroke_margin", -0.01, ">= 0"),
    ("stroke_margin", 0.8, "below half the stroke (0.8 m)"),
    ("force_margin", 1.0, "below 1"),
    ("force_margin", -0.1, ">= 0"),
    ("voltage_margin", 1.5, "below 1"),
    ("tilt_rate_limit", 0.0, "finite number > 0"),
    ("perception_weight", [1.0, 1.0, 1.0], "list of 6 numbers"),
    ("perception_weight", [1.0, 1.0, 1.0, 1.0, 1.0, -1.0], ">= 0"),
    ("position_weight", 1.0, "list of 3 numbers"),
    ("velocity_weight", [1.0, float("nan"), 1.0], "finite number"),
    ("yaw_weight", -1.0, ">= 0"),
    ("rate_weight", [0.0, 0.0], "list of 3 numbers"),
    ("acceleration_weight", [0.01, -0.01, 0.01], ">= 0"),
    ("angular_acceleration_weight", ["a", 0.01, 0.01], "finite number"),
    ("slack_weight", [1000.0, 0.0], "finite number > 0"),
    ("slack_weight", [1000.0], "list of 2 numbers"),
    ("terminal_weight", -1.0, ">= 0"),
    ("tolerance", 0.0, "finite number > 0"),
    ("max_iter", 0, "integer >= 1"),
    ("max_iter", 100.0, "integer >= 1"),
    ("max_iter", True, "integer >= 1"),
])
def test_bad_values_name_the_key(key, value, reason):
    """Refused by optimal_options, and by cueing_config too (the table is checked whole: a
    typo in the sub-table fails the classical mode as well)."""
    model = scene_from_dict(with_optimal(**{key: value}))
    for read in (optimal_options, cueing_config):
        with pytest.raises(SceneError, match=re.escape(reason)) as err:
            read(model)
        assert err.value.key == f"cueing.optimal.{key}"


def test_the_sub_table_must_be_a_table():
    data = scene_dict("sim")
    data["cueing"]["optimal"] = 3
    with pytest.raises(SceneError, match="must be a table") as err:
        optimal_options(scene_from_dict(data))
    assert err.value.key == "cueing.optimal"


def test_steps_bound_is_round_horizon_times_rate():
    """The bounds themselves are allowed: 2 steps and 200 steps."""
    low = optimal_options(scene_from_dict(with_optimal(rate=20, horizon=0.1)))
    high = optimal_options(scene_from_dict(with_optimal(rate=20, horizon=10.0)))
    assert round(low.horizon * low.rate) == MPC_STEPS[0] == 2
    assert round(high.horizon * high.rate) == MPC_STEPS[1] == 200


def test_the_scene_rate_reaches_the_solver():
    """The `cue` command's optimal mode (make_cue) runs at the scene's rate: 10 Hz on a 12 s
    motion is 120 MPC steps 0.1 s apart, the cue optimal_cueing gives with the
    same options directly; a gentle braking pulse, solved at every step."""
    t = np.arange(0.0, 12.0, 0.01)
    f_dev = np.zeros((t.size, 3))
    f_dev[(t >= 1.0) & (t < 3.0), 0] = -1.0
    mo = motion(t, f_dev)
    model = scene_from_dict(with_optimal(rate=10, horizon=1.5))
    config = cueing_config(model)
    cue, solver = make_cue("optimal", scene_of(model), config, mo)
    assert solver is not None and solver.t.size == 120
    np.testing.assert_allclose(np.diff(solver.t), 0.1, rtol=0, atol=1e-12)
    assert solver.status_counts == {"solved": 120}
    direct = optimal_cueing(model, config, mo, model.home, model.gravity,
                            controller=scene_of(model).controller,
                            options=OptimalOptions(rate=10.0, horizon=1.5))
    assert direct.diagnostics.t.size == 120
    np.testing.assert_array_equal(cue.q, direct.cue.q)


def test_the_cue_command_refuses_a_bad_option_in_one_line(tmp_path):
    text = SIM.read_text()
    assert text.count("\nhorizon = 2.0 ") == 1
    scene = tmp_path / "sim.toml"
    scene.write_text(text.replace("\nhorizon = 2.0 ", "\nhorizon = 0.0 "))
    out = tmp_path / "cue"
    done = subprocess.run([sys.executable, "-m", "stewart_sim", "cue", str(scene), "--motion",
                           str(ROOT / "scenes" / "motions" / "braking_car.csv"), "--mode",
                           "optimal", "--out", str(out)], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "cueing.optimal.horizon" in lines[0], done.stderr
    assert "Traceback" not in done.stderr and not out.exists()


def test_scene_info_shows_the_sub_table():
    text = describe(scene_of(scene_from_dict(with_optimal(rate=10, preview=False))))
    line = next(x for x in text.splitlines() if x.startswith("cueing.optimal:"))
    assert "at 10 Hz over 2 s (20 steps), preview off" in line
    assert "tilt rate limit the [cueing] tilt_rate_limit" in line
    data = scene_dict("sim")
    del data["cueing"]["optimal"]
    assert "cueing.optimal:" not in describe(scene_of(scene_from_dict(data)))


def test_every_key_is_documented_with_its_default():
    """docs/scene-format.md's [cueing.optimal] table lists exactly the OptimalOptions fields,
    each with the default OptimalOptions() holds (tilt_rate_limit: the [cueing] one)."""
    doc = (ROOT / "docs" / "scene-format.md").read_text()
    section = doc.split("### `[cueing.optimal]`", 1)[1].split("\n## ", 1)[0]
    rows = {m.group(1): m.group(2) for m in
            re.finditer(r"^\| `(\w+)` \| [^|]+ \| ([^|]+) \|", section, re.MULTILINE)}
    assert set(rows) == {f.name for f in dataclasses.fields(OptimalOptions)}
    for name, text in rows.items():
        default = getattr(OptimalOptions(), name)
        if default is None:
            assert "tilt_rate_limit" in text
        elif isinstance(default, bool):
            assert text.strip() == str(default).lower()
        else:
            assert np.array_equal(np.atleast_1d(json.loads(text)), np.atleast_1d(default)), name
