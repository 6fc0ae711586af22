"""The `simulate`, `trajectory` and `case` commands (stewart_sim.open_loop.forward,
stewart_sim.open_loop.references, stewart_sim.studies.cases.report), called through a local argparse parser built from their command modules'
add_parser functions (stewart_sim.commands, the way stewart_sim/cli.py registers them) and
through their pipeline functions."""
from __future__ import annotations

import argparse
import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from controller.moves import demo_trajectory
from stewart_fmu import io, load_scene
from stewart_fmu.errors import StewartError, TrajectoryError
from stewart_fmu.io import POSE, TRAJECTORY_COLUMNS
from stewart_fmu.plant import StepRejected
from stewart_sim import cli
from stewart_sim.open_loop import forward, references
from stewart_sim.open_loop.inverse_forces import run_inverse
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.cases import report as case_report
from tests.helpers import record

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
SIM = ROOT / "scenes" / "motion_simulator.toml"
RATE = 1000.0
H = 1.0 / RATE
ROUND_TRIP_POS = 4e-7     # m, measured 2.6e-7 (micro, demo move, 0.5 s, rk4)
ROUND_TRIP_ANGLE = 4e-6   # rad


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="stewart-sim")
    sub = p.add_subparsers(required=True)
    for name in ("simulate", "trajectory", "case"):
        cli.command_module(name).add_parser(sub, cli.COMMANDS[name])
    return p


def run(*argv: str):
    args = parser().parse_args([str(a) for a in argv])
    return args.run(args)


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array([[float(c) for c in row] for row in rows[1:]])


# --- simulate -------------------------------------------------------------------------------------

def test_simulate_round_trip_of_inverse(tmp_path):
    """A smooth trajectory -> `inverse` forces -> `simulate` (rk4) gives the trajectory back.

    The forces are held over each interval, so they are the inverse dynamics at the interval's
    midpoint (the trajectory file given to `inverse` is the move sampled at t_k + h/2, its force
    rows relabelled t_k): a zero-order hold of midpoint samples is second order. Forces sampled at
    the interval's start lag by h/2: first order, measured and reported below."""
    model = load_scene(MICRO)
    t2, q2, qd2, qdd2 = demo_trajectory(model, 0.5, 2 * RATE)   # every h/2
    mid = tmp_path / "mid.csv"
    io.write_csv(mid, io.trajectory_table(t2[1::2], q2[1::2], qd2[1::2], qdd2[1::2]))
    forces = tmp_path / "forces.csv"
    run_inverse(model, mid, forces, False, Progress())
    header, table = read_csv(forces)
    assert header[:7] == ["t", *(f"sigma{i}" for i in range(1, 7))]
    table[:, 0] -= H / 2                                          # held from t_k
    table = np.vstack([table, table[-1]])                         # a row at the end time
    table[-1, 0] = 0.5
    held = tmp_path / "held.csv"
    io.write_csv(held, io.named_array({n: table[:, k] for k, n in enumerate(header)}))
    run("simulate", MICRO, "--forces", held, "--out", tmp_path / "out", "--integrator", "rk4")
    names, motion = read_csv(tmp_path / "out" / "motion.csv")
    assert names == list(forward.MOTION_COLUMNS)
    assert (tmp_path / "out" / "motion.png").stat().st_size > 0
    q_ref, qd_ref = q2[::2], qd2[::2]
    assert np.allclose(motion[:, 0], np.arange(501) * H, atol=1e-12)
    pos = float(np.abs(motion[:, 1:4] - q_ref[:, :3]).max())
    ang = float(np.abs(motion[:, 4:7] - q_ref[:, 3:]).max())
    record("simulate round trip |x - x_ref| (m), micro demo 0.5 s at 1 kHz", pos, ROUND_TRIP_POS)
    record("simulate round trip |th - th_ref| (rad)", ang, ROUND_TRIP_ANGLE)
    assert pos <= ROUND_TRIP_POS and ang <= ROUND_TRIP_ANGLE, (pos, ang)
    assert np.abs(motion[:, 7:13] - qd_ref).max() < 1e-4
    lengths = np.column_stack([motion[:, 13 + i] for i in range(6)])
    from stewart_fmu.kinematics import inverse_kinematics
    assert np.abs(lengths - inverse_kinematics(model, motion[:, 1:7]).lengths).max() < 1e-12
    # the same forces sampled at the interval starts: first order (the h/2 lag)
    t, q, qd, qdd = demo_trajectory(model, 0.5, RATE)
    from stewart_fmu import inverse_dynamics
    lag = forward.simulate(model, t, inverse_dynamics(model, q, qd, qdd), "rk4")
    lag_err = float(np.max([np.abs(lag[c] - q[:, k]).max() for k, c in enumerate(POSE[:3])]))
    assert 100 * pos < lag_err < 1e-3


