"""`stewart-sim size` (stewart_sim/commands/size.py, stewart_sim/studies/sizing/): the shipped
motion
simulator with the three shipped vehicle motions and the shipped drive catalogue writes its
report; its peak rack force is `inverse`'s on the same motion (through the real commands:
`cue` writes the trajectory, `inverse` its forces); a catalogue drive's torque and speed
recomputed from the scene with that drive put in (stewart_fmu alone); bad catalogue and motion
inputs give one line and exit 2."""
from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import io, load_scene
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim import cli
from tests.app.console import EXE, WAIT, console_env

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"
MOTIONS = [ROOT / "scenes" / "motions" / f"{n}.csv"
           for n in ("braking_car", "lane_change", "takeoff")]
CATALOGUE = ROOT / "scenes" / "catalogues" / "drives.csv"
MARGIN = 0.2                 # size's default (stewart_sim.studies.sizing.study.DEFAULT_MARGIN)
SAME = 1e-12                 # the same float64 computation on the same numbers, relative


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def sized(tmp_path_factory):
    """`cue` on the braking car (its trajectory.csv), then `size` on the three shipped motions
    and that trajectory with the shipped catalogue, as the console script (a local Dask
    cluster of 2 workers)."""
    tmp = tmp_path_factory.mktemp("size")
    assert cli.main(["cue", str(SIM), "--motion", str(MOTIONS[0]), "--out", str(tmp / "cue"),
                     "--no-view"]) == 0
    traj = tmp / "cue" / "trajectory.csv"
    out = tmp / "out"
    proc = subprocess.run([str(EXE), "size", str(SIM), "--motions", *map(str, MOTIONS), str(traj),
                           "--catalogue", str(CATALOGUE), "--out", str(out), "--workers", "2"],
                          capture_output=True, text=True, env=console_env(), timeout=WAIT * 3)
    assert proc.returncode == 0, proc.stderr
    return tmp, traj, out, proc.stdout


def test_size_writes_its_report(sized):
    _, _, out, stdout = sized
    names = {p.name for p in out.iterdir()} - {".stewart-sim-set"}
    assert names == {"report.md", "motions.csv", "scene_checks.csv", "demand.png",
                     "torque_speed.png", "candidates.csv", "candidate_motions.csv",
                     "candidates.png"}
    report = (out / "report.md").read_text()
    for part in ("## Motions", "## What the motions ask of each leg", "## The scene's drive",
                 "## Catalogue: 8 drives", "**Choice: "):
        assert part in report
    assert "drives meet every motion with a 20 % margin" in stdout
    motions = _rows(out / "motions.csv")
    assert [r["kind"] for r in motions] == ["vehicle", "vehicle", "vehicle", "platform"]
    for r in motions:   # units in the column names; the motor's quantities present
        assert {"force_peak_N", "torque_rms_Nm", "motor_speed_peak_rad_s", "power_peak_W",
                "stroke_used_m", "current_peak_A", "voltage_peak_V"} <= set(r)


def test_peak_force_is_inverse_on_the_same_motion(sized, tmp_path):
    """The braking car cued inside `size`, and `cue`'s trajectory.csv given as it is, both peak
    where `inverse` on that trajectory peaks."""
    _, traj, out, _ = sized
    forces = tmp_path / "forces.csv"
    assert cli.main(["inverse", str(SIM), "--trajectory", str(traj), "--out", str(forces),
                     "--no-view"]) == 0
    table = io.read_samples(forces, ("t", *(f"sigma{i}" for i in range(1, 7))), "forces",
                            prefix=True)
    sigma = table[:, 1:]
    k, leg = np.unravel_index(np.argmax(np.abs(sigma)), sigma.shape)
    vehicle, platform = _rows(out / "motions.csv")[0], _rows(out / "motions.csv")[3]
    for row in (vehicle, platform):
        assert float(row["force_peak_N"]) == pytest.approx(sigma[k, leg], rel=SAME, abs=0)
        assert int(row["force_peak_leg"]) == leg + 1
        assert float(row["force_peak_t_s"]) == table[k, 0]
    # the scene's motor: torque is sigma r / zeta, current sigma / (Kt zeta / r)
    assert float(vehicle["torque_peak_Nm"]) == pytest.approx(sigma[k, leg] * 0.04 / 10.0, rel=SAME)
    assert float(vehicle["current_peak_A"]) == pytest.approx(sigma[k, leg] / (0.5 * 10 / 0.04),
                                                             rel=SAME)


