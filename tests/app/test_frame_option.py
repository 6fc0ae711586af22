"""`--frame NAME` on every command that reads or writes poses: on a scene whose [frames] rotate
and shift (the user frame on the base, the tool frame on the platform), each command run in a
frame gives what the platform run gives, after converting its files back with
stewart_fmu.frames (or with them converted in). The contract's columns stay as they are; the
frame is said on the terminal. An unknown frame is one line naming it, exit 2."""
from __future__ import annotations

import contextlib
import csv
import io as text_io
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import io
from stewart_fmu.frames import from_platform, motion_from_platform, motion_to_platform, \
    table_from_platform, table_to_platform
from stewart_fmu.scene import load_scene
from stewart_sim import cli
from stewart_sim.view.sources import read_run_table

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
SHIPPED_POSES = ROOT / "scenes" / "poses" / "micro_manipulator.csv"
BRAKING = ROOT / "scenes" / "motions" / "braking_car.csv"
FRAMES = ("\n[frames]\npivot = [0.01, -0.02, 0.05]\nuser = [0.1, -0.2, 0.3, 0.1, -0.2, 0.3]\n"
          "tool = [0.02, 0.01, 0.04, -0.3, 0.2, 0.1]\n")
ROUND_TRIP = 1e-15       # relative, the conversion's round trip (tests/stewart_fmu/test_frame_motion.py)


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("frames") / "framed.toml"
    path.write_text(MICRO.read_text(encoding="utf-8") + FRAMES, encoding="utf-8")
    return path


def main(*args) -> tuple[int, str]:
    out = text_io.StringIO()
    with contextlib.redirect_stdout(out):
        code = cli.main([str(a) for a in args])
    return code, out.getvalue()


def relative(a: np.ndarray, b: np.ndarray, via: np.ndarray) -> float:
    """max |a - b| per block of three columns (positions, angles) over the largest value of
    that block in b or in `via`, the same quantity in the other frame (the round trip's
    scale, as tests/stewart_fmu/test_frame_motion.py measures it)."""
    a, b, via = (np.asarray(x, float) for x in (a, b, via))
    return max(np.max(np.abs(a[:, k:k + 3] - b[:, k:k + 3]))
               / max(np.max(np.abs(b[:, k:k + 3])), np.max(np.abs(via[:, k:k + 3])), 1e-300)
               for k in range(0, b.shape[1], 3))


def motion_of(path: Path) -> tuple[np.ndarray, ...]:
    return io.read_trajectory(path)


def test_trajectory_then_inverse_in_the_user_frame(scene, tmp_path):
    """trajectory --frame user writes the move's motion in the user frame (the platform file's
    motion converted, to the round trip); inverse --frame user reads it back into the platform
    file's forces."""
    model = load_scene(scene)
    p, u = tmp_path / "p.csv", tmp_path / "u.csv"
    assert main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", p)[0] == 0
    code, text = main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", u,
                      "--frame", "user")
    assert code == 0 and "user frame" in text
    assert io.csv_header(u, "t") == io.csv_header(p, "t") == io.TRAJECTORY_COLUMNS
    t, q, qd, qdd = motion_of(p)
    tu, *fu = motion_of(u)
    assert np.array_equal(t, tu)
    expected = motion_from_platform(model, q, qd, qdd, "user")
    for got, want in zip(fu, expected):             # the same numbers, written repr-exact
        assert np.array_equal(got, want)
    assert np.max(np.abs(fu[0] - q)) > 0.1          # the frame is not the platform's
    back = motion_to_platform(model, *fu, "user")
    for got, want, via in zip(back, (q, qd, qdd), fu):
        assert relative(got, want, via) <= ROUND_TRIP
    fp, fuser = tmp_path / "fp.csv", tmp_path / "fu.csv"
    assert main("inverse", scene, "--trajectory", p, "--out", fp, "--no-view")[0] == 0
    code, text = main("inverse", scene, "--trajectory", u, "--out", fuser, "--no-view",
                      "--frame", "user")
    assert code == 0 and "user frame" in text
    a = np.genfromtxt(fp, delimiter=",", names=True)
    b = np.genfromtxt(fuser, delimiter=",", names=True)
    sa = np.column_stack([a[f"sigma{i}"] for i in range(1, 7)])
    sb = np.column_stack([b[f"sigma{i}"] for i in range(1, 7)])
    err = np.max(np.abs(sa - sb)) / np.max(np.abs(sa))
    print(f"inverse: forces from the user-frame file within {err:.3g} of the platform file's")
    assert err <= 4 * ROUND_TRIP        # the round trip's error through the dynamics (~1e-15)


