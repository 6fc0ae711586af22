"""`identify` end to end on run files the model generated: noise-free recovery of the base
parameters and prediction of a held-out run (1e-8), the files it writes, and its refusals."""
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.standard import NAMES, standard_parameters
from stewart_sim.studies.identify.report import standard_rows
from stewart_sim.studies.identify.runs import read_run
from stewart_sim.studies.identify.study import identify, predict

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
TRUTH = {"platform.mass": 0.58, "platform.inertia": [6.9e-4, 6.6e-4, 1.25e-3],
         "legs.lower_mass": 0.078, "legs.lower_com": 0.044, "legs.lower_inertia": [3.6e-5, 1.2e-6],
         "legs.upper_mass": 0.052, "legs.upper_com": 0.035, "legs.upper_inertia": [2.4e-5, 8e-7],
         "drive.rotor_inertia": [1.2e-6, 0.9e-6, 1.1e-6, 1.25e-6, 0.8e-6, 1.15e-6],
         "friction.viscous": [6.0, 4.2, 5.5, 6.4, 3.9, 5.6],
         "friction.coulomb": [0.3, 0.25, 0.35, 0.2, 0.3, 0.28]}


def fourier_motion(model, seed, period=4.0, harmonics=5, rate=1000.0, rotate=True):
    """A periodic pose (whole periods) around home: q, qd, qdd exact, t without the end point."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(period * rate)) / rate
    amp = np.array([0.004, 0.004, 0.004, 0.04, 0.04, 0.04]) / harmonics
    if not rotate:
        amp[3:] = 0.0
    q = np.tile(np.asarray(model.home, float), (t.size, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for k in range(1, harmonics + 1):
        w = 2 * np.pi * k / period
        a = amp * rng.uniform(-1, 1, 6)
        ph = rng.uniform(0, 2 * np.pi, 6)
        arg = w * t[:, None] + ph
        q += a * np.sin(arg)
        qd += a * w * np.cos(arg)
        qdd -= a * w * w * np.sin(arg)
    return t, q, qd, qdd


def write_run(path, model, t, q, qd, qdd):
    lengths = inverse_kinematics(model, q).lengths
    sigma = inverse_dynamics(model, q, qd, qdd)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *(f"l{i}" for i in range(1, 7)), *(f"sigma{i}" for i in range(1, 7))])
        for k in range(t.size):
            w.writerow([repr(float(x)) for x in (t[k], *lengths[k], *sigma[k])])
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("runs")
    truth = load_scene(SCENE, overrides=TRUTH)
    out = {}
    for name, seed, rotate in (("a", 1, True), ("b", 2, True), ("flat", 3, False)):
        out[name] = write_run(d / f"{name}.csv", truth, *fourier_motion(truth, seed,
                                                                       rotate=rotate))
    return truth, out


@pytest.mark.numerics
def test_noise_free_runs_give_the_truth(runs):
    truth, files = runs
    prior = load_scene(SCENE)
    ident = identify(prior, [read_run(files["a"], prior)])
    b = ident.base
    err = np.abs(ident.estimate.beta - b.beta(standard_parameters(truth))) / ident.base_scale()
    assert err.max() < 1e-8, err.max()
    held = predict(ident, read_run(files["b"], prior))
    assert np.max(np.abs(held.identified - held.measured)) < 1e-8 * held.force_peak
    # the prior is far off on the same run
    assert np.max(np.abs(held.prior - held.measured)) > 1e-2 * held.force_peak


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "stewart_sim", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


def test_the_command_writes_its_files(runs, tmp_path):
    _, files = runs
    out = tmp_path / "ident"
    r = cli("identify", SCENE, "--runs", files["a"], "--validate", files["b"], "--out", out)
    assert r.returncode == 0, r.stderr
    for name in ("identified.toml", "base_parameters.csv", "standard_parameters.csv",
                 "residuals.png", "validation.png", "report.md"):
        assert (out / name).is_file(), name
    model = load_scene(out / "identified.toml")
    truth = load_scene(SCENE, overrides=TRUTH)
    assert model.platform_mass == pytest.approx(truth.platform_mass + 6 * truth.legs.upper_mass
                                                - 6 * model.legs.upper_mass, rel=1e-6)
    assert np.allclose(model.friction.viscous_legs, truth.friction.viscous_legs, rtol=1e-6)
    assert np.allclose(model.drive.reflected_masses, truth.drive.reflected_masses, rtol=1e-6)
    text = (out / "report.md").read_text()
    assert "at the noise floor" in text and "Only in combination" in text
    # the input scene's comments are kept
    assert "# The micro-manipulator of the paper" in (out / "identified.toml").read_text()


def test_runs_without_rotation_are_refused_with_a_hint(runs, tmp_path):
    _, files = runs
    r = cli("identify", SCENE, "--runs", files["flat"], "--out", tmp_path / "x")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "regressor rank" in lines[0] and "rotation about" in lines[0]
    assert "platform.inertia_tensor.xx" in lines[0]
    assert not (tmp_path / "x").exists()
    r = cli("identify", SCENE, "--runs", files["flat"], "--partial", "--out", tmp_path / "x")
    assert r.returncode == 0, r.stderr
    assert "Not excited by these runs" in (tmp_path / "x" / "report.md").read_text()


def test_a_run_without_forces_is_one_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,l1,l2,l3,l4,l5,l6\n0,0.1,0.1,0.1,0.1,0.1,0.1\n")
    r = cli("identify", SCENE, "--runs", bad, "--out", tmp_path / "o")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "bad.csv" in r.stderr


@pytest.mark.numerics
def test_a_known_force_delay_is_taken_exactly(runs, tmp_path):
    """Forces recorded 2 ms after the motion they belong to (a periodic record rolled by two
    samples): --force-delay 0.002 recovers the base parameters as if there were none; without
    it the estimate is off."""
    truth, files = runs
    data = np.loadtxt(files["a"], delimiter=",", skiprows=1)
    data[:, 7:] = np.roll(data[:, 7:], 2, axis=0)
    late = tmp_path / "late.csv"
    np.savetxt(late, data, delimiter=",", header=open(files["a"]).readline().strip(),
               comments="", fmt="%.17g")
    prior = load_scene(SCENE)
    bt = None
    for delay, bound in ((0.002, 1e-8), (0.0, None)):
        ident = identify(prior, [read_run(late, prior)], force_delay=delay)
        bt = ident.base.beta(standard_parameters(truth))
        err = np.abs(ident.estimate.beta - bt) / ident.base_scale()
        if bound is not None:
            assert err.max() < bound, err.max()
        else:
            assert err.max() > 1e-4


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/null"])
def test_a_special_file_is_one_line_not_a_hang(special, tmp_path):
    """A device as a run (reading /dev/zero would never end): one line naming it, exit 2."""
    r = cli("identify", SCENE, "--runs", special, "--out", tmp_path / "o")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert special in r.stderr and "not a regular file" in r.stderr

    r = cli("identify", special, "--runs", special, "--out", tmp_path / "o")   # as the scene
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "not a scene file" in r.stderr


# A per-leg truth whose Coulomb friction is zero on three legs: noise-free, the weighted least
# squares gives those legs a Coulomb friction of +-1e-9 N, which the convex solve meets
# ("friction >= 0") only to its tolerance.
PER_LEG = dict(TRUTH, **{"friction.coulomb": [0.3, 0.0, 0.35, 0.0, 0.0, 0.28]})


@pytest.mark.numerics
def test_noise_free_runs_with_per_leg_friction_identify(tmp_path):
    """The result is projected onto the constraints before the scene's check: the identified
    scene is written, every friction >= 0 exactly, the zero ones within 1e-8 N of zero, and
    the written scene predicts a held-out run to 1e-8 of its peak (what noise-free data give,
    test_noise_free_runs_give_the_truth)."""
    from stewart_sim.studies.identify.report import write_identification

    truth = load_scene(SCENE, overrides=PER_LEG)
    a = write_run(tmp_path / "a.csv", truth, *fourier_motion(truth, 1))
    b = write_run(tmp_path / "b.csv", truth, *fourier_motion(truth, 2))
    prior = load_scene(SCENE)
    ident = identify(prior, [read_run(a, prior)])
    held = read_run(b, prior)
    write_identification(ident, SCENE, [predict(ident, held)], tmp_path / "out")
    found = load_scene(tmp_path / "out" / "identified.toml")
    coulomb = found.friction.coulomb_legs
    assert np.all(coulomb >= 0.0), coulomb
    assert np.max(np.abs(coulomb - truth.friction.coulomb_legs)) < 1e-8, coulomb
    v = predict(ident, held, standard_parameters(found))
    assert np.max(np.abs(v.identified - v.measured)) < 1e-8 * v.force_peak


@pytest.mark.numerics
def test_what_the_runs_do_not_determine_keeps_its_prior_exactly(tmp_path):
    """A truth whose platform and upper-leg inertias differ from the prior's: the standard
    parameters the runs cannot determine (the lower part's mass, the axial moments) keep the
    prior's values bit for bit, and the estimate still predicts a held-out run to 1e-8."""
    over = dict(TRUTH, **{"platform.inertia": [9e-4, 8e-4, 1.6e-3],
                          "legs.upper_inertia": [5e-5, 1.5e-6]})
    truth = load_scene(SCENE, overrides=over)
    prior = load_scene(SCENE)
    a = write_run(tmp_path / "a.csv", truth, *fourier_motion(truth, 1))
    b = write_run(tmp_path / "b.csv", truth, *fourier_motion(truth, 2))
    ident = identify(prior, [read_run(a, prior)])
    lost = ident.base.unidentifiable
    assert "legs.lower_mass" in lost
    idx = [NAMES.index(n) for n in lost]
    assert np.array_equal(ident.pi[idx], ident.prior[idx]), ident.pi[idx] - ident.prior[idx]
    assert ident.estimate.moved == ()
    held = predict(ident, read_run(b, prior))
    assert np.max(np.abs(held.identified - held.measured)) < 1e-8 * held.force_peak


@pytest.mark.numerics
def test_a_prior_the_constraints_must_move_is_reported(tmp_path):
    """A truth whose lower part is three times heavier and its centre of mass further out: the
    identified first moment m c and joint inertia J of the lower part admit no consistent body
    with the prior's mass (J - J_a / 2 >= (m c)^2 / m fails), so the mass, which the runs do not
    determine, moves; the report names it, its prior and the identified combination behind it."""
    from stewart_sim.studies.identify.report import report_text

    over = dict(TRUTH, **{"legs.lower_mass": 0.2, "legs.lower_com": 0.07,
                          "legs.lower_inertia": [1e-5, 1e-6]})
    truth = load_scene(SCENE, overrides=over)
    prior = load_scene(SCENE)
    a = write_run(tmp_path / "a.csv", truth, *fourier_motion(truth, 1))
    ident = identify(prior, [read_run(a, prior)])
    assert "legs.lower_mass" in ident.estimate.moved
    text = report_text(ident, SCENE, [], {})
    line = next(x for x in text.splitlines() if x.startswith("- legs.lower_mass: prior"))
    assert "legs.lower_first_moment" in line
    k = NAMES.index("legs.lower_mass")
    assert ident.pi[k] > ident.prior[k]
    assert "moved by the consistency constraints" in dict(
        (r[0], r[3]) for r in standard_rows(ident))["legs.lower_mass"]
