"""`stewart-sim design` with motions to fly and a drive from a catalogue
(stewart_sim.studies.design.flight): a candidate's motion margins against inverse kinematics
and dynamics called directly, the base joints' height, bad input, a requirement no design
meets, the motion-simulator example at a reduced size (its best.toml re-checked here on every
sample of the motions as `size` reads them from the written scene), and one seed giving one
search on 1 and 2 workers and BLAS threads."""
from __future__ import annotations

import csv
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from controller.drive import constant_load
from stewart_fmu import load_scene
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.reach import Engine
from stewart_fmu.stiffness import modes_map
from stewart_sim.scene.load import load as load_full_scene
from stewart_sim.studies.design import candidate as C
from stewart_sim.studies.design import spec as S
from stewart_sim.studies.sizing.catalogue import read_catalogue
from stewart_sim.studies.sizing.demand import leg_rms
from stewart_sim.studies.sizing.motions import read_one

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "scenes" / "design" / "motion_simulator.toml"
POSITIONING = ROOT / "scenes" / "design" / "positioning_hexapod.toml"
CATALOGUE = ROOT / "scenes" / "catalogues" / "drives.csv"
REDUCED = ("--population", "20", "--generations", "6")   # the example's CI size
# the shipped motion simulator's geometry with a 1.6 m stroke from 1.7 m, and drive 3 in cost
# order (SGMSH-30 i16 r25)
X = np.array([2.2, 1.4, np.radians(12), np.radians(48), 2.3, -0.35, 1.7, 1.6, 3.5])


def cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "stewart_sim", *map(str, args)],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, **(env or {})})


def design_file(tmp_path: Path, source: Path = EXAMPLE, drop=(), **tables) -> Path:
    """The example with tables' keys replaced (and tables dropped), its paths absolute."""
    doc = tomlkit.parse(source.read_text())
    doc["design"]["base_scene"] = str((source.parent / doc["design"]["base_scene"]).resolve())
    if "motions" in doc:
        doc["motions"]["files"] = [str((source.parent / f).resolve())
                                   for f in doc["motions"]["files"]]
    if "drives" in doc:
        doc["drives"]["catalogue"] = str((source.parent / doc["drives"]["catalogue"]).resolve())
    for table in drop:
        del doc[table]
    for table, keys in tables.items():
        if table not in doc:
            doc[table] = tomlkit.table()
        for k, v in keys.items():
            doc[table][k] = v
    path = tmp_path / "design.toml"
    path.write_text(tomlkit.dumps(doc))
    return path


def motions_of(scene_file: Path) -> list:
    """The example's motions as `size` reads them for a scene file (cued about its home)."""
    scene = load_full_scene(scene_file)
    return [read_one(scene, (EXAMPLE.parent / f).resolve(), f)
            for f in tomlkit.parse(EXAMPLE.read_text())["motions"]["files"]]


def drive_of(model):
    """The catalogue drive whose [drive] table the model has."""
    for d in read_catalogue(CATALOGUE):
        if (d.gear_ratio, d.pinion_radius, d.rotor_inertia) == (
                model.drive.gear_ratio, model.drive.pinion_radius, model.drive.rotor_inertia):
            return d
    raise AssertionError("the model's drive is not in the catalogue")


def demand(model, motions):
    """Per motion: leg lengths, rates, accelerations and rack forces, from inverse kinematics
    and dynamics called directly."""
    out = []
    for m in motions:
        kin = inverse_kinematics(model, m.q, m.qd, m.qdd)
        out.append((m, np.asarray(kin.lengths), np.asarray(kin.rates),
                    np.asarray(kin.accelerations), np.asarray(kin.cond).ravel(),
                    inverse_dynamics(model, m.q, m.qd, m.qdd)))
    return out


