"""The numbers at the edges of `calibrate` and `size`: inputs
beyond physical bounds refused in one line naming them (exit 2, nothing written), every result
checked finite before the first file, the counts an input implies checked against the memory
budget before allocating, a user's text escaped where it lands in Markdown; and seeded,
bounded fuzzing of both commands' inputs: never a traceback, never a non-finite result
accepted."""
from __future__ import annotations

import dataclasses
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from controller.moves import demo_trajectory
from stewart_fmu import load_scene
from stewart_fmu.budget import MEMORY_BUDGET, BudgetError
from stewart_fmu.errors import StewartError
from stewart_fmu.io import named_array, write_csv
from stewart_fmu.scene import read_scene_dict
from stewart_sim import cli
from stewart_sim.cueing.feasibility import Margin
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.studies.calibrate import study
from stewart_sim.studies.sizing import catalogue as catalogue_module
from stewart_sim.studies.sizing import study as sizing
from stewart_sim.studies.sizing.motions import Motion
from stewart_sim.studies.sizing.report import report_markdown

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
POSES = ROOT / "scenes" / "poses" / "micro_manipulator.csv"
SIM = ROOT / "scenes" / "motion_simulator.toml"
BRAKING = ROOT / "scenes" / "motions" / "braking_car.csv"
HEADER = ",".join(catalogue_module.COLUMNS[:-1])     # without mass: ranked by price
GOOD = "A,10,0.04,0.002,40,15,400,1000"
HOSTILE = [1e300, -1e300, 1e-300, -1e-300, 5e-324, 0.0, 1e10, -1e10, 1e6, 3 * math.pi, 100.0]


