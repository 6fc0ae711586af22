"""The input and output halves of `identify`: run files (columns, force sources, refusals,
forward kinematics of every sample), the zero-phase filter and derivatives, the identified scene
(standard parameters back into the scene's text) and the figures."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu.dynamics import inverse_dynamics, regressor
from stewart_fmu.errors import StewartError, TrajectoryError
from stewart_fmu.io import named_array, write_csv
from stewart_fmu.kinematics import forward_kinematics_many, inverse_kinematics
from stewart_fmu.rotations import solve_rate_matrices, solve_rate_matrix
from stewart_fmu.standard import NAMES, present, standard_parameters
from stewart_sim.scene.load import load
from stewart_sim.studies.identify.plots import residual_figure, validation_figure
from stewart_sim.studies.identify.runs import MIN_SAMPLES, pose_of, read_run
from stewart_sim.studies.identify.scene_out import NOT_HELD, scene_values, write_identified
from stewart_sim.studies.identify.signal import (
    DECIMATED_RATIO,
    TRIM_PERIODS,
    choose_filter,
    decimated,
    derivatives,
    lowpass,
)
from tests.app.test_plot_labels import check_figure
from tests.helpers import SCENE_FILES, record

MICRO = SCENE_FILES["micro"]
POSE = ("x", "y", "z", "thx", "thy", "thz")


@pytest.fixture(scope="module")
def scene():
    return load(MICRO)


def fourier_motion(model, t, period=10.0, harmonics=10, seed=0, amplitude=(4e-3, 0.04)):
    """A band-limited periodic pose about home (a Fourier series of `harmonics` harmonics of
    1/period, amplitudes falling as 1/k) and its exact first two derivatives."""
    rng = np.random.default_rng(seed)
    k = np.arange(1, harmonics + 1)
    scale = np.repeat(amplitude, 3)[:, None] / k / np.sqrt(harmonics)
    a, b = rng.normal(size=(2, 6, harmonics)) * scale
    w = 2 * np.pi * k / period
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = model.home + s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return q, qd, qdd


def write_run(path: Path, columns: dict[str, np.ndarray]) -> Path:
    return write_csv(path, named_array(columns))


def run_columns(model, t, q, forces="sigma", extra=()):
    """A run file's columns: time, the lengths of poses q, six force columns of `forces`
    (made up, 1..6 N times the sample index), and `extra` columns (pose, unrelated)."""
    lengths = inverse_kinematics(model, q, with_cond=False).lengths
    cols = {"t": t}
    cols.update({f"l{i + 1}": lengths[:, i] for i in range(6)})
    cols.update({f"{forces}{i + 1}": (i + 1) * np.arange(len(t), dtype=float) for i in range(6)})
    if "pose" in extra:
        cols.update({c: q[:, k] for k, c in enumerate(POSE)})
    if "other" in extra:
        cols["voltage1"] = np.ones(len(t))
    return cols


# --- runs ------------------------------------------------------------------------------------

def test_read_run_takes_the_columns_it_needs_and_ignores_the_others(scene, tmp_path):
    """t, l1..l6, sigma1..6 and a pose are read as written; other columns are ignored."""
    m = scene.model
    t = np.arange(200) / 1000.0
    q = fourier_motion(m, t)[0]
    path = write_run(tmp_path / "run.csv", run_columns(m, t, q, extra=("pose", "other")))
    run = read_run(path, m)
    assert run.source == "sigma" and run.path == path
    np.testing.assert_array_equal(run.t, t)
    np.testing.assert_array_equal(run.lengths, inverse_kinematics(m, q).lengths)
    np.testing.assert_array_equal(run.sigma[:, 2], 3 * np.arange(200.0))
    np.testing.assert_array_equal(run.pose, q)
    assert run.rate == pytest.approx(1000.0, rel=1e-12)


def test_force_sources_in_order_and_their_conversion(scene, tmp_path):
    """`time` as `run` writes it; force1..6 as they are; torque1..6 times zeta / r;
    current1..6 times K_t zeta / r (the scene's [controller.motor] and [drive]); sigma first
    when a file has several."""
    m, motor = scene.model, scene.controller.motor
    t = np.arange(150) / 500.0
    q = fourier_motion(m, t)[0]
    ratio = m.drive.gear_ratio / m.drive.pinion_radius
    for prefix, gain in (("force", 1.0), ("torque", ratio),
                         ("current", motor.torque_constant * ratio)):
        cols = run_columns(m, t, q, prefix)
        cols["time"] = cols.pop("t")
        run = read_run(write_run(tmp_path / f"{prefix}.csv", cols), m, motor)
        assert run.source.startswith(prefix) and run.pose is None
        np.testing.assert_allclose(run.sigma[:, 5], gain * 6 * np.arange(150.0), rtol=1e-15)
    both = run_columns(m, t, q, "current") | {f"sigma{i}": np.ones(150) for i in range(1, 7)}
    assert read_run(write_run(tmp_path / "both.csv", both), m, motor).source == "sigma"


def test_currents_without_a_motor_are_refused(scene, tmp_path):
    m = scene.model
    t = np.arange(150) / 500.0
    path = write_run(tmp_path / "cur.csv", run_columns(m, t, fourier_motion(m, t)[0], "current"))
    with pytest.raises(TrajectoryError, match=r"cur.csv: .*\[controller.motor\] torque_constant"):
        read_run(path, m)
    no_drive = dataclasses.replace(m, drive=None)
    with pytest.raises(TrajectoryError, match=r"need the scene's \[drive\]"):
        read_run(path, no_drive, scene.controller.motor)


def test_missing_columns_are_listed_with_the_alternatives(scene, tmp_path):
    """A file without forces names every accepted force column set; simulate's motion.csv
    (pose, rates, lengths, no forces) is told apart; a file without t and l3 lists both."""
    m = scene.model
    t = np.arange(150) / 500.0
    q = fourier_motion(m, t)[0]
    cols = run_columns(m, t, q, extra=("pose",))    # motion.csv: t, x..thz, dx..dthz, l1..l6
    for i in range(1, 7):
        del cols[f"sigma{i}"]
    cols.update({f"d{c}": np.zeros(len(t)) for c in POSE})
    with pytest.raises(TrajectoryError) as info:
        read_run(write_run(tmp_path / "motion.csv", cols), m)
    text = str(info.value)
    assert text.startswith(str(tmp_path / "motion.csv")) and "\n" not in text
    for alt in ("sigma1..sigma6", "force1..force6", "torque1..torque6", "current1..current6"):
        assert alt in text
    assert "simulate" in text and "no forces" in text
    cols = run_columns(m, t, q)
    del cols["t"], cols["l3"]
    with pytest.raises(TrajectoryError, match=r"missing columns t \(or time\); l3"):
        read_run(write_run(tmp_path / "nol3.csv", cols), m)


def test_too_few_samples_are_refused(scene, tmp_path):
    m = scene.model
    t = np.arange(MIN_SAMPLES - 1) / 1000.0
    path = write_run(tmp_path / "short.csv", run_columns(m, t, fourier_motion(m, t)[0]))
    with pytest.raises(TrajectoryError, match=f"short.csv: {MIN_SAMPLES - 1} samples, "
                                              f"identification needs at least {MIN_SAMPLES}"):
        read_run(path, m)


def test_non_uniform_time_is_refused_naming_the_sample(scene, tmp_path):
    """A sample 1 % of the period off the grid: refused (filters assume one rate); timestamps
    rounded to 1 us at 1 kHz pass."""
    m = scene.model
    t = np.arange(300) / 1000.0
    cols = run_columns(m, t, fourier_motion(m, t)[0])
    cols["t"] = np.round(t + 0.37e-6, 6)
    read_run(write_run(tmp_path / "rounded.csv", cols), m)
    cols["t"] = t.copy()
    cols["t"][123] += 1e-5
    with pytest.raises(TrajectoryError, match=r"jitter.csv: time not uniformly sampled: sample "
                                              r"123 \(t = 0.12301 s\).*one sampling rate"
                                              ) as info:
        read_run(write_run(tmp_path / "jitter.csv", cols), m)
    assert info.value.index == 123


def test_lengths_outside_the_stroke_are_refused_naming_sample_and_time(scene, tmp_path):
    m = scene.model
    t = np.arange(300) / 1000.0
    cols = run_columns(m, t, fourier_motion(m, t)[0])
    cols["l4"][207] = m.leg_max + 1e-6
    cols["l4"][250] = m.leg_min - 1e-3
    with pytest.raises(TrajectoryError, match=r"stroke.csv: sample 207 \(t = 0.207 s\): leg\(s\)"
                                              r" \[4\] .* outside the scene's stroke \[0.07, "
                                              r"0.19\] m; 1 more such samples"):
        read_run(write_run(tmp_path / "stroke.csv", cols), m)


def test_pose_of_60_s_at_1_khz(scene, tmp_path):
    """Forward kinematics of 60 000 samples at once: lengths matched to 1e-12 m, the pose back
    to 1e-10 (m, rad), from home and from a measured pose. Its time is a benchmark's
    (benchmarks/bench_identify.py, stage "forward kinematics"), not a test's."""
    m = scene.model
    t = np.arange(60_000) / 1000.0
    q = fourier_motion(m, t, period=12.0)[0]
    path = write_run(tmp_path / "long.csv", run_columns(m, t, q))
    run = read_run(path, m)
    pose = pose_of(m, run)
    assert np.abs(inverse_kinematics(m, pose).lengths - run.lengths).max() <= 1e-12
    assert np.abs(pose - q).max() <= 1e-10
    measured = dataclasses.replace(run, pose=q + 1e-4)
    assert np.abs(pose_of(m, measured) - q).max() <= 1e-10


def test_pose_of_names_the_sample_forward_kinematics_fails_on(scene, tmp_path):
    """Lengths no pose has (one leg three times its length, the stroke lifted so that Newton
    meets the geometry): one line naming the file, the sample and its time."""
    m = dataclasses.replace(scene.model, leg_min=None, leg_max=None)
    t = np.arange(400) / 1000.0
    cols = run_columns(m, t, fourier_motion(m, t)[0])
    cols["l6"][321] *= 3.0
    run = read_run(write_run(tmp_path / "far.csv", cols), m)
    with pytest.raises(TrajectoryError) as info:
        pose_of(m, run)
    text = str(info.value)
    assert text.startswith(f"{tmp_path / 'far.csv'}: sample 321 (t = 0.321 s): forward "
                           f"kinematics failed: ") and "\n" not in text
    assert info.value.index == 321 and info.value.time == pytest.approx(0.321)


def test_forward_kinematics_many_continues_from_neighbours(scene):
    """A ramp from home to a far pose (8 mm, 0.3 rad) that Newton does not reach from home in
    4 iterations is reached from its solved neighbours; a sample with no lengths is reported,
    the others solved."""
    m = scene.model
    q = m.home + np.linspace(0.0, 1.0, 200)[:, None] * np.array([8e-3] * 3 + [0.3] * 3)
    lengths = inverse_kinematics(m, q).lengths
    assert not forward_kinematics_many(m, lengths[-1:], m.home, max_iter=4).converged[0]
    lengths[150] = np.nan
    sol = forward_kinematics_many(m, lengths, max_iter=4)
    assert not sol.converged[150] and np.isnan(sol.residual[150])
    ok = np.arange(200) != 150
    assert sol.converged[ok].all()
    assert np.abs(sol.poses[ok] - q[ok]).max() <= 1e-10


def test_batched_euler_rates_are_the_per_sample_arithmetic():
    """solve_rate_matrices (forward_kinematics_many's step) gives solve_rate_matrix's numbers
    bit for bit, and refuses the same gimbal-locked poses."""
    rng = np.random.default_rng(4)
    Q = rng.uniform(-1.0, 1.0, (500, 6))
    Q[7, 4] = np.pi / 2
    W = rng.normal(size=(500, 3))
    X, ok = solve_rate_matrices(Q, W)
    for k in range(500):
        good, *x = solve_rate_matrix(Q[k], *W[k])
        assert good == ok[k] and (not good or x == X[k].tolist())
    assert not ok[7] and ok.sum() == 499


# --- signal ----------------------------------------------------------------------------------

def _errors(f, q, qd, qdd, t):
    """Largest error of the filtered pose and its derivatives inside the trimmed record,
    relative to each one's peak."""
    got = derivatives(q, f)
    keep = slice(f.trim, len(t) - f.trim)
    return [float(np.abs(g[keep] - e[keep]).max() / np.abs(e).max())
            for g, e in zip(got, (q, qd, qdd))]


@pytest.mark.parametrize("layout", ["periodic", "closed"])
def test_derivatives_of_a_periodic_record_are_exact(scene, layout):
    """A Fourier series over whole periods (5 periods of 4 s, 10 harmonics, 1 kHz), with or
    without its first sample repeated at the end: the pose and its first two derivatives to
    1e-12 of their peak (frequency domain: nothing is approximated)."""
    m = scene.model
    t = np.arange(20_000 + (layout == "closed")) / 1000.0
    q, qd, qdd = fourier_motion(m, t, period=4.0)
    f = choose_filter(t, q)
    assert f.extension == layout and f.trim == 0
    assert 2.5 <= f.cutoff <= 2.5 * 1.2 + 1e-9     # the top harmonic (2.5 Hz) times MARGIN
    errs = _errors(f, q, qd, qdd, t)
    record(f"identify: periodic derivatives [{layout}]", max(errs), 1e-12)
    assert max(errs) <= 1e-12, errs


def test_derivatives_of_a_record_of_no_whole_periods(scene):
    """2.37 periods: the record is mirrored (detrended, odd); inside the trimmed edges (8
    periods of the cut-off) the pose within 5e-7, qd 1e-5, qdd 3e-5 of their peak (measured
    at the default cut-off, 141 Hz: 8e-11, 5e-8, 5.5e-6; at 4 Hz: 1.2e-7, 2.2e-6, 7.2e-6: the
    seam's error is a fraction of qdd's peak, integrated once or twice over 1 / f_c)."""
    m = scene.model
    t = np.arange(int(2.37 * 4000)) / 1000.0
    q, qd, qdd = fourier_motion(m, t, period=4.0)
    for cutoff in (None, 4.0):
        f = choose_filter(t, q, cutoff=cutoff)
        assert f.extension == "reflect"
        assert f.trim == int(np.ceil(TRIM_PERIODS * f.rate / f.cutoff))
        errs = _errors(f, q, qd, qdd, t)
        record(f"identify: derivatives of 2.37 periods, qdd [cutoff {cutoff}]", errs[2], 3e-5)
        assert errs[0] <= 5e-7 and errs[1] <= 1e-5 and errs[2] <= 3e-5, errs


def test_derivatives_from_1_um_quantized_lengths(scene):
    """60 s at 1 kHz, 6 periods of a 10 s Fourier pose with harmonics to 1 Hz, leg lengths
    quantized to 1 um (an encoder), the pose by forward kinematics: the default cut-off lands
    just above the top harmonic (1.2 Hz) and the error, RMS relative to the signal's RMS about
    its mean, the worst pose axis, is measured: q 2.6e-5, qd 4.9e-5, qdd 1.1e-4 (bounds about twice that)."""
    m = scene.model
    t = np.arange(60_000) / 1000.0
    q, qd, qdd = fourier_motion(m, t, period=10.0, seed=3)
    lengths = np.round(inverse_kinematics(m, q).lengths * 1e6) / 1e6
    measured = forward_kinematics_many(m, lengths).poses
    f = choose_filter(t, measured)
    assert f.extension == "periodic"
    assert 1.0 <= f.cutoff <= 1.5, f
    got = derivatives(measured, f)
    rms = [float(np.max(np.sqrt(np.mean((g - e) ** 2, axis=0))
                        / np.sqrt(np.mean((e - e.mean(axis=0)) ** 2, axis=0))))
           for g, e in zip(got, (q, qd, qdd))]
    for name, value, bound in zip(("q", "qd", "qdd"), rms, (6e-5, 1e-4, 2.5e-4)):
        record(f"identify: 1 um quantization, RMS error of {name}", value, bound)
        assert value <= bound, (name, value)


def test_lowpass_is_the_filter_of_the_derivatives_and_commutes_with_pi(scene):
    """lowpass(x) is derivatives(x)'s filtered signal; on (N, 6, P) regressor-shaped arrays
    lowpass(Y) pi = lowpass(Y pi) to round-off, for each extension."""
    m = scene.model
    rng = np.random.default_rng(1)
    for n in (4000, 4001, 3333):
        t = np.arange(n) / 1000.0
        q = fourier_motion(m, t, period=4.0)[0]
        if n == 4001:
            q[-1] = q[0]
        f = choose_filter(t, q)
        np.testing.assert_array_equal(lowpass(q, f), derivatives(q, f)[0])
        Y = rng.normal(size=(n, 6, 70))
        pi = rng.normal(size=70)
        lhs, rhs = lowpass(Y, f) @ pi, lowpass(Y @ pi, f)
        assert np.abs(lhs - rhs).max() <= 1e-12 * np.abs(rhs).max()
        assert lowpass(Y, f).shape == Y.shape


def test_noise_above_the_cutoff_is_removed(scene):
    """A sine inside the band passes untouched; one above (1 + TAPER) f_c is gone."""
    t = np.arange(10_000) / 1000.0
    inside, outside = np.sin(2 * np.pi * 1.0 * t), np.sin(2 * np.pi * 40.0 * t)
    f = choose_filter(t, np.column_stack([inside] * 6), cutoff=10.0)
    out = lowpass(np.column_stack([inside + outside, outside]), f)
    assert np.abs(out[:, 0] - inside).max() <= 1e-12
    assert np.abs(out[:, 1]).max() <= 1e-12


def test_choose_filter_decimation_and_refusals():
    """Default decimation keeps the decimated rate >= DECIMATED_RATIO x the cut-off; decimated()
    trims and strides; a bad cut-off or decimation is one line."""
    t = np.arange(5000) / 1000.0
    q = np.column_stack([np.sin(2 * np.pi * 0.4 * t + k) for k in range(6)])
    f = choose_filter(t, q, cutoff=7.0)
    assert f.decimate == 28 and f.rate / f.decimate >= DECIMATED_RATIO * f.cutoff
    assert f.rate / (f.decimate + 1) < DECIMATED_RATIO * f.cutoff
    x = np.arange(5000)
    np.testing.assert_array_equal(decimated(x, f), x[f.trim:5000 - f.trim:28])
    assert choose_filter(t, q, cutoff=7.0, decimate=3).decimate == 3
    for bad in (0.0, -1.0, 600.0, float("nan")):
        with pytest.raises(StewartError, match="cut-off must be above 0 and below half"):
            choose_filter(t, q, cutoff=bad)
    for bad in (0, 1.5, True):
        with pytest.raises(StewartError, match="decimation must be a whole number"):
            choose_filter(t, q, decimate=bad)


# --- scene_out -------------------------------------------------------------------------------

def _perturbed(model, seed=0):
    """The standard parameters of the model with its inertial and friction parameters each
    scaled by 1 +- 20 % (per leg where per leg), the platform's moments by 1 +- 10 % (a
    triangle still), Coulomb friction 0.5-1.5 N per leg; the lower part's mass kept (it is
    not identifiable)."""
    rng = np.random.default_rng(seed)
    u = lambda *shape: rng.uniform(0.8, 1.2, shape or None)  # noqa: E731
    lg = model.legs
    legs = dataclasses.replace(
        lg, lower_com=lg.lower_com * u(), lower_inertia=tuple(np.multiply(lg.lower_inertia, u(2))),
        upper_mass=lg.upper_mass * u(), upper_com=lg.upper_com * u(),
        upper_inertia=tuple(np.multiply(lg.upper_inertia, u(2))))
    drive = dataclasses.replace(model.drive, rotor_inertia=tuple(
        model.drive.rotor_inertia * u(6)))
    friction = dataclasses.replace(model.friction, viscous=tuple(model.friction.viscous_legs
                                                                 * u(6)),
                                   coulomb=tuple(rng.uniform(0.5, 1.5, 6)))
    true = dataclasses.replace(model, platform_mass=model.platform_mass * u(),
                               platform_inertia=model.platform_inertia * rng.uniform(0.9, 1.1, 3),
                               legs=legs, drive=drive, friction=friction)
    return standard_parameters(true)


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_identified_scene_round_trip(name, tmp_path):
    """Every parameter the scene holds identified (but the lower mass): write -> load ->
    standard_parameters equals pi on the identified entries to 1e-12 relative, and the prior
    elsewhere; the lower part's com follows from the prior mass."""
    path = SCENE_FILES[name]
    prior = load(path).model
    pi = _perturbed(prior)
    ids = {n for n, h in zip(NAMES, present(prior)) if h} - set(NOT_HELD) - {"legs.lower_mass"}
    values, not_held = scene_values(prior, pi, ids)
    assert not_held == {}
    out = write_identified(path, values, tmp_path / "identified.toml", ["identified from a.csv"])
    back = standard_parameters(load(out).model)
    idx = [NAMES.index(n) for n in ids]
    rel = np.abs(back[idx] - pi[idx]) / np.abs(pi[idx])
    record(f"identify: identified scene round trip [{name}]", rel.max(), 1e-12)
    assert rel.max() <= 1e-12, [NAMES[i] for i in np.array(idx)[rel > 1e-12]]
    other = [k for k, n in enumerate(NAMES) if n not in ids]
    np.testing.assert_allclose(back[other], standard_parameters(prior)[other], rtol=1e-15)
    assert values["legs.lower_com"] == pytest.approx(
        pi[NAMES.index("legs.lower_first_moment")] / prior.legs.lower_mass, rel=1e-15)


def test_identified_scene_keeps_text_comments_and_layout(tmp_path):
    """Only the identified keys' lines change (per-leg ones become lists of six), every comment
    and other line is kept, the header comment comes first."""
    prior = load(MICRO).model
    pi = _perturbed(prior, seed=2)
    ids = {f"friction.viscous.{i}" for i in range(1, 7)} | {"drive.reflected_mass.3"}
    values, _ = scene_values(prior, pi, ids)
    assert set(values) == {"friction.viscous", "drive.rotor_inertia"}
    assert values["drive.rotor_inertia"][0] == prior.drive.rotor_inertia
    out = write_identified(MICRO, values, tmp_path / "id.toml",
                           ["identified by stewart-sim identify", "runs: a.csv, b.csv"])
    old, new = MICRO.read_text().splitlines(), out.read_text().splitlines()
    assert new[:2] == ["# identified by stewart-sim identify", "# runs: a.csv, b.csv"]
    assert len(new) == len(old) + 2
    changed = [(a, b) for a, b in zip(old, new[2:]) if a != b]
    assert [a.split("=")[0].strip() for a, _ in changed] == ["rotor_inertia", "viscous"]
    viscous = dict(changed)["viscous = 5.0"]
    assert viscous == "viscous = [" + ", ".join(repr(v) for v in values["friction.viscous"]) + "]"


def test_values_the_scene_cannot_hold_are_returned_apart():
    prior = load(MICRO).model
    pi = standard_parameters(prior)
    pi[NAMES.index("platform.first_moment.z")] = -2e-3
    pi[NAMES.index("platform.inertia_tensor.xy")] = 1e-6
    ids = {"platform.mass", "platform.first_moment.z", "platform.inertia_tensor.xy",
           "platform.inertia_tensor.zz"}
    values, not_held = scene_values(prior, pi, ids)
    assert not_held == {"platform.first_moment.z": -2e-3, "platform.inertia_tensor.xy": 1e-6}
    assert values == {"platform.mass": 0.5, "platform.inertia": [6e-4, 6e-4, 1.1e-3]}


def test_an_invalid_identified_scene_is_refused_and_not_written(tmp_path):
    """A leg part whose moment about its joint is below (m c)^2 / m (negative I_t), or a
    non-positive mass: StewartError naming the key; nothing written."""
    prior = load(MICRO).model
    pi = standard_parameters(prior)
    pi[NAMES.index("legs.upper_joint_inertia")] = 1e-5
    values, _ = scene_values(prior, pi, {"legs.upper_joint_inertia"})
    with pytest.raises(StewartError, match="identified values make an invalid scene: .*"
                                           "legs.upper_inertia"):
        write_identified(MICRO, values, tmp_path / "bad.toml", [])
    assert not (tmp_path / "bad.toml").exists()
    pi[NAMES.index("legs.upper_mass")] = -0.1
    with pytest.raises(StewartError, match="'legs.upper_com': the identified mass -0.1 kg"):
        scene_values(prior, pi, {"legs.upper_mass"})
    with pytest.raises(ValueError, match="not standard parameters"):
        scene_values(prior, pi, {"platform.moss"})


# --- plots -----------------------------------------------------------------------------------

def test_figures_have_units_and_decimate_long_runs():
    t = np.arange(60_000) / 1000.0
    measured = np.sin(np.outer(t, np.arange(1, 7)))
    fig = residual_figure(t, measured, 0.9 * measured, "identification runs")
    check_figure(fig)
    assert len(fig.axes) == 12
    fig = validation_figure(t, measured, 0.99 * measured, 0.8 * measured, "held-out run")
    check_figure(fig)
    assert "RMS" in fig.axes[1].get_legend().get_texts()[0].get_text()


# --- the input half end to end ---------------------------------------------------------------

@pytest.mark.parametrize("name, amplitude", [("micro", (4e-3, 0.04)), ("sim", (0.05, 0.05))])
def test_run_file_to_filtered_regressor_is_exact(name, amplitude, tmp_path):
    """A noise-free periodic run written as a file (lengths and the inverse dynamics' forces),
    read, its poses by forward kinematics, filtered and differentiated: Y(q_f, qd, qdd) pi
    equals the file's forces, and lowpass(Y) pi equals lowpass(sigma), to 1e-10 of their peak
    (measured 3.3e-11 on the micro-manipulator, 1.6e-12 on the simulator)."""
    m = load(SCENE_FILES[name]).model
    t = np.arange(20_000) / 1000.0
    q, qd, qdd = fourier_motion(m, t, period=4.0, amplitude=amplitude, seed=5)
    sigma = inverse_dynamics(m, q, qd, qdd)
    cols = run_columns(m, t, q)
    cols.update({f"sigma{i + 1}": sigma[:, i] for i in range(6)})
    run = read_run(write_run(tmp_path / "run.csv", cols), m)
    pose = pose_of(m, run)
    f = choose_filter(run.t, pose)
    assert f.extension == "periodic"
    Y = regressor(m, *derivatives(pose, f))
    pi = standard_parameters(m)
    peak = np.abs(run.sigma).max()
    worst = max(np.abs(Y @ pi - run.sigma).max(),
                np.abs(lowpass(Y, f) @ pi - lowpass(run.sigma, f)).max()) / peak
    record(f"identify: run file to filtered regressor [{name}]", worst, 1e-10)
    assert worst <= 1e-10