def test_a_candidates_motion_margins_are_the_legs_demand_on_its_drive():
    spec = S.load(EXAMPLE)
    names = C.requirement_names(spec)
    c = C.evaluate(spec, X, names, every=1)
    got = {m.name: m for m in c.margins}
    values = spec.values(X)
    drive = spec.drive(values)
    assert drive.name == "SGMSH-30 i16 r25"
    model = C.candidate_model(spec, values)
    assert model.drive.gear_ratio == drive.gear_ratio
    # the motions about this candidate's home: the base scene's cue moved by the homes' offset
    base = load_full_scene(ROOT / "scenes" / "motion_simulator.toml")
    offset = np.asarray(model.home) - np.asarray(base.model.home)
    motions = [m.__class__(m.name, m.kind, m.t, m.q + offset, m.qd, m.qdd)
               for m in motions_of(ROOT / "scenes" / "motion_simulator.toml")]
    rows = demand(model, motions)
    L = np.vstack([r[1] for r in rows])
    assert got["motion_stroke_min"].absolute == pytest.approx(L.min() - values["leg_min"],
                                                              abs=1e-9)
    assert got["motion_stroke_max"].absolute == pytest.approx(
        values["leg_min"] + values["stroke"] - L.max(), abs=1e-9)
    cond = np.concatenate([r[4] for r in rows])
    assert got["motion_cond"].absolute == pytest.approx(20.0 - cond.max(), rel=1e-9)
    ratio = drive.gear_ratio / drive.pinion_radius
    keep = 1.0 + spec.flight.margin
    torque = max(np.abs(r[5]).max() for r in rows) / ratio
    assert got["torque_peak"].absolute == pytest.approx(drive.peak_torque / keep - torque,
                                                        rel=1e-9)
    rms = max(leg_rms(r[0].t, r[5] / ratio).max() for r in rows)
    assert got["torque_rms"].relative == pytest.approx(1 - rms / drive.continuous_torque * keep,
                                                       rel=1e-9)
    speed = max(np.abs(r[2]).max() for r in rows) * ratio
    assert got["motor_speed"].absolute == pytest.approx(drive.max_speed / keep - speed, rel=1e-9)
    # the leg acceleration against what the drive gives the constant load
    reflected = drive.gear_ratio**2 * drive.rotor_inertia / drive.pinion_radius**2
    bound = drive.peak_torque * ratio / (constant_load(model) + reflected) / keep
    accel = max(np.abs(r[3]).max() for r in rows)
    assert got["motion_acceleration"].absolute == pytest.approx(bound - accel, rel=1e-9)
    # the search thins the samples: it never sees a larger peak than every sample holds
    thin = {m.name: m for m in C.evaluate(spec, X, names).margins}
    for n in ("torque_peak", "motor_speed", "motion_stroke_min", "motion_acceleration"):
        assert thin[n].absolute >= got[n].absolute - 1e-12