def test_simulate_refused_step_writes_nothing(tmp_path):
    """Forces far above the hold drive a leg out of its stroke: StepRejected (one line, naming
    the time), and no output directory, not even a partial one."""
    model = load_scene(MICRO)
    t = np.arange(501) * H
    hold = forward.simulate(model, t[:2], np.tile(_hold(model), (2, 1)))   # sanity: holds
    assert abs(hold["z"][-1] - model.home[2]) < 1e-12
    forces = tmp_path / "push.csv"
    sigma = np.tile(_hold(model) + 50.0, (t.size, 1))
    io.write_csv(forces, io.named_array({"t": t, **{f"sigma{i + 1}": sigma[:, i] for i in range(6)}}))
    out = tmp_path / "out"
    with pytest.raises(StewartError) as exc:
        run("simulate", MICRO, "--forces", forces, "--out", out)
    assert isinstance(exc.value, (StepRejected,)) or "unstable" in str(exc.value)
    assert "\n" not in str(exc.value) and "t =" in str(exc.value)
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]
    (out).mkdir()
    (out / "keep.txt").write_text("x")
    with pytest.raises(StewartError):
        run("simulate", MICRO, "--forces", forces, "--out", out)
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]


def _hold(model) -> np.ndarray:
    from stewart_fmu import inverse_dynamics
    return inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))


@pytest.mark.parametrize("text, message", [
    ("t,sigma1\n0,1\n", "header must start with t,sigma1"),
    ("t,sigma1,sigma2,sigma3,sigma4,sigma5,sigma6\n0,1,1,1,1,1,1\n", "two or more samples"),
    ("t,sigma1,sigma2,sigma3,sigma4,sigma5,sigma6\n0,1,1,1,1,1,1\n0,1,1,1,1,x,1\n", "line 3, column 'sigma5'"),
    ("t,sigma1,sigma2,sigma3,sigma4,sigma5,sigma6\n0,1,1,1,1,1,1\n0,1,1,1,1,1,1\n", "time must increase"),
    ("t,sigma1,sigma2,sigma3,sigma4,sigma5,sigma6\n0,1,1,1,1,1,1\n1,nan,1,1,1,1,1\n", "non-finite"),
])
def test_simulate_bad_forces_file(tmp_path, text, message):
    path = tmp_path / "f.csv"
    path.write_text(text)
    with pytest.raises(TrajectoryError, match=message):
        run("simulate", MICRO, "--forces", path, "--out", tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(TrajectoryError, match="cannot read"):
        forward.read_forces(tmp_path / "missing.csv")


# --- trajectory -----------------------------------------------------------------------------------

@pytest.mark.parametrize("move", references.MOVES)
def test_trajectory_moves_feed_inverse(tmp_path, move):
    """Each move's file has the contract's columns, starts at rest at home and `inverse` reads
    it; its forces equal the inverse dynamics of the move built in memory."""
    model = load_scene(SIM)
    out = tmp_path / f"{move}.csv"
    run("trajectory", SIM, "--move", move, "--out", out, "--rate", 500, "--duration", 2)
    t, q, qd, qdd = io.read_trajectory(out)
    assert t[0] == 0.0 and t[-1] == pytest.approx(2.0) and np.allclose(np.diff(t), 1 / 500)
    assert np.array_equal(q[0], model.home) and not qd[0].any()
    forces = tmp_path / "forces.csv"
    n, table = run_inverse(model, out, forces, False, Progress(), keep=True)
    assert n == t.size
    ref = references.move(model, move, 2.0, 500.0)
    from stewart_fmu import inverse_dynamics
    sigma = np.column_stack([table[f"sigma{i}"] for i in range(1, 7)])
    assert np.array_equal(sigma, inverse_dynamics(model, ref.q, ref.qd, ref.qdd))


def test_trajectory_waypoints_round_trip(tmp_path):
    """A spline through waypoints passes through them, rests at both ends, and round-trips
    through its CSV (repr-exact) and `inverse`."""
    model = load_scene(MICRO)
    home = model.home
    wp = tmp_path / "w.csv"
    poses = [home, home + [0.002, 0, 0.003, 0, 0.02, 0], home + [-0.002, 0.001, 0, 0.01, 0, -0.02], home]
    with wp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *POSE])
        for tk, pose in zip((0.0, 0.3, 0.7, 1.0), poses):
            w.writerow([tk, *pose])
    out = tmp_path / "t.csv"
    run("trajectory", MICRO, "--waypoints", wp, "--out", out, "--rate", 200)
    t, q, qd, qdd = io.read_trajectory(out)
    assert t.size == 201
    for tk, pose in zip((0.0, 0.3, 0.7, 1.0), poses):
        k = int(round(tk * 200))
        assert np.allclose(q[k], pose, atol=1e-15)
    assert np.abs(qd[[0, -1]]).max() < 1e-15
    ref = references.waypoint_trajectory(wp, 200.0)
    assert np.array_equal(q, ref.q) and np.array_equal(qdd, ref.qdd)
    n, _ = run_inverse(model, out, tmp_path / "f.csv", True, Progress())
    assert n == 201