def test_catalogue_drive_recomputed_with_the_drive_put_in(sized):
    """Every catalogue drive's peak torque and motor speed on the braking car's trajectory, from
    the scene with that [drive] (load_scene overrides, inverse_dynamics, inverse_kinematics);
    its reflected inertia changes the rack force."""
    _, traj, out, _ = sized
    t, q, qd, qdd = io.read_trajectory(traj)
    by_name = {(r["name"], Path(r["motion"]).name): r
               for r in _rows(out / "candidate_motions.csv")}
    peaks = set()
    for drive in _rows(CATALOGUE):
        zeta, r, inertia = (float(drive[k]) for k in ("gear_ratio", "pinion_radius",
                                                      "rotor_inertia"))
        model = load_scene(SIM, {"drive.gear_ratio": zeta, "drive.pinion_radius": r,
                                 "drive.rotor_inertia": inertia})
        torque = inverse_dynamics(model, q, qd, qdd) * r / zeta
        speed = inverse_kinematics(model, q, qd, qdd).rates * zeta / r
        row = by_name[(drive["name"], "trajectory.csv")]
        assert abs(float(row["torque_peak_Nm"])) == pytest.approx(np.abs(torque).max(), rel=SAME)
        assert abs(float(row["motor_speed_peak_rad_s"])) == pytest.approx(np.abs(speed).max(),
                                                                          rel=SAME)
        peaks.add(round(float(row["force_peak_N"]), 6))
    assert len(peaks) == len(_rows(CATALOGUE))    # each drive's inertia: its own rack force


def test_the_ranking_keeps_the_margin_and_orders_by_price(sized):
    _, _, out, _ = sized
    rows = _rows(out / "candidates.csv")
    assert [int(r["rank"]) for r in rows] == list(range(1, 9))
    good = [r for r in rows if r["qualifies"] == "True"]
    assert 0 < len(good) < len(rows)          # the shipped catalogue has both kinds
    assert rows[:len(good)] == good           # the qualifying drives first
    assert [float(r["price"]) for r in good] == sorted(float(r["price"]) for r in good)
    per_motion = _rows(out / "candidate_motions.csv")
    for r in rows:
        ratios = [float(m[f"{c}_ratio"]) for m in per_motion if m["name"] == r["name"]
                  for c in ("torque_peak", "torque_rms", "motor_speed")]
        assert len(ratios) == 3 * 4
        assert (r["qualifies"] == "True") == (max(ratios) * (1 + MARGIN) <= 1)
        drive = next(d for d in _rows(CATALOGUE) if d["name"] == r["name"])
        rms = max(float(m["torque_rms_Nm"]) for m in per_motion if m["name"] == r["name"])
        assert float(r["torque_rms_ratio"]) == pytest.approx(
            rms / float(drive["continuous_torque"]), rel=SAME)


HEADER = "name,gear_ratio,pinion_radius,rotor_inertia,peak_torque,continuous_torque,max_speed,price"
GOOD = "A,10,0.04,0.002,40,15,400,1000"