def test_waypoints_in_the_tool_frame(scene, tmp_path):
    """--waypoints given in the tool frame: the spline through their platform poses, written
    in the tool frame."""
    model = load_scene(scene)
    times = np.array([0.0, 0.5, 1.0])
    poses = model.home + np.array([[0, 0, 0, 0, 0, 0], [0.003, -0.002, 0.004, 0.02, -0.03, 0.05],
                                   [0, 0, 0, 0, 0, 0]])
    for name, rows in (("wp.csv", poses), ("wt.csv", from_platform(model, poses, "tool"))):
        io.write_csv(tmp_path / name, io.named_array(
            {c: col for c, col in zip(("t", *io.POSE), np.column_stack([times, rows]).T)}))
    assert main("trajectory", scene, "--waypoints", tmp_path / "wp.csv",
                "--out", tmp_path / "p.csv")[0] == 0
    assert main("trajectory", scene, "--waypoints", tmp_path / "wt.csv",
                "--out", tmp_path / "t.csv", "--frame", "tool")[0] == 0
    _, q, qd, qdd = motion_of(tmp_path / "p.csv")
    _, *ft = motion_of(tmp_path / "t.csv")
    back = motion_to_platform(model, *ft, "tool")
    # the waypoints went through one round trip more than the platform file's, then the spline
    for name, got, want, via in zip(("q", "qd", "qdd"), back, (q, qd, qdd), ft):
        err = relative(got, want, via)
        print(f"waypoints in the tool frame: {name} within {err:.3g}")
        assert err <= 4 * ROUND_TRIP


def test_simulate_writes_motion_in_the_frame(scene, tmp_path):
    """motion.csv's poses and rates in the tool frame are the platform run's, converted; the
    leg lengths are the same numbers."""
    model = load_scene(scene)
    traj = tmp_path / "t.csv"
    assert main("trajectory", scene, "--move", "demo", "--duration", "0.5", "--out", traj)[0] == 0
    forces = tmp_path / "f.csv"
    assert main("inverse", scene, "--trajectory", traj, "--out", forces, "--no-view")[0] == 0
    assert main("simulate", scene, "--forces", forces, "--out", tmp_path / "p")[0] == 0
    code, text = main("simulate", scene, "--forces", forces, "--out", tmp_path / "t",
                      "--frame", "tool")
    assert code == 0 and "tool frame" in text
    a = np.genfromtxt(tmp_path / "p" / "motion.csv", delimiter=",", names=True)
    b = np.genfromtxt(tmp_path / "t" / "motion.csv", delimiter=",", names=True)
    assert a.dtype.names == b.dtype.names
    for c in ("t", *(f"l{i}" for i in range(1, 7))):
        assert np.array_equal(a[c], b[c])
    back = table_to_platform(model, b, "tool")
    for prefix in ("", "d"):
        cols = [prefix + c for c in io.POSE]
        got = np.column_stack([back[c] for c in cols])
        want = np.column_stack([a[c] for c in cols])
        via = np.column_stack([b[c] for c in cols])
        assert relative(got, want, via) <= ROUND_TRIP


def test_run_writes_poses_in_the_frame(scene, tmp_path):
    """run.csv's poses and references in the user frame are the platform run's converted; the
    frame is said in summary.md and on the terminal."""
    model = load_scene(scene)
    assert main("run", scene, "--out", tmp_path / "p", "--duration", "0.5", "--no-view")[0] == 0
    code, text = main("run", scene, "--out", tmp_path / "u", "--duration", "0.5", "--no-view",
                      "--frame", "user")
    assert code == 0 and "poses in the user frame" in text
    assert "the user frame" in (tmp_path / "u" / "summary.md").read_text(encoding="utf-8")
    a, b = read_run_table(tmp_path / "p" / "run.csv"), read_run_table(tmp_path / "u" / "run.csv")
    assert io.csv_header(tmp_path / "p" / "run.csv", "run") == \
        io.csv_header(tmp_path / "u" / "run.csv", "run")
    back = table_to_platform(model, b, "user")
    for suffix in ("", "_ref"):
        cols = [c + suffix for c in io.POSE]
        want = np.column_stack([a[c] for c in cols])
        via = np.column_stack([b[c] for c in cols])
        assert relative(np.column_stack([back[c] for c in cols]), want, via) <= ROUND_TRIP
        assert np.max(np.abs(via - want)) > 0.1


def test_link_reference_read_in_the_frame(scene, tmp_path):
    """run --link --trajectory T.csv --frame user: the reference is the platform one."""
    from stewart_sim.closed_loop.over_link import link_trajectory
    from stewart_sim.scene.load import load

    s = load(scene)
    p, u = tmp_path / "p.csv", tmp_path / "u.csv"
    assert main("trajectory", scene, "--move", "run", "--duration", "0.4", "--out", p)[0] == 0
    assert main("trajectory", scene, "--move", "run", "--duration", "0.4", "--out", u,
                "--frame", "user")[0] == 0
    config = s.require_controller()
    a = link_trajectory(s.model, config, p)
    b = link_trajectory(s.model, config, u, "user")
    assert np.array_equal(a.t, b.t)
    _, *fu = motion_of(u)
    for got, want, via in zip((b.q, b.qd, b.qdd), (a.q, a.qd, a.qdd), fu):
        assert relative(got, want, via) <= ROUND_TRIP


