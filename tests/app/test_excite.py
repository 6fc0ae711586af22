"""Excitation trajectories (stewart_sim.studies.excite, `stewart-sim excite`): the Fourier series at
rest
at home at both ends and periodic, its derivatives exact; the command's trajectory on the
micro-manipulator recomputed from the file it writes: the condition number of the stacked base
regressor at or below the issue's 100, every limit kept with the margins it reports, read back
by the trajectory reader and run through `inverse`; bad input refused in one line."""
from __future__ import annotations

import contextlib
import io as text_io
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controller.drive import axis_model
from stewart_fmu import io
from stewart_fmu.dynamics import inverse_dynamics, regressor
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim import cli
from stewart_sim.cueing.feasibility import COND_LIMIT, feasibility
from stewart_sim.scene.load import load
from stewart_sim.studies.excite.bounds import LIMIT_FRACTION, STROKE_MARGIN
from stewart_sim.studies.excite.design import PERIOD, PERIODS
from stewart_sim.studies.excite.fourier import FourierSeries
from stewart_sim.studies.excite.report import figure
from stewart_sim.studies.identify.base import scaled_condition, stacked, structural_base
from tests.app.test_plot_labels import check_figure

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
GOAL = 100.0        # the condition number on the micro-manipulator


def random_series(harmonics: int = 5, period: float = 5.0, seed: int = 3):
    rng = np.random.default_rng(seed)
    home = np.array([0.01, -0.02, 0.12, 0.05, -0.03, 0.2])
    series = FourierSeries(period, harmonics, home, np.array([0.01] * 3 + [0.1] * 3))
    return series, rng.standard_normal(series.size)


# --- the series ----------------------------------------------------------------------------

@pytest.mark.parametrize("harmonics", [2, 5, 8])
def test_at_rest_at_home_at_both_ends(harmonics):
    series, x = random_series(harmonics)
    periods = 3
    q, qd, qdd = series.evaluate(x, np.array([0.0, periods * series.period]))
    assert np.abs(q - series.home).max() < 1e-13
    assert np.abs(qd).max() < 1e-13 and np.abs(qdd).max() < 1e-12
    # and it moves in between: the constraints do not pin it
    q, qd, qdd = series.evaluate(x, np.linspace(0.0, series.period, 101))
    assert np.abs(qd).max() > 1e-3 and np.abs(q - series.home).max() > 1e-3


def test_periodic_and_band_limited():
    series, x = random_series()
    t = np.random.default_rng(1).uniform(0.0, series.period, 50)
    for a, b in zip(series.evaluate(x, t), series.evaluate(x, t + 2 * series.period)):
        assert np.abs(a - b).max() < 1e-12
    # no polynomial correction: the spectrum of one period holds the H harmonics and nothing
    # above them
    n = 512
    q = series.evaluate(x, np.arange(n) * series.period / n)[0]
    spectrum = np.abs(np.fft.rfft(q, axis=0))
    assert spectrum[series.harmonics + 1:].max() < 1e-12 * spectrum.max()


def test_rates_and_accelerations_are_the_derivatives():
    series, x = random_series()
    h = 1e-5
    t = np.linspace(0.3, 4.7, 23)
    q_m, qd_m, _ = series.evaluate(x, t - h)
    q_p, qd_p, _ = series.evaluate(x, t + h)
    _, qd, qdd = series.evaluate(x, t)
    assert np.abs((q_p - q_m) / (2 * h) - qd).max() < 1e-8 * np.abs(qd).max()
    assert np.abs((qd_p - qd_m) / (2 * h) - qdd).max() < 1e-7 * np.abs(qdd).max()


def test_coefficients_meet_the_rest_constraints():
    series, x = random_series()
    q0, a, b = series.coefficients(x)
    k = np.arange(1, series.harmonics + 1)
    assert np.abs(a.sum(axis=1)).max() < 1e-14                       # qd(0) = 0
    assert np.abs((k * b).sum(axis=1)).max() < 1e-13                 # qdd(0) = 0 / w_f
    assert np.abs(q0 - (b / (k * series.omega)).sum(axis=1) - series.home).max() < 1e-15


# --- the command on the micro-manipulator --------------------------------------------------

@pytest.fixture(scope="module")
def excited(tmp_path_factory):
    """`excite` with its defaults on the micro-manipulator: (T.csv, its printed lines)."""
    out = tmp_path_factory.mktemp("excite") / "T.csv"
    printed = text_io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert cli.main(["excite", str(MICRO), "--out", str(out)]) == 0
    return out, printed.getvalue()


@pytest.fixture(scope="module")
def scene():
    return load(MICRO)