def test_the_base_joints_height_moves_the_whole_mechanism():
    # without obstacles in N, raising the base joints with home (home_height is above them)
    # changes no margin: the mechanism, the motions and gravity are the same relative to it
    spec = S.load(EXAMPLE)
    names = C.requirement_names(spec)
    low = C.evaluate(spec, X, names)
    raised = replace(spec, parameters=tuple(
        S.Parameter(p.name, 0.3, 0.3) if p.name == "base_joint_z" else p
        for p in spec.parameters))
    high = C.evaluate(raised, X, names)
    model = C.candidate_model(raised, raised.values(X))
    assert np.allclose(np.asarray(model.base_joints)[:, 2], 0.3)
    assert model.home[2] == pytest.approx(0.3 + 2.3)
    for a, b in zip(low.margins, high.margins):
        assert a.name == b.name and b.relative == pytest.approx(a.relative, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize("tables,drop,key", [
    ({"motions": {"files": ["/nonexistent/motion.csv"]}}, (), "motions.files[0]"),
    ({"motions": {"every": 0}}, (), "motions.every"),
    ({"motions": {"margin": -0.1}}, (), "motions.margin"),
    ({"drives": {"names": ["no such drive"]}}, (), "drives.names"),
    ({"drives": {"catalogue": "/nonexistent/drives.csv"}}, (), "drives.catalogue"),
    ({}, ("motions",), "[drives]"),
    ({"parameters": {"base_joint_z": [0.5, 0.1]}}, (), "parameters.base_joint_z"),
])
def test_bad_input_is_one_line_naming_the_key(tmp_path, tables, drop, key):
    out = tmp_path / "out"
    r = cli("design", design_file(tmp_path, drop=drop, **tables), "--out", out)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and key in r.stderr, r.stderr
    assert not out.exists()


def test_without_a_catalogue_the_base_scenes_drive_flies_the_motions(tmp_path):
    # the positioning example's base scene (the micro-manipulator) has a [drive] and a motor:
    # its drives' bounds (controller.capability: speed, acceleration, rack force) are checked
    # along the motions, derated by the margin; no drive parameter, no catalogue ratings
    from controller.capability import capability
    from stewart_fmu.io import TRAJECTORY_COLUMNS

    t = np.linspace(0.0, 1.0, 201)
    w, a = 2 * np.pi * 3.0, 0.004             # 4 mm heave at 3 Hz about the base scene's home
    home = load_scene(ROOT / "scenes" / "micro_manipulator.toml").home
    traj = np.zeros((len(t), 19))
    traj[:, 0], traj[:, 1:7] = t, home
    traj[:, 3] += a * np.sin(w * t)
    traj[:, 9], traj[:, 15] = a * w * np.cos(w * t), -a * w * w * np.sin(w * t)
    motion = tmp_path / "heave.csv"
    np.savetxt(motion, traj, delimiter=",", header=",".join(TRAJECTORY_COLUMNS), comments="")
    spec = S.load(design_file(tmp_path, source=POSITIONING,
                              motions={"files": [str(motion)], "margin": 0.2}))
    assert "drive" not in [p.name for p in spec.parameters]
    names = C.requirement_names(spec)
    assert {"motion_speed", "motion_acceleration", "motion_force"} <= set(names)
    assert not {"torque_peak", "torque_rms", "motor_speed"} & set(names)
    assert {"current", "voltage"} <= set(names)
    x = np.array([0.1, 0.06, np.radians(10), np.radians(50), 0.12, 0.09, 0.05, 1e7])
    got = {m.name: m for m in C.evaluate(spec, x, names, every=1).margins}
    model = C.candidate_model(spec, spec.values(x))
    bounds = capability(model, spec.flight.controller).drive
    q = np.asarray(model.home) + traj[:, 1:7] - home     # flown about the candidate's home
    qd, qdd = traj[:, 7:13], traj[:, 13:19]
    kin = inverse_kinematics(model, q, qd, qdd)
    sigma = inverse_dynamics(model, q, qd, qdd)
    assert got["motion_speed"].absolute == pytest.approx(
        bounds.speed / 1.2 - np.abs(kin.rates).max(), rel=1e-9)
    assert got["motion_acceleration"].absolute == pytest.approx(
        bounds.acceleration / 1.2 - np.abs(kin.accelerations).max(), rel=1e-9)
    assert got["motion_force"].absolute == pytest.approx(
        bounds.force / 1.2 - np.abs(sigma).max(), rel=1e-9)
    assert got["motion_force"].relative == pytest.approx(
        got["motion_force"].absolute / (bounds.force / 1.2), rel=1e-12)
    # the motor's current for that force: i = sigma / (Kt zeta / r), against current_limit
    axis = capability(model, spec.flight.controller).axis
    assert got["current"].absolute == pytest.approx(
        axis.motor.current_limit / 1.2 - np.abs(sigma).max() / axis.force_constant, rel=1e-9)
    assert "voltage" in got and np.isfinite(got["voltage"].absolute)


def test_an_impossible_drive_requirement_is_named_with_its_shortfall(tmp_path):
    # every rating kept 10 times free: the cheapest drive cannot give the braking car's torque
    path = design_file(tmp_path, motions={"margin": 10.0},
                       drives={"names": ["SGMSH-15 i20 r25"]})
    out = tmp_path / "out"
    r = cli("design", path, "--out", out, "--workers", "1", "--population", "8",
            "--generations", "2")
    assert r.returncode == 3, r.stderr
    assert "Traceback" not in r.stderr
    with open(out / "candidates.csv") as fh:
        rows = list(csv.DictReader(fh))
    best = max(float(row["margin_torque_rms"]) for row in rows)
    assert best < 0
    line = r.stdout.strip().splitlines()[-1]
    assert "torque_rms" in line and f"short by {-best:.1%}" in line, line
    assert not (out / "best.toml").exists()
    assert "torque_rms" in (out / "summary.md").read_text()


def test_the_example_at_a_reduced_size_finds_a_design_that_flies(tmp_path):
    out = tmp_path / "out"
    r = cli("design", EXAMPLE, "--out", out, "--workers", "2", *REDUCED)
    assert r.returncode == 0, r.stderr
    spec = S.load(EXAMPLE)
    model = load_scene(out / "best.toml")
    drive = drive_of(model)
    # the workspace on the dense grid: every limit, the first resonance
    Q = C.workspace_poses(spec.workspace, model.home, spec.workspace.check_points)
    assert Engine(model, None, spec.requirements.cond_limit).check(Q)["feasible"].all()
    assert modes_map(model, Q).lowest_hz.min() >= spec.requirements.first_resonance
    # the motions cued from the written scene, every sample: stroke, cond, the joint cones,
    # and the drive's ratings with size's margin, from inverse kinematics and dynamics
    keep = 1.0 + spec.flight.margin
    ratio = drive.gear_ratio / drive.pinion_radius
    reflected = drive.gear_ratio**2 * drive.rotor_inertia / drive.pinion_radius**2
    accel_bound = drive.peak_torque * ratio / (constant_load(model) + reflected)
    engine = Engine(model, None, spec.requirements.cond_limit)
    for m, L, rate, acc, cond, sigma in demand(model, motions_of(out / "best.toml")):
        assert len(m.t) > 1000                           # every sample
        assert L.min() >= model.leg_min and L.max() <= model.leg_max
        assert cond.max() < spec.requirements.cond_limit
        assert engine.check(m.q)["feasible"].all()       # the joint cones
        assert np.abs(sigma).max() / ratio * keep <= drive.peak_torque
        assert leg_rms(m.t, sigma / ratio).max() * keep <= drive.continuous_torque
        assert np.abs(rate).max() * ratio * keep <= drive.max_speed
        assert np.abs(acc).max() * keep <= accel_bound
    text = (out / "best.toml").read_text()
    assert f"drive = {drive.name!r}" in text