def _one_line(capsys, words: str) -> str:
    err = capsys.readouterr().err
    assert err.startswith("stewart-sim: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and words in err, err
    return err


# --- calibrate: defects 6 and 7 -------------------------------------------------------------

def _poses_file(path: Path, change) -> Path:
    table = study.pose_table(study.read_poses(POSES))
    change(table)
    write_csv(path, named_array(table))
    return path


@pytest.mark.parametrize("change, words", [
    (lambda t: t["x"].fill(1e300),                              # defect 6: was a traceback
     "line 2, column 'x': 1e+300 is more than the machine's size"),
    (lambda t: t["l3"].__setitem__(4, 1e300),                   # defect 7: was exit 0, std inf
     "line 6, column 'l3': 1e+300 is above"),
    (lambda t: t["thz"].__setitem__(7, 40.0), "line 9, column 'thz': 40.0 is beyond +-2 pi rad"),
])
def test_calibrate_refuses_poses_beyond_physical_bounds(tmp_path, capsys, change, words):
    path = _poses_file(tmp_path / "P.csv", change)
    out = tmp_path / "cal"
    assert cli.main(["calibrate", str(MICRO), "--poses", str(path), "--out", str(out)]) == 2
    _one_line(capsys, f"{path}: {words}")
    assert not out.exists()


def test_calibrate_refuses_a_non_finite_result_before_writing(tmp_path, capsys, monkeypatch):
    """Numerical trouble the bounds do not foresee (an estimate gone NaN): one line naming the
    poses file, exit 2, no file written."""
    calibrate = study.calibrate

    def troubled(*args, **kwargs):
        cal = calibrate(*args, **kwargs)
        return dataclasses.replace(cal, std=np.where(cal.observable, np.inf, cal.std))
    monkeypatch.setattr(study, "calibrate", troubled)
    out = tmp_path / "cal"
    assert cli.main(["calibrate", str(MICRO), "--poses", str(POSES), "--out", str(out)]) == 2
    _one_line(capsys, f"{POSES}: the calibration's standard deviations are not finite")
    assert not out.exists()


def test_calibrate_checks_the_poses_against_the_memory_budget():
    """A count of poses whose working arrays would not fit is refused before they exist
    (zero-copy views stand for the rows)."""
    n = MEMORY_BUDGET // study.POSE_BYTES + 1
    data = study.read_poses(POSES)
    huge = study.PoseSet(np.broadcast_to(data.poses[0], (n, 6)),
                         np.broadcast_to(data.lengths[0], (n, 6)))
    with pytest.raises(BudgetError, match=re.escape(f"poses: {n:.4g} are more than the")):
        study.calibrate(load_scene(MICRO), huge)


# --- size: defect 9, the budget, a user's text in report.md ----------------------------------

@pytest.mark.parametrize("row, words", [
    ("A,1e-300,0.04,0.002,40,15,400,1000",                         # defect 9: was exit 0, inf
     "line 2, column 'gear_ratio': must be >= 0.01, got 1e-300"),
    ("A,10,0.04,0.002,1e-300,1e-300,400,1000", "line 2, column 'peak_torque': must be >= 1e-06"),
    ("A,10,0.04,0.002,40,15,1e-300,1000", "line 2, column 'max_speed': must be >= 0.001"),
])
def test_size_refuses_a_drive_beyond_physical_bounds(tmp_path, capsys, row, words):
    path = tmp_path / "drives.csv"
    path.write_text(f"{HEADER}\n{row}\n")
    out = tmp_path / "out"
    assert cli.main(["size", str(SIM), "--motions", str(BRAKING), "--catalogue", str(path),
                     "--out", str(out)]) == 2
    _one_line(capsys, f"{path}: {words}")
    assert not out.exists()


@pytest.fixture(scope="module")
def short_motion() -> tuple[dict, Motion]:
    """The motion simulator's scene (as a dict) and 2 s of its demo move: a fast drive
    evaluation."""
    t, q, qd, qdd = demo_trajectory(load_scene(SIM), 2.0)
    return read_scene_dict(SIM), Motion("demo", "platform", t, q, qd, qdd)


def _drive(**change) -> catalogue_module.Drive:
    return dataclasses.replace(catalogue_module.Drive("A", 10.0, 0.04, 0.002, 40.0, 15.0, 400.0,
                                                      1000.0), **change)


def test_size_refuses_a_non_finite_result_before_writing(short_motion):
    """A drive's check that came out inf (numerical trouble the bounds do not foresee) is
    refused naming the catalogue and the drive; a finite one passes."""
    scene, motion = short_motion
    good = sizing.evaluate_drive(scene, str(SIM), _drive(), [motion])
    empty = sizing.SceneSizing((), (), None, None)
    sizing.check_finite(empty, [good], "drives.csv")
    check = good.motions[0].checks[0]
    bad_check = Margin(check.quantity, math.inf, math.inf, check.limit, check.unit, check.t,
                       check.sample, check.leg)
    bad = dataclasses.replace(good, motions=(dataclasses.replace(
        good.motions[0], checks=(bad_check, *good.motions[0].checks[1:])),))
    with pytest.raises(sizing.SizingError,
                       match="drives.csv: drive 'A' on demo: torque_peak .* is not finite"):
        sizing.check_finite(empty, [good, bad], "drives.csv")


def test_size_checks_drives_times_motions_against_the_memory_budget(short_motion):
    _, motion = short_motion
    fits = MEMORY_BUDGET // sizing.RESULT_BYTES
    sizing.check_budget([_drive()] * fits, [motion], "drives.csv")
    with pytest.raises(BudgetError, match=r"drives.csv: \d+ drives x 3 motions: results"):
        sizing.check_budget([_drive()] * (fits // 3 + 1), [motion] * 3, "drives.csv")


def test_a_drives_name_lands_in_report_md_as_text(short_motion):
    """A catalogue name holding a table's bar, HTML and a line break: one table row, shown
    as the characters it holds."""
    scene, motion = short_motion
    name = "SG|X <script>alert(1)</script>\n| 9 | fake row |"
    result = sizing.evaluate_drive(scene, str(SIM), _drive(name=name), [motion])
    model = load_scene(SIM)
    text = report_markdown(model, [motion], sizing.size_scene(model, None, [motion]),
                           sizing.CatalogueSweep((result,), 1, None), [result], 0.2,
                           "a <b>title</b>", ["report.md"])
    assert "<script>" not in text and "<b>" not in text and "| 9 |" not in text
    row = next(line for line in text.splitlines() if "alert" in line)
    assert row.startswith("| 1 | SG\\|X &lt;script&gt;alert(1)&lt;/script&gt; \\| 9 \\| fake "
                          "row \\| | 10 |")
    assert len(re.findall(r"(?<!\\)\|", row)) == 12        # eleven cells, as the header


def test_markdown_escaping_renders_the_text_itself():
    assert md_text("a_b*c`d[e]f|g~h\\i") == "a\\_b\\*c\\`d\\[e\\]f\\|g\\~h\\\\i"
    assert md_text("x < y & z > w\r\nv") == "x &lt; y &amp; z &gt; w  v"
    assert md_code("run.csv") == "`run.csv`" and md_code("a``b") == "```a``b```"
    assert md_code("`x\ny`") == "`` `x y` ``"


# --- fuzzing: never a traceback, never a non-finite result accepted -------------------------

def _fuzzed_poses(rng: np.random.Generator, data: study.PoseSet) -> study.PoseSet:
    rows = rng.choice(len(data.poses), int(rng.integers(8, 30)), replace=False)
    values = np.column_stack([data.poses[rows], data.lengths[rows]])
    kind = rng.integers(4)
    if kind == 0:                       # hostile cells
        for _ in range(int(rng.integers(1, 4))):
            values[rng.integers(len(values)), rng.integers(12)] = rng.choice(HOSTILE)
    elif kind == 1:                     # one pose repeated: nothing observable
        values[:] = values[0]
    elif kind == 2:                     # lengths scaled: another machine's encoders
        values[:, 6:] *= rng.choice([1e-6, 1e-3, 3.0])
    else:                               # noise of any size on the poses
        values[:, :6] += rng.normal(0, rng.choice([1e-9, 1e-3, 1e-1]), (len(values), 6))
    return study.PoseSet(values[:, :6], values[:, 6:])


@pytest.mark.numerics       # Levenberg-Marquardt's outcome on hostile poses
def test_fuzz_calibrate(tmp_path):
    """120 seeded hostile pose sets through what the command does before writing (bounds,
    calibration, finiteness): a one-line StewartError, or a result finite where documented,
    and no warning from numpy or LAPACK."""
    model = load_scene(MICRO)
    data = study.read_poses(POSES)
    rng = np.random.default_rng(3406)
    refused = 0
    for case in range(120):
        fuzzed = _fuzzed_poses(rng, data)
        select = int(rng.integers(8, len(fuzzed.poses) + 1)) if rng.random() < 0.3 else None
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                study.check_bounds(model, fuzzed, "P.csv")
                cal = study.calibrate(model, fuzzed, select)
                study.check_finite(cal, "P.csv")
            except StewartError as exc:
                assert "\n" not in str(exc) and str(exc).startswith(("P.csv", "poses")), exc
                refused += 1
                continue
        assert np.isfinite(cal.estimate).all() and np.isfinite(cal.residuals).all(), case
        assert np.isfinite(cal.std[cal.observable]).all(), case
    assert 0 < refused < 120          # both outcomes were exercised


def _fuzzed_row(rng: np.random.Generator) -> str:
    cells = GOOD.split(",")
    for _ in range(int(rng.integers(1, 3))):
        column = int(rng.integers(8))
        cells[column] = (rng.choice(["A|<i>\nx", "", " ", "nan", "-inf", "1e999", "0x10", "Ω"])
                         if column == 0 or rng.random() < 0.2 else repr(float(rng.choice(HOSTILE))))
    return ",".join(f'"{c}"' if "\n" in c or "," in c else c for c in cells)


def test_fuzz_size_catalogue(tmp_path, short_motion):
    """80 seeded hostile catalogue rows: each refused in one line naming the file, or a drive
    whose evaluation is finite (or names its error) and whose report.md stays one row."""
    scene, motion = short_motion
    model = load_scene(SIM)
    scene_sizing = sizing.size_scene(model, None, [motion])
    rng = np.random.default_rng(3409)
    path = tmp_path / "drives.csv"
    accepted = 0
    for case in range(80):
        path.write_text(f"{HEADER}\n{_fuzzed_row(rng)}\n")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                drives = catalogue_module.read_catalogue(path)
                result = sizing.evaluate_drive(scene, str(SIM), drives[0], [motion])
                sizing.check_finite(scene_sizing, [result], str(path))
            except StewartError as exc:
                assert "\n" not in str(exc) and str(exc).startswith(str(path)), exc
                continue
        accepted += 1
        for m in result.motions:
            assert all(math.isfinite(c.ratio) for c in m.checks), case
        text = report_markdown(model, [motion], scene_sizing,
                               sizing.CatalogueSweep((result,), 1, None), [result], 0.2, "t",
                               ["report.md"])
        assert "<i>" not in text
    assert 0 < accepted < 80