def test_writes_the_trajectory_the_report_and_the_figure(excited, scene):
    out, printed = excited
    assert out.with_suffix(".md").is_file() and out.with_suffix(".png").is_file()
    t, q, qd, qdd = io.read_trajectory(out)          # the reader of `inverse` and `run`
    assert t.size == round(PERIODS * PERIOD * scene.controller.rate) + 1
    assert np.allclose(np.diff(t), 1.0 / scene.controller.rate, rtol=0, atol=1e-12)
    assert t[-1] == pytest.approx(PERIODS * PERIOD)
    for k in (0, -1):                                  # at rest at home at both ends
        assert np.abs(q[k] - scene.model.home).max() < 1e-12
        assert np.abs(qd[k]).max() < 1e-12 and np.abs(qdd[k]).max() < 1e-11
    n = round(PERIOD * scene.controller.rate)          # periodic
    assert np.abs(q[n:] - q[:-n]).max() < 1e-12
    report = out.with_suffix(".md").read_text(encoding="utf-8")
    assert "31 base parameters" in report and "| leg speed |" in report


@pytest.mark.numerics
def test_condition_number_reaches_the_goal(excited, scene):
    """Recomputed from the file: the base regressor stacked over every sample, scaled."""
    out, printed = excited
    t, q, qd, qdd = io.read_trajectory(out)
    model = scene.model
    base = structural_base(model)
    assert base.rank == 31
    cond = scaled_condition(stacked(regressor(model, q, qd, qdd)[:, :, base.independent]))
    reported = float(re.search(r"base regressor: ([0-9.]+)", printed).group(1))
    assert cond == pytest.approx(reported, rel=1e-3)
    assert cond <= GOAL, cond


@pytest.mark.numerics
def test_inside_every_limit_with_the_margins_reported(excited, scene):
    """Each limit recomputed from the file by the kinematics, the dynamics and the drive."""
    out, printed = excited
    t, q, qd, qdd = io.read_trajectory(out)
    model, controller = scene.model, scene.controller
    kin = inverse_kinematics(model, q, qd, qdd)
    axis = axis_model(model, controller.motor)
    sigma = inverse_dynamics(model, q, qd, qdd)       # refuses a pose past the stroke
    voltage = feasibility(model, t, q, qd, qdd, controller).voltage
    span = model.leg_max - model.leg_min
    shortest, longest = kin.lengths.min(), kin.lengths.max()
    assert shortest >= model.leg_min + STROKE_MARGIN * span
    assert longest <= model.leg_max - STROKE_MARGIN * span
    peaks = {"leg speed": (np.abs(kin.rates).max(), axis.no_load_speed),
             "leg acceleration": (np.abs(kin.accelerations).max(), axis.peak_acceleration),
             "rack force": (np.abs(sigma).max(), axis.peak_force),
             "motor voltage": (np.abs(voltage).max(), controller.motor.voltage_limit)}
    # the force limit is Kt zeta / r x current_limit, here by hand
    d = model.drive
    assert axis.peak_force == pytest.approx(controller.motor.current_limit
                                            * controller.motor.torque_constant
                                            * d.gear_ratio / d.pinion_radius)
    for label, (peak, limit) in peaks.items():
        assert peak <= LIMIT_FRACTION * limit, (label, peak, limit)
        line = re.search(rf"{label}: peak ([0-9.e+-]+) \S+ of ([0-9.e+-]+)", printed)
        assert float(line.group(1)) == pytest.approx(peak, rel=1e-3), label
        assert float(line.group(2)) == pytest.approx(limit, rel=1e-3), label
    assert kin.cond.max() <= LIMIT_FRACTION * COND_LIMIT
    assert float(re.search(r"cond\(J\): worst ([0-9.]+)", printed).group(1)) == \
        pytest.approx(kin.cond.max(), rel=1e-2)
    stroke = re.search(r"shortest leg ([0-9.]+) mm, ([0-9.]+) mm from leg_min; longest "
                       r"([0-9.]+) mm, ([0-9.]+) mm from leg_max", printed)
    assert [float(v) for v in stroke.groups()] == pytest.approx(
        [shortest * 1e3, (shortest - model.leg_min) * 1e3, longest * 1e3,
         (model.leg_max - longest) * 1e3], abs=0.006)


def test_inverse_runs_on_it(excited, tmp_path):
    out, _ = excited
    forces = tmp_path / "F.csv"
    assert cli.main(["inverse", str(MICRO), "--trajectory", str(out), "--out", str(forces),
                     "--no-view"]) == 0
    assert io.read_samples(forces, io.FORCE_COLUMNS, "forces", prefix=True).shape[0] == \
        round(PERIODS * PERIOD * 1000) + 1


