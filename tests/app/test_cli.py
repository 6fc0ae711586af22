"""The command line (stewart_sim.cli), called in-process through main([...]), and the installed
console script."""
from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import PARTS, check_poses, inverse_dynamics, inverse_dynamics_parts, io, load_scene
from stewart_sim import cli
from stewart_sim.commands.paper import resolve_scene
from stewart_sim.open_loop import inverse_forces as inverse_files
from stewart_sim.shell import progress

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
RATE = 1000.0
SIGMAS = [f"sigma{i}" for i in range(1, 7)]
PRECIOUS = "an earlier result that must survive\n"


@pytest.fixture(scope="module")
def model():
    """The paper's micro-manipulator."""
    return load_scene(MICRO)


@pytest.fixture(scope="module")
def traj(model) -> tuple[np.ndarray, ...]:
    """A small six-axis sinusoidal trajectory about home (t, q, qd, qdd), 120 samples."""
    t = np.arange(120) / RATE
    amp = np.array([0.01, -0.008, 0.006, 0.05, -0.04, 0.06])
    w = 2 * np.pi * np.array([3.0, 4.0, 5.0, 3.5, 4.5, 2.5])
    phase = np.array([0.1, 0.7, 1.3, 1.9, 2.5, 3.1])
    arg = np.outer(t, w) + phase
    q = model.home + amp * np.sin(arg)
    return t, q, amp * w * np.cos(arg), -amp * w**2 * np.sin(arg)


@pytest.fixture()
def traj_file(tmp_path: Path, traj) -> Path:
    """The trajectory written with the contract's columns."""
    return io.write_csv(tmp_path / "traj.csv", io.trajectory_table(*traj))


def read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and values of a CSV, each cell parsed with float()."""
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array([[float(c) for c in row] for row in rows[1:]])


def columns(header: list[str], values: np.ndarray, prefix: str) -> np.ndarray:
    """The six columns <prefix>1..<prefix>6 as an (N, 6) array."""
    return values[:, [header.index(f"{prefix}{i}") for i in range(1, 7)]]


def run_inverse(scene: Path, trajectory: Path, out: Path, *extra: str) -> int:
    """main(['inverse', ...]) in-process; returns the exit status."""
    return cli.main(["inverse", str(scene), "--trajectory", str(trajectory), "--out", str(out),
                     *extra])


# --- inverse ---------------------------------------------------------------------------------

def test_inverse_writes_exact_forces(tmp_path, model, traj, traj_file, capsys) -> None:
    """Header t,sigma1..6,cond; values == inverse_dynamics and check_poses' cond, bit for bit."""
    out = tmp_path / "forces.csv"
    assert run_inverse(MICRO, traj_file, out) == 0
    header, values = read_table(out)
    assert header == ["t", *SIGMAS, "cond"]
    t, q, qd, qdd = traj
    assert np.array_equal(values[:, 0], t)
    assert np.array_equal(values[:, 1:7], inverse_dynamics(model, q, qd, qdd))
    assert np.array_equal(values[:, 7], check_poses(model, q, t).cond)
    captured = capsys.readouterr()
    assert f"wrote {out}" in captured.out
    assert captured.err == ""  # small runs show no progress


def test_inverse_parts_sum_to_sigma(tmp_path, model, traj, traj_file) -> None:
    """--parts adds <part>1..6 for every part of PARTS the scene has; they sum to sigma."""
    out = tmp_path / "forces.csv"
    assert run_inverse(MICRO, traj_file, out, "--parts") == 0
    header, values = read_table(out)
    assert header == ["t", *SIGMAS, "cond", *(f"{p}{i}" for p in PARTS for i in range(1, 7))]
    sigma = columns(header, values, "sigma")
    parts = {p: columns(header, values, p) for p in PARTS}
    total = sum(parts.values())
    scale = np.max(np.abs(sigma), axis=1, keepdims=True)
    assert np.all(np.abs(total - sigma) <= 1e-12 * scale)
    expected = inverse_dynamics_parts(model, *traj[1:])
    for p in PARTS:
        assert np.array_equal(parts[p], expected[p])