@pytest.mark.parametrize("text, words", [
    (f"{HEADER}\nA,ten,0.04,0.002,40,15,400,1000\n", "line 2, column 'gear_ratio': not a number"),
    (f"{HEADER}\nA,-10,0.04,0.002,40,15,400,1000\n", "line 2, column 'gear_ratio': must be > 0"),
    (f"{HEADER}\nA,10,0.04,0.002,40,15,400,nan\n", "line 2, column 'price': not finite"),
    (f"{HEADER}\nA,10,0,0.002,40,15,400,1000\n",
     "line 2, column 'pinion_radius': must be >= 1e-06"),
    (f"{HEADER}\nA,10,0.04,0,40,15,400,1000\n", "line 2, column 'rotor_inertia': must be > 0"),
    (f"{HEADER}\nA,10,0.04,0.002,40,15,1e9,1000\n", "line 2, column 'max_speed': must be <= 20000"),
    (f"{HEADER}\n{GOOD}\nB,10,0.04,0.002,10,15,400,1000\n",
     "line 3, column 'continuous_torque': 15.0 N m above peak_torque"),
    (f"{HEADER}\n{GOOD}\n{GOOD}\n", "line 3, column 'name': 'A' already on line 2"),
    (f"{HEADER}\n,10,0.04,0.002,40,15,400,1000\n", "line 2, column 'name': empty"),
    (f"{HEADER}\n=HYPERLINK(\"x\"),10,0.04,0.002,40,15,400,1000\n",
     "line 2, column 'name': '=HYPERLINK(\"x\")' starts with '='"),
    (f"{HEADER}\n@SUM(A1),10,0.04,0.002,40,15,400,1000\n", "starts with '@'"),
    (f"{HEADER}\n\"A\x1b[2J\",10,0.04,0.002,40,15,400,1000\n", "holds a control character"),
    (f"{HEADER}\n{'A' * 65},10,0.04,0.002,40,15,400,1000\n", "65 characters, at most 64"),
    (f"{HEADER}\nA,10,0.04\n", "line 2: 3 cells for 8 columns"),
    (f"{HEADER},colour\n{GOOD},red\n", "line 1: unknown column 'colour'"),
    (HEADER.replace(",max_speed", "") + "\nA,10,0.04,0.002,40,15,1000\n",
     "line 1: missing column max_speed"),
    (HEADER.replace(",price", "") + "\nA,10,0.04,0.002,40,15,400\n", "need a price or a mass"),
    (f"{HEADER}\n", "no drives, only the header"),
    ("", "empty"),
])
def test_bad_catalogue_is_one_line_and_exit_2(tmp_path, capsys, text, words):
    path = tmp_path / "drives.csv"
    path.write_text(text)
    out = tmp_path / "out"
    status = cli.main(["size", str(SIM), "--motions", str(MOTIONS[0]), "--catalogue", str(path),
                       "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.count("\n") == 1 and err.startswith(f"stewart-sim: error: {path}: "), err
    assert words in err
    assert not out.exists()


def test_bad_motion_inputs_are_one_line_and_exit_2(tmp_path, capsys):
    unknown = tmp_path / "forces.csv"
    unknown.write_text("t,sigma1,sigma2\n0,1,2\n")
    vehicle = tmp_path / "vehicle.csv"
    vehicle.write_text("t,fx,fy,fz,wx,wy,wz\n0,0,0,9.81,0,0,0\n0.01,0,0,inf,0,0,0\n")
    platform = tmp_path / "platform.csv"
    rows = io.trajectory_table(np.array([0.0, 0.1]), np.tile([0, 0, 2.3, 0, 0, 0.0], (2, 1)),
                               np.zeros((2, 6)), np.zeros((2, 6)))
    io.write_csv(platform, rows)
    platform.write_text(platform.read_text().replace("2.3", "x", 1))
    single = tmp_path / "single.csv"
    io.write_csv(single, rows[:1])
    cases = [([str(unknown)], f"{unknown}: header t,sigma1,sigma2 is neither a platform"),
             ([str(single)], f"{single}: need two or more samples, got 1"),
             ([str(vehicle)], f"{vehicle}: line 3, column 'fz': non-finite"),
             ([str(platform)], f"{platform}: line 2, column 'z'"),
             ([str(tmp_path / "missing.csv")], "missing.csv"),
             ([str(MOTIONS[0]), str(MOTIONS[0])], f"{MOTIONS[0]}: given twice")]
    for motions, words in cases:
        status = cli.main(["size", str(SIM), "--motions", *motions, "--out",
                           str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert status == 2, err
        assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "out").exists()


def test_a_cluster_without_a_catalogue_is_refused(tmp_path, capsys):
    status = cli.main(["size", str(SIM), "--motions", str(MOTIONS[0]), "--out",
                       str(tmp_path / "out"), "--workers", "2"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "give --catalogue" in err, err


def test_on_a_running_scheduler_the_ranking_is_the_in_process_one(tmp_path, capsys):
    """`--scheduler` runs the catalogue on a running cluster's workers; the ranking is that of
    evaluate_drive called in this process, drive by drive."""
    from distributed import LocalCluster

    from stewart_fmu.scene import read_scene_dict
    from stewart_sim.scene.load import load
    from stewart_sim.studies.sizing.catalogue import read_catalogue
    from stewart_sim.studies.sizing.motions import read_motions
    from stewart_sim.studies.sizing.study import evaluate_drive, ranking

    motion = MOTIONS[1]
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as cluster:
        status = cli.main(["size", str(SIM), "--motions", str(motion), "--catalogue",
                           str(CATALOGUE), "--out", str(tmp_path / "out"), "--scheduler",
                           cluster.scheduler_address])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert f"({cluster.scheduler_address}, dashboard http" in captured.out
    motions = read_motions(load(SIM), [str(motion)])
    data = read_scene_dict(SIM)
    expected = ranking([evaluate_drive(data, str(SIM), d, motions)
                        for d in read_catalogue(CATALOGUE)], MARGIN)
    rows = _rows(tmp_path / "out" / "candidates.csv")
    assert [r["name"] for r in rows] == [r.drive.name for r in expected]
    assert [float(r["worst_ratio"]) for r in rows] == [r.worst_ratio for r in expected]


def test_without_a_price_the_drives_rank_by_mass(tmp_path):
    from stewart_sim.cueing.feasibility import Margin
    from stewart_sim.studies.sizing.catalogue import read_catalogue
    from stewart_sim.studies.sizing.study import CandidateMotion, CandidateResult, ranking

    path = tmp_path / "drives.csv"
    path.write_text("mass,name,gear_ratio,pinion_radius,rotor_inertia,peak_torque,"
                    "continuous_torque,max_speed\n"
                    "30,heavy,10,0.04,0.002,40,15,400\n\n"
                    "12,light,10,0.04,0.002,40,15,400\n"
                    "5,weak,10,0.04,0.002,40,15,400\n")
    drives = read_catalogue(path)
    assert [(d.name, d.price, d.mass) for d in drives] == [("heavy", None, 30.0),
                                                           ("light", None, 12.0),
                                                           ("weak", None, 5.0)]

    def result(drive, ratio):
        check = Margin("torque_peak", ratio, ratio, 1.0, "N m", 0.0, 0, 1)
        return CandidateResult(drive, (CandidateMotion("m", (check,), {}),), ())

    ranked = ranking([result(drives[0], 0.5), result(drives[1], 0.8), result(drives[2], 0.9)],
                     MARGIN)
    # light and heavy keep the margin (0.8 x 1.2 <= 1), lightest first; weak does not (0.9)
    assert [r.drive.name for r in ranked] == ["light", "heavy", "weak"]


def test_a_motion_past_the_stroke_is_reported_not_refused(tmp_path):
    """Sizing shows what the whole motion would take: a pose past leg_max is a check past its
    limit (exit 0), its forces computed there as `cue`'s feasibility does."""
    path = tmp_path / "high.csv"
    t = np.array([0.0, 0.5, 1.0])
    io.write_csv(path, io.trajectory_table(t, np.tile([0, 0, 3.8, 0, 0, 0.0], (3, 1)),
                                           np.zeros((3, 6)), np.zeros((3, 6))))
    assert cli.main(["size", str(SIM), "--motions", str(path), "--out", str(tmp_path / "out")]) == 0
    checks = {r["check"]: r for r in _rows(tmp_path / "out" / "scene_checks.csv")}
    assert checks["stroke_max"]["verdict"] == "past the limit"
    assert float(checks["stroke_max"]["value"]) > 3.3 and float(checks["stroke_max"]["ratio"]) > 1
    assert checks["force"]["verdict"] == "meets"


def test_a_drives_checks_take_the_demand_alone_with_the_same_numbers(tmp_path):
    """A catalogue drive's checks skip feasibility's (stroke, cond(J)): leg_demand without
    them gives the same arrays, also past the stroke, and drive_result on a model built with
    the drive is evaluate_drive's result, figure for figure."""
    from stewart_fmu.scene import read_scene_dict, scene_from_dict
    from stewart_sim.scene.load import load
    from stewart_sim.studies.sizing.catalogue import read_catalogue
    from stewart_sim.studies.sizing.demand import leg_demand
    from stewart_sim.studies.sizing.motions import read_motions
    from stewart_sim.studies.sizing.study import drive_result, evaluate_drive

    high = tmp_path / "high.csv"      # past leg_max at t = 0.5 s
    t = np.array([0.0, 0.5, 1.0])
    q = np.tile([0, 0, 3.3, 0, 0, 0.0], (3, 1))
    q[1, 2] = 3.8
    io.write_csv(high, io.trajectory_table(t, q, np.zeros((3, 6)), np.zeros((3, 6))))
    motions = read_motions(load(SIM), [str(MOTIONS[1]), str(high)])
    data = read_scene_dict(SIM)
    drive = read_catalogue(CATALOGUE)[0]
    model = scene_from_dict({**data, "drive": drive.drive_table}, str(SIM))
    for m in motions:
        full, alone = leg_demand(model, m, None), leg_demand(model, m, None, checks=False)
        assert alone.feasibility is None and full.feasibility is not None
        assert np.array_equal(alone.t, full.t) and np.array_equal(alone.lengths, full.lengths)
        assert alone.values.keys() == full.values.keys()
        for k, v in full.values.items():
            assert (v is None and alone.values[k] is None) or np.array_equal(alone.values[k], v), k
    past = {mg.quantity: mg for mg in full.feasibility.margins}["stroke_max"]
    assert past.ratio > 1.0      # the second motion is past leg_max
    direct, built = drive_result(model, drive, motions), evaluate_drive(data, str(SIM), drive,
                                                                        motions)
    assert direct.error is None and repr(direct.motions) == repr(built.motions)
    for (s1, t1), (s2, t2) in zip(direct.points, built.points, strict=True):
        assert np.array_equal(s1, s2) and np.array_equal(t1, t2)