def test_cue_writes_its_trajectory_in_the_frame(scene, tmp_path):
    """cue --frame tool: trajectory.csv is the platform cue's motion in the tool frame; the
    forces are the same numbers; summary.md says the frame."""
    model = load_scene(scene)
    motion = tmp_path / "short.csv"
    motion.write_text("".join(BRAKING.read_text(encoding="utf-8").splitlines(True)[:301]),
                      encoding="utf-8")
    assert main("cue", scene, "--motion", motion, "--out", tmp_path / "p", "--no-view")[0] == 0
    code, text = main("cue", scene, "--motion", motion, "--out", tmp_path / "t", "--no-view",
                      "--frame", "tool")
    assert code == 0 and "trajectories in the tool frame" in text
    assert "in the tool frame" in (tmp_path / "t" / "summary.md").read_text(encoding="utf-8")
    _, q, qd, qdd = motion_of(tmp_path / "p" / "trajectory.csv")
    _, *ft = motion_of(tmp_path / "t" / "trajectory.csv")
    for got, want in zip(ft, motion_from_platform(model, q, qd, qdd, "tool")):
        assert np.array_equal(got, want)
    assert (tmp_path / "p" / "forces.csv").read_bytes() == (tmp_path / "t" / "forces.csv").read_bytes()


def test_excite_writes_in_the_frame(scene, tmp_path):
    """excite --frame user: T.csv is the platform excitation's motion in the user frame."""
    model = load_scene(scene)
    args = ("--starts", "1", "--harmonics", "2", "--period", "2", "--duration", "2")
    assert main("excite", scene, "--out", tmp_path / "p.csv", *args)[0] == 0
    code, text = main("excite", scene, "--out", tmp_path / "u.csv", *args, "--frame", "user")
    assert code == 0 and "user frame" in text
    assert "user frame" in (tmp_path / "u.md").read_text(encoding="utf-8")
    _, q, qd, qdd = motion_of(tmp_path / "p.csv")
    _, *fu = motion_of(tmp_path / "u.csv")
    for got, want in zip(fu, motion_from_platform(model, q, qd, qdd, "user")):
        assert np.array_equal(got, want)


def test_size_reads_trajectories_in_the_frame(scene, tmp_path):
    """size --frame user on the user-frame file sizes the platform file's motion: the same
    peak rack force to the digits printed."""
    p, u = tmp_path / "p.csv", tmp_path / "u.csv"
    assert main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", p)[0] == 0
    assert main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", u,
                "--frame", "user")[0] == 0
    code_p, text_p = main("size", scene, "--motions", p, "--out", tmp_path / "sp")
    code_u, text_u = main("size", scene, "--motions", u, "--out", tmp_path / "su",
                          "--frame", "user")
    assert code_p == code_u == 0 and "read in the user frame" in text_u

    def peak(text: str) -> str:
        line = next(ln for ln in text.splitlines() if ln.startswith("peak rack force"))
        return line.split(",")[0] + line.split(",")[1]

    assert peak(text_p) == peak(text_u)
    assert "(user frame)" in (tmp_path / "su" / "report.md").read_text(encoding="utf-8")


def test_view_reads_poses_in_the_frame(scene, tmp_path):
    """view of the user-frame trajectory and run table shows the platform poses."""
    from stewart_sim.view.sources import view_of
    from stewart_sim.scene.load import load

    s = load(scene)
    p, u = tmp_path / "p.csv", tmp_path / "u.csv"
    assert main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", p)[0] == 0
    assert main("trajectory", scene, "--move", "demo", "--duration", "1", "--out", u,
                "--frame", "user")[0] == 0
    a = view_of(p, s.model, controller=s.controller)
    b = view_of(u, s.model, controller=s.controller, frame="user")
    qa, qb = np.asarray(a.q, float), np.asarray(b.q, float)
    assert qa.shape == qb.shape and relative(qb, qa, motion_of(u)[1]) <= ROUND_TRIP
    code, text = main("view", u, "--scene", scene, "-o", tmp_path / "v.html", "--frame", "user")
    assert code == 0 and "user frame" in text