def test_parts_leave_out_absent_effects(tmp_path, traj_file) -> None:
    """A scene without [drive] and [friction] gets no drives/friction columns (not zeros)."""
    text = MICRO.read_text()
    scene = tmp_path / "no_drive.toml"
    scene.write_text(text[:text.index("[drive]")])
    out = tmp_path / "forces.csv"
    assert run_inverse(scene, traj_file, out, "--parts") == 0
    header, values = read_table(out)
    present = ("platform", "lower_legs", "upper_legs", "gravity")
    assert header == ["t", *SIGMAS, "cond", *(f"{p}{i}" for p in present for i in range(1, 7))]
    total = sum(columns(header, values, p) for p in present)
    sigma = columns(header, values, "sigma")
    assert np.all(np.abs(total - sigma) <= 1e-12 * np.max(np.abs(sigma), axis=1, keepdims=True))


def test_blocks_and_progress(tmp_path, traj_file, monkeypatch, capsys) -> None:
    """Processing in small blocks writes the same bytes; long runs report progress on stderr."""
    whole, blocks = tmp_path / "whole.csv", tmp_path / "blocks.csv"
    assert run_inverse(MICRO, traj_file, whole, "--parts") == 0
    capsys.readouterr()
    monkeypatch.setattr(inverse_files, "CHUNK_SAMPLES", 7)
    monkeypatch.setattr(progress, "PROGRESS_SAMPLES", 50)  # 120 samples count as a long run
    monkeypatch.setattr(progress, "PROGRESS_INTERVAL", 0.0)
    assert run_inverse(MICRO, traj_file, blocks, "--parts") == 0
    assert blocks.read_bytes() == whole.read_bytes()
    err = capsys.readouterr().err
    assert "checking poses: 120/120 (100%) samples" in err
    assert "computing and writing forces: 7/120" in err
    assert "computing and writing forces: 120/120 (100%) samples" in err


# --- errors: exit 2, a message that names the problem, outputs untouched ---------------------

def _rewrite(path: Path, line: int, column: str, value: str) -> None:
    """Replace one cell of a CSV (line 1 = header)."""
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    rows[line - 1][io.TRAJECTORY_COLUMNS.index(column)] = value
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def _past_stroke(path: Path, traj) -> None:
    """Sample 40 lifted 0.1 m: legs longer than leg_max = 0.19 m."""
    t, q, qd, qdd = (a.copy() for a in traj)
    q[40, 2] += 0.1
    io.write_csv(path, io.trajectory_table(t, q, qd, qdd))


BAD_INPUTS = {
    "bad header": (lambda p, tr: _rewrite(p, 1, "thz", "thzz"),
                   ["header must be t,x,y,z", "missing ['thz']", "unexpected ['thzz']"]),
    "non-numeric cell": (lambda p, tr: _rewrite(p, 5, "dy", "abc"),
                         ["line 5, column 'dy': not a number: 'abc'"]),
    "NaN": (lambda p, tr: _rewrite(p, 7, "ddthx", "nan"),
            ["line 7, column 'ddthx': non-finite value nan"]),
    "past the stroke": (_past_stroke,
                        ["line 42", "outside the stroke [0.07, 0.19] m",
                         "at sample 40 (t = 0.04 s)"]),
}


@pytest.mark.parametrize("chunk", [inverse_files.CHUNK_SAMPLES, 16])
@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_trajectory(tmp_path, traj, traj_file, case, chunk, monkeypatch, capsys) -> None:
    """Each bad input: status 2, one error line naming line/column or sample/time, no output."""
    monkeypatch.setattr(inverse_files, "CHUNK_SAMPLES", chunk)  # 16: the bad sample lies in a later block
    spoil, expected = BAD_INPUTS[case]
    spoil(traj_file, traj)
    out = tmp_path / "forces.csv"
    out.write_text(PRECIOUS)
    assert run_inverse(MICRO, traj_file, out, "--parts") == 2
    err = capsys.readouterr().err
    assert err.startswith("stewart-sim: error: ") and err.count("\n") == 1
    assert str(traj_file) in err and "Traceback" not in err
    for fragment in expected:
        assert fragment in err
    assert out.read_text() == PRECIOUS
    assert sorted(p.name for p in tmp_path.iterdir()) == ["forces.csv", "traj.csv"]  # no temps