def test_trajectory_errors(tmp_path):
    wp = tmp_path / "w.csv"
    wp.write_text("t,x,y,z,thx,thy,thz\n0,0,0,0.12,0,0,0\n1,0,0,0.5,0,0,0\n")
    with pytest.raises(StewartError, match="stroke"):          # checked by inverse kinematics
        run("trajectory", MICRO, "--waypoints", wp, "--out", tmp_path / "t.csv")
    assert not (tmp_path / "t.csv").exists()
    with pytest.raises(StewartError, match="--duration applies to --move only"):
        run("trajectory", MICRO, "--waypoints", wp, "--out", tmp_path / "t.csv", "--duration", 1)
    wp.write_text("t,x,y\n0,0,0\n")
    with pytest.raises(TrajectoryError, match="header must start with"):
        run("trajectory", MICRO, "--waypoints", wp, "--out", tmp_path / "t.csv")
    with pytest.raises(SystemExit):                                # usage: neither or both
        parser().parse_args(["trajectory", str(MICRO), "--out", "x.csv"])
    with pytest.raises(SystemExit):
        parser().parse_args(["trajectory", str(MICRO), "--move", "demo", "--out", "x.csv", "--rate", "-1"])


def test_trajectory_columns_are_the_contract():
    assert tuple(io.trajectory_table(*(np.zeros((2, 6)) if k else np.arange(2.0) for k in range(4))).dtype.names) \
        == TRAJECTORY_COLUMNS


# --- case -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("scene, expect", [("stiff/compliant.toml", "ok"),
                                            ("extreme/stroke_crossing.toml", "StrokeLimitError")])
def test_case_as_expected_exits_0(capsys, scene, expect):
    assert run("case", ROOT / "scenes" / scene) == 0
    out = capsys.readouterr().out
    assert f"expected: {expect}" in out and f"outcome:  {expect}" in out
    assert "verdict: as expected" in out
    if expect == "ok":
        assert "cond(J) max" in out and "final pose" in out
    else:
        assert "error: " in out and "t = " in out


def test_case_mismatch_exits_1(tmp_path, capsys):
    src = (ROOT / "scenes" / "extreme" / "stroke_crossing.toml").read_text()
    scene = tmp_path / "wrong.toml"
    scene.write_text(src.replace('expect = "StrokeLimitError"', 'expect = "ok"'))
    with pytest.raises(SystemExit) as exc:
        run("case", scene)
    assert exc.value.code == case_report.MISMATCH_STATUS == 1
    assert "verdict: NOT as expected" in capsys.readouterr().out


def test_case_needs_a_case_table(tmp_path):
    with pytest.raises(StewartError, match=r"no \[case\] table"):
        run("case", MICRO)
    shutil.copy(MICRO, tmp_path / "m.toml")
    with pytest.raises(SystemExit):
        parser().parse_args(["case", str(tmp_path / "m.toml"), "--duration", "0"])


def test_the_command_line_runs_the_new_commands(tmp_path, capsys):
    """stewart-sim lists simulate, trajectory and case in --help (without importing them) and
    runs each through cli.main with its module's own arguments."""
    assert cli.main(["--help"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in ("simulate", "trajectory", "case"))
    out = tmp_path / "t.csv"
    assert cli.main(["trajectory", str(MICRO), "--move", "demo", "--duration", "0.2",
                     "--out", str(out)]) == 0
    assert out.read_text().startswith("t,x,y,z,")
    assert cli.main(["simulate", str(MICRO), "--forces", str(tmp_path / "missing.csv"),
                     "--out", str(tmp_path / "sim")]) == 2     # one line, exit 2
    assert "missing.csv" in capsys.readouterr().err