def test_figure_has_units(excited, scene):
    from stewart_sim.studies.excite.design import design, excitation
    d = design(scene.model, scene.controller, starts=1, max_iterations=2, polish=0)
    check_figure(figure(scene.model, excitation(scene.model, scene.controller, d, 2, 100.0)))


# --- bad input -----------------------------------------------------------------------------

def no_room(tmp_path: Path) -> Path:
    """The micro-manipulator with leg_min a few mm below the home leg length (128.6 mm),
    within the margin kept (5 % of the stroke)."""
    text = MICRO.read_text(encoding="utf-8").replace("leg_min = 0.07", "leg_min = 0.127")
    path = tmp_path / "tight.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("case, words", [
    ("duration", "--duration 7 s is not a whole number of periods of 5 s"),
    ("negative", "--duration: must be a finite number of seconds > 0"),
    ("unknown", "missing.toml"),
    ("no room", "no room to move"),
    ("out", "the trajectory cannot be a .md file"),
    ("harmonics", "--harmonics: must be a whole number >= 2"),
])
def test_bad_input_in_one_line(tmp_path, capsys, case, words):
    scene, out, extra = str(MICRO), tmp_path / "T.csv", []
    if case == "duration":
        extra = ["--duration", "7"]
    elif case == "negative":
        extra = ["--duration", "-5"]
    elif case == "unknown":
        scene = str(tmp_path / "missing.toml")
    elif case == "no room":
        scene = str(no_room(tmp_path))
    elif case == "out":
        out = tmp_path / "T.md"
    elif case == "harmonics":
        extra = ["--harmonics", "1"]
    assert cli.main(["excite", scene, "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    if case in ("negative", "harmonics"):    # argparse's usage, then its one line
        err = err[-1:]
    assert len(err) == 1 and words in err[0], err
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_no_room_is_refused_before_any_optimisation(tmp_path):
    from stewart_fmu.errors import StewartError
    from stewart_sim.studies.excite.bounds import limits
    tight = load(no_room(tmp_path))
    with pytest.raises(StewartError, match="mm from an end of its stroke"):
        limits(tight.model, tight.controller)
    free = replace(tight.model, leg_min=None, leg_max=None)
    with pytest.raises(StewartError, match="gives no stroke"):
        limits(free, tight.controller)


@pytest.mark.numerics
def test_a_scene_without_a_motor_keeps_its_stroke_and_cond(tmp_path, capsys):
    """No [controller]: speed, acceleration, force and voltage are not limited (and said so),
    the stroke and cond(J) still are; the trajectory at 1 kHz."""
    text = MICRO.read_text(encoding="utf-8").split("# Per-axis drive controllers")[0]
    path = tmp_path / "no_motor.toml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "T.csv"
    assert cli.main(["excite", str(path), "--out", str(out), "--duration", "10",
                     "--starts", "1"]) == 0
    printed = capsys.readouterr().out
    assert "no [controller] table" in printed and "leg speed: peak" not in printed
    t, q, _, _ = io.read_trajectory(out)
    assert t.size == 10_001
    model = load(path).model
    lengths = inverse_kinematics(model, q).lengths
    span = model.leg_max - model.leg_min
    assert lengths.min() >= model.leg_min + STROKE_MARGIN * span
    assert lengths.max() <= model.leg_max - STROKE_MARGIN * span
    assert "| rack force | " in out.with_suffix(".md").read_text(encoding="utf-8")


# --- counts against the memory budget, and hostile values -----------------------

@pytest.mark.parametrize("extra, words", [
    # the series' bases alone would take 80 GB (past LAPACK's 32-bit integers)
    (["--harmonics", "100000"], "--harmonics 100000: entries of the series' bases"),
    # the trajectory's sin and cos: 2 x 60,001 x 10,000 floats, 9.6 GB
    (["--harmonics", "10000"], "--harmonics 10000: entries of the series' bases"),
    # the optimiser's constraint derivatives grow as the square of the harmonics
    (["--harmonics", "101"], "--harmonics 101: the optimiser's constraint derivatives"),
    # within check_samples' 2.1 M samples, but the regressor over every sample is not
    (["--duration", "1000"], "over 1000 s (--duration) at 1000 Hz: trajectory samples"),
])
def test_counts_past_the_memory_budget_are_refused_first(tmp_path, capsys, extra, words):
    out = tmp_path / "T.csv"
    assert cli.main(["excite", str(MICRO), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "memory budget of 2 GiB" in err[0], err
    assert not list(tmp_path.iterdir())


def test_harmonics_the_rate_cannot_hold_are_refused(tmp_path, capsys):
    """A top harmonic at or above half the output rate would alias in T.csv."""
    out = tmp_path / "T.csv"
    assert cli.main(["excite", str(MICRO), "--out", str(out), "--period", "0.01",
                     "--duration", "0.01"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--harmonics 5 of a --period of 0.01 s reach 500 Hz" in err[0], err
    assert not list(tmp_path.iterdir())


def test_the_budget_is_the_projects():
    """One budget: the counts are checked by stewart_fmu.budget.check_count."""
    from stewart_fmu.budget import MEMORY_BUDGET, BudgetError
    from stewart_sim.studies.excite.design import check_sizes
    check_sizes(5, PERIOD, PERIODS, 1000.0)            # the defaults fit
    with pytest.raises(BudgetError, match=f"{MEMORY_BUDGET / 1024**3:g} GiB"):
        check_sizes(5, PERIOD, 400, 1000.0)


FUZZ_SCENE_EDGES = [
    ("voltage_limit = 24.0", "voltage_limit = 1e-300"),
    ("voltage_limit = 24.0", "voltage_limit = 1e300"),
    ("current_limit = 2.0", "current_limit = 1e-300"),
    ("rate = 1000.0", "rate = 1.0"),
    ("rate = 1000.0", "rate = 1e9"),
    ("leg_max = 0.19", "leg_max = 0.1287"),
    ("mass = 0.5", "mass = 1e-300"),
    ("viscous = 5.0", "viscous = 1e300"),
    ("pinion_radius = 0.005", "pinion_radius = 1e-300"),
]
FUZZ_ARGUMENTS = {
    "--harmonics": ["2", "3", "0", "-1", "1e3", "nan", "99999999999999999999", "abc"],
    "--period": ["5", "1e-300", "0.004", "1e300", "inf", "nan", "-1", "0"],
    "--duration": ["5", "1e-300", "1e300", "inf", "2.5", "0"],
    "--starts": ["1", "0", "101", "1e9", "-3"],
}


def fuzz_cases(count: int, seed: int):
    """Seeded cases: a scene edge or none, and one to three arguments at their edges."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        edge = None if rng.random() < 0.4 else FUZZ_SCENE_EDGES[rng.integers(len(FUZZ_SCENE_EDGES))]
        names = rng.choice(list(FUZZ_ARGUMENTS), size=rng.integers(1, 4), replace=False)
        yield edge, [str(v) for n in names for v in (n, rng.choice(FUZZ_ARGUMENTS[n]))]


@pytest.mark.parametrize("case", range(24))
def test_fuzzed_inputs_give_one_line_or_a_finite_result(tmp_path, capfd, recwarn, monkeypatch,
                                                        case):
    """Seeded and bounded: never a traceback or a warning, never exit 0 with a non-finite
    result; refusals are one line, exit 2, nothing written. The optimiser is cut to 2 iterations
    a run (what is fuzzed is the input's path, not the optimum) and --starts to 1 where valid."""
    import functools
    from stewart_sim.studies.excite import design as design_module
    monkeypatch.setattr(design_module, "design",
                        functools.partial(design_module.design, max_iterations=2, polish=2))
    edge, extra = list(fuzz_cases(24, seed=34))[case]
    scene = MICRO
    if edge is not None:
        scene = tmp_path / "edge.toml"
        scene.write_text(MICRO.read_text(encoding="utf-8").replace(*edge), encoding="utf-8")
    if "--starts" not in extra:
        extra += ["--starts", "1"]
    if "--duration" not in extra:     # one period: the run stays short
        extra += ["--duration", extra[extra.index("--period") + 1] if "--period" in extra
                  else str(PERIOD)]
    out = tmp_path / "out" / "T.csv"
    code = cli.main(["excite", str(scene), "--out", str(out), *extra])
    captured = capfd.readouterr()        # the descriptors: LAPACK writes to them directly
    assert "Traceback" not in captured.err and "** On entry" not in captured.out + captured.err
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], \
        [str(w.message) for w in recwarn]
    if code == 0:
        t, q, qd, qdd = io.read_trajectory(out)
        assert all(np.all(np.isfinite(a)) for a in (t, q, qd, qdd))
        cond = float(re.search(r"base regressor: ([0-9.e+]+)", captured.out).group(1))
        assert np.isfinite(cond) and cond >= 1.0
    else:
        assert code == 2, (edge, extra, code, captured.err)
        err = [line for line in captured.err.strip().splitlines() if line]
        if err and err[0].startswith("usage:"):    # argparse: its usage, then its one line
            err = err[-1:]
        assert len(err) == 1, (edge, extra, err)
        assert not out.parent.exists() or not list(out.parent.iterdir())