def test_missing_scene(tmp_path, traj_file, capsys) -> None:
    """A scene file that does not exist: status 2, the path named, the output untouched."""
    out = tmp_path / "forces.csv"
    out.write_text(PRECIOUS)
    missing = tmp_path / "no_such_scene.toml"
    assert run_inverse(missing, traj_file, out) == 2
    err = capsys.readouterr().err
    assert err.startswith("stewart-sim: error: ")
    assert f"no such scene file: {missing}" in err
    assert out.read_text() == PRECIOUS


def test_unwritable_output(tmp_path, traj_file, capsys) -> None:
    """An output under a regular file: status 1, naming the output (not a temporary file)."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    out = blocker / "forces.csv"
    assert run_inverse(MICRO, traj_file, out) == 1
    assert capsys.readouterr().err.startswith(f"stewart-sim: error: cannot write {out}: ")


def test_usage_errors_exit_2(capsys) -> None:
    """argparse errors (missing option, bad --duration) return 2 like the input errors."""
    assert cli.main(["inverse", str(MICRO)]) == 2
    assert "--trajectory" in capsys.readouterr().err
    assert cli.main(["demo", str(MICRO), "--out", "x", "--duration", "-1"]) == 2
    assert "--duration" in capsys.readouterr().err


# --- scene-info, demo, paper ----------------------------------------------------------------

def test_scene_info(capsys) -> None:
    """Name, effects, masses, m_d, home leg lengths and cond(J) at home."""
    assert cli.main(["scene-info", str(MICRO)]) == 0
    out = capsys.readouterr().out
    for fragment in ("scene: micro-manipulator", "effects: legs, drive, friction",
                     "platform: mass 0.5 kg", "lower part 0.065 kg", "m_d = zeta^2 I / r^2 = 16 kg",
                     "home leg lengths: [0.128482", "cond(J) at home: 2.3882"):
        assert fragment in out


def test_demo(tmp_path, model, capsys) -> None:
    """demo writes the trajectory, its forces with parts, the plot and the paper rerun."""
    out = tmp_path / "results"
    assert cli.main(["demo", str(MICRO), "--out", str(out), "--duration", "0.05"]) == 0
    stdout = capsys.readouterr().out
    files = ["demo_trajectory.csv", "demo_forces.csv", "demo_forces.png", "paper/report.md"]
    for name in files:
        assert f"wrote {out / name}" in stdout
    assert "agrees" in stdout

    t, q, qd, qdd = io.read_trajectory(out / "demo_trajectory.csv")
    assert t.size == 51 and np.array_equal(t, np.arange(51) / RATE)
    assert np.array_equal(q[0], model.home) and not np.any(qd[0])  # from rest at home
    assert np.all(np.ptp(q, axis=0) > 0)                          # all six coordinates move
    h = 1 / RATE                                                  # exact derivatives: O(h^2)
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * h), qd[1:-1], rtol=0, atol=1e-5)
    np.testing.assert_allclose((qd[2:] - qd[:-2]) / (2 * h), qdd[1:-1], rtol=0, atol=1e-3)

    header, values = read_table(out / "demo_forces.csv")
    assert header[:8] == ["t", *SIGMAS, "cond"] and f"{PARTS[-1]}6" in header
    assert np.array_equal(columns(header, values, "sigma"), inverse_dynamics(model, q, qd, qdd))
    assert (out / "demo_forces.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "paper" / "x_level1.csv").is_file()


def test_paper_default_scene(tmp_path, monkeypatch, capsys) -> None:
    """paper without SCENE uses scenes/micro_manipulator.toml; prints the report and verdicts."""
    monkeypatch.chdir(ROOT)
    assert cli.main(["paper", "--out", str(tmp_path / "paper")]) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'paper' / 'report.md'}" in out
    assert out.count("agree") == 4  # four verdicts: 'agrees' or 'does not agree'
    monkeypatch.chdir(tmp_path)  # elsewhere: the source checkout's copy
    assert resolve_scene(None) == MICRO


def test_console_script_help() -> None:
    """The installed `stewart-sim` entry point runs and lists the subcommands."""
    exe = shutil.which("stewart-sim", path=str(Path(sys.executable).parent))
    assert exe, f"stewart-sim is not installed next to {sys.executable}"
    done = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    for command in ("inverse", "paper", "demo", "scene-info"):
        assert command in done.stdout