def test_calibrate_reads_poses_in_the_frame(scene, tmp_path):
    """The shipped tracker poses given in the tool frame calibrate as the platform poses do
    (the least-squares estimate to 1e-12 m: the same data to the round trip)."""
    model = load_scene(scene)
    with SHIPPED_POSES.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    cols = [header.index(c) for c in io.POSE]
    framed = data.copy()
    framed[:, cols] = from_platform(model, data[:, cols], "tool")
    path = tmp_path / "tool.csv"
    io.write_csv(path, io.named_array({c: framed[:, k] for k, c in enumerate(header)}))
    assert main("calibrate", scene, "--poses", SHIPPED_POSES, "--out", tmp_path / "p",
                "--select", "50")[0] == 0
    code, text = main("calibrate", scene, "--poses", path, "--out", tmp_path / "t",
                      "--select", "50", "--frame", "tool")
    assert code == 0 and "tool frame" in text
    a = np.genfromtxt(tmp_path / "p" / "calibration.csv", delimiter=",", names=True,
                      dtype=None, encoding="utf-8")
    b = np.genfromtxt(tmp_path / "t" / "calibration.csv", delimiter=",", names=True,
                      dtype=None, encoding="utf-8")
    err = np.max(np.abs(a["estimate"] - b["estimate"]))
    print(f"calibrate: estimates from the tool-frame poses within {err:.3g} m")
    assert err <= 1e-12


COMMANDS = {
    "trajectory": ["--move", "demo", "--out", "{tmp}/t.csv"],
    "inverse": ["--trajectory", "{tmp}/t.csv", "--out", "{tmp}/f.csv"],
    "simulate": ["--forces", "{tmp}/f.csv", "--out", "{tmp}/s"],
    "run": ["--out", "{tmp}/r"],
    "cue": ["--motion", str(BRAKING), "--out", "{tmp}/c"],
    "excite": ["--out", "{tmp}/e.csv"],
    "size": ["--motions", str(BRAKING), "--out", "{tmp}/z"],
    "calibrate": ["--poses", str(SHIPPED_POSES), "--out", "{tmp}/k"],
    "workspace": ["--ranges"],
    "modes": ["--out", "{tmp}/m"],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_unknown_frame_is_one_line(scene, tmp_path, capsys, command):
    """--frame tcp: one line naming it, exit 2, nothing written."""
    args = [a.format(tmp=tmp_path) for a in COMMANDS[command]]
    assert cli.main([command, str(scene), *args, "--frame", "tcp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'tcp'" in err[0] and "unknown frame" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_view_unknown_frame_is_one_line(scene, tmp_path, capsys):
    traj = tmp_path / "t.csv"
    assert main("trajectory", scene, "--move", "demo", "--duration", "0.5", "--out", traj)[0] == 0
    capsys.readouterr()
    assert cli.main(["view", str(traj), "--scene", str(scene), "-o", str(tmp_path / "v.html"),
                     "--frame", "tcp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'tcp'" in err[0]
    assert not (tmp_path / "v.html").exists()


def test_table_conversions_invert_each_other(scene):
    """table_to_platform undoes table_from_platform on a table with poses, rates, references
    and other columns (which pass unchanged)."""
    model = load_scene(scene)
    rng = np.random.default_rng(5)
    n = 50
    cols = {"time": np.arange(n) * 0.01}
    q = model.home + rng.uniform(-1, 1, (n, 6)) * [0.01, 0.01, 0.01, 0.2, 0.2, 0.2]
    for k, c in enumerate(io.POSE):
        cols[c] = q[:, k]
        cols["d" + c] = rng.uniform(-1, 1, n)
        cols[c + "_ref"] = q[:, k] + 1e-3
        cols[f"l{k + 1}"] = rng.uniform(0.1, 0.2, n)
    table = io.named_array(cols)
    framed = table_from_platform(model, table, "user")
    back = table_to_platform(model, framed, "user")
    for c in table.dtype.names:
        if c.startswith("l") or c == "time":
            assert np.array_equal(framed[c], table[c])
        assert np.allclose(back[c], table[c], rtol=0, atol=2e-15 * max(1, np.abs(table[c]).max()))


def test_the_scene_default_frame_applies(scene, tmp_path):
    """Without --frame, the scene's [frames] default: the same file as --frame user; --frame
    platform overrides it."""
    default = tmp_path / "default.toml"
    default.write_text(Path(scene).read_text(encoding="utf-8") + 'default = "user"\n',
                       encoding="utf-8")
    args = ("--move", "demo", "--duration", "0.5", "--out")
    assert main("trajectory", scene, *args, tmp_path / "u.csv", "--frame", "user")[0] == 0
    code, text = main("trajectory", default, *args, tmp_path / "d.csv")
    assert code == 0 and "user frame" in text
    assert (tmp_path / "u.csv").read_bytes() == (tmp_path / "d.csv").read_bytes()
    assert main("trajectory", scene, *args, tmp_path / "p.csv")[0] == 0
    assert main("trajectory", default, *args, tmp_path / "o.csv", "--frame", "platform")[0] == 0
    assert (tmp_path / "p.csv").read_bytes() == (tmp_path / "o.csv").read_bytes()
