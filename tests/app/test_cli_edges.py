"""The command line's edges: result sets all or nothing (a real SIGINT), bad inputs as one line
and exit 2, scene-info checking what run checks, start-up without the heavy imports."""
from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from controller.moves import demo_trajectory
from stewart_fmu import io, load_scene
from stewart_sim import cli
from stewart_sim.shell import interrupt, outputs, progress, run_length
from stewart_sim.shell.outputs import MANIFEST
from stewart_sim.view import files as view_command
from tests.app.console import EXE, WAIT, partials, signal_when_ready

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
EARLIER = {"summary.md": "# an earlier result that must survive\n",
           "run.csv": "t,x\n0.0,1.0\n"}


def _listing(d: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in d.iterdir()} if d.exists() else {}


def _after(seconds: float):
    """ready(): the temporary directory exists, then `seconds` more."""
    seen: list[float] = []

    def ready(_: Path) -> bool:
        seen.append(time.monotonic())
        return seen[-1] - seen[0] >= seconds
    return ready


@pytest.mark.parametrize("command", ["run", "compare", "paper", "accuracy"])
@pytest.mark.parametrize("earlier", [True, False], ids=["over_earlier_set", "new_dir"])
def test_sigint_keeps_the_earlier_set_whole(command, earlier, tmp_path) -> None:
    """A real Ctrl-C mid-command: exit 130, one line saying what was kept, and DIR holds
    exactly the earlier set (or does not exist); no temporary directory is left."""
    out = tmp_path / "out"
    if earlier:
        out.mkdir()
        for name, text in EARLIER.items():
            (out / name).write_text(text)
    args = {"run": ["run", str(MICRO), "--duration", "1"],
            "compare": ["compare", str(MICRO), "--points", "2"],
            "paper": ["paper", str(MICRO)],
            "accuracy": ["accuracy", str(MICRO), "--repeats", "1"]}[command]
    # run: once run.csv is written into the temporary directory (the plots take seconds more)
    ready = (lambda d: (d / "run.csv").exists()) if command == "run" else _after(0.3)
    status, err = signal_when_ready([*args, "--out", str(out)], out, ready)
    assert status == 130, err
    line = err.rstrip().splitlines()[-1]
    assert line.startswith(f"stewart-sim: error: interrupted: nothing new written, {out} ")
    assert ("the earlier set untouched" if earlier else "not created") in line
    assert _listing(out) == (EARLIER if earlier else {})
    assert partials(out) == []


def test_a_rerun_replaces_the_earlier_set_whole(tmp_path, capsys) -> None:
    """A second command into DIR removes every file of the first set, keeps foreign files."""
    out = tmp_path / "out"
    assert cli.main(["run", str(MICRO), "--out", str(out), "--duration", "0.5"]) == 0
    (out / "notes.txt").write_text("mine\n")
    assert cli.main(["accuracy", str(MICRO), "--out", str(out), "--repeats", "1",
                     "--no-closed-loop"]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {"open_loop.csv", "work_precision.png", "summary.md", "notes.txt", MANIFEST}
    assert "Closed-loop run" not in (out / "summary.md").read_text()
    assert partials(out) == []
    capsys.readouterr()


def test_an_earlier_set_without_manifest_is_replaced_by_its_known_names(tmp_path, capsys) -> None:
    """`run` over a set written before the manifest existed: no stale run_link.png is left."""
    out = tmp_path / "out"
    out.mkdir()
    for name in ("run.csv", "run_link.png", "summary.md"):
        (out / name).write_text("old\n")
    assert cli.main(["run", str(MICRO), "--out", str(out), "--duration", "0.5"]) == 0
    assert {p.name for p in out.iterdir()} == {*cli_run_files(), MANIFEST}
    capsys.readouterr()


def cli_run_files() -> tuple[str, ...]:
    from stewart_sim.closed_loop.run_files import RUN_FILES
    return RUN_FILES


# --- inverse: FORCES.csv and FORCES.html together or not at all ------------------------------

EARLIER_PAIR = {"F.csv": "t,sigma1\n0.0,1.0\n", "F.html": "<p>an earlier view</p>\n"}


@pytest.fixture(scope="module")
def long_traj(tmp_path_factory) -> Path:
    """60 s of the demo move at 1 kHz: 60,001 samples, seconds of work for `inverse`."""
    return _demo_file(tmp_path_factory.mktemp("traj"), 60.0)


def _demo_file(d: Path, duration: float) -> Path:
    path = d / "traj.csv"
    io.write_csv(path, io.trajectory_table(*demo_trajectory(load_scene(MICRO), duration)))
    return path


def _earlier_pair(d: Path, names=EARLIER_PAIR) -> None:
    for name in names:
        (d / name).write_text(EARLIER_PAIR[name])


def _inverse(traj: Path, out: Path) -> list[str]:
    return ["inverse", str(MICRO), "--trajectory", str(traj), "--out", str(out)]


@pytest.mark.parametrize("earlier", [["F.csv", "F.html"], ["F.csv"]], ids=["both", "csv_only"])
@pytest.mark.parametrize("failure", ["disk full", "Ctrl-C"])
def test_inverse_page_failing_leaves_the_earlier_files(failure, earlier, tmp_path, monkeypatch,
                                                       capsys) -> None:
    """The page fails after FORCES.csv is written (in its temporary): neither new file
    appears, the earlier ones are as they were, no temporary is left; exit 1 naming the page
    (not its temporary), or 130 saying what was kept."""
    traj = _demo_file(tmp_path, 0.2)
    work = tmp_path / "work"
    work.mkdir()
    _earlier_pair(work, earlier)
    staged: list[Path] = []

    def fail(path: Path, view) -> int:
        staged.extend(path.parent.iterdir())           # what the temporary holds by now
        if failure == "Ctrl-C":
            raise KeyboardInterrupt
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(view_command, "write_view", fail)
    status = cli.main(_inverse(traj, work / "F.csv"))
    err = _one_error_line(capsys)
    assert [p.name for p in staged] == ["F.csv"]                 # the forces were written
    if failure == "Ctrl-C":
        assert status == 130
        kept = (f"{work / 'F.html'} left as it was" if "F.html" in earlier
                else f"{work / 'F.html'} not created")
        assert err == (f"stewart-sim: error: interrupted: nothing new written, "
                       f"{work / 'F.csv'} left as it was, {kept}\n")
    else:
        assert status == 1
        assert err == (f"stewart-sim: error: cannot write {work / 'F.html'}: "
                       "No space left on device\n")
    assert _listing(work) == {name: EARLIER_PAIR[name] for name in earlier}


def test_inverse_commit_failing_puts_the_earlier_files_back(tmp_path, monkeypatch,
                                                           capsys) -> None:
    """The second move into place fails: the first is undone, the earlier pair is back."""
    traj = _demo_file(tmp_path, 0.2)
    work = tmp_path / "work"
    work.mkdir()
    _earlier_pair(work)
    rename, failed = os.rename, []

    def flaky(src, dst) -> None:   # moving the new page in fails, once
        if Path(src).parent != work and Path(dst) == work / "F.html" and not failed:
            failed.append(dst)
            raise OSError(5, "Input/output error")
        rename(src, dst)

    monkeypatch.setattr(os, "rename", flaky)
    assert cli.main(_inverse(traj, work / "F.csv")) == 1
    assert _one_error_line(capsys) == (f"stewart-sim: error: cannot write {work / 'F.csv'}: "
                                       "Input/output error\n")
    assert _listing(work) == EARLIER_PAIR
    monkeypatch.setattr(os, "rename", rename)
    assert cli.main(_inverse(traj, work / "F.csv")) == 0        # and then both, new
    assert sorted(_listing(work)) == ["F.csv", "F.html"]
    assert (work / "F.csv").read_text().startswith("t,sigma1,")
    assert (work / "F.html").read_text().startswith("<!DOCTYPE html>")
    capsys.readouterr()


def test_inverse_refuses_a_directory_or_a_page_over_its_forces(tmp_path, capsys) -> None:
    """FORCES.html a directory: refused before any work; --out F.html: the page would
    overwrite the forces."""
    (tmp_path / "F.html").mkdir()
    (tmp_path / "F.csv").write_text(EARLIER_PAIR["F.csv"])
    assert cli.main(_inverse(tmp_path / "nope.csv", tmp_path / "F.csv")) == 1
    assert _one_error_line(capsys) == (f"stewart-sim: error: cannot write {tmp_path / 'F.html'}: "
                                       "is a directory\n")
    assert (tmp_path / "F.csv").read_text() == EARLIER_PAIR["F.csv"]
    assert cli.main(_inverse(tmp_path / "nope.csv", tmp_path / "G.html")) == 2
    assert "the 3D view would be written over it" in _one_error_line(capsys)
    assert partials(tmp_path / "F.csv") == [] and not (tmp_path / "G.html").exists()


def test_sigint_while_the_pair_moves_in_is_held(tmp_path, monkeypatch) -> None:
    """Ctrl-C during the moves into place waits for them: both new files are in, the
    earlier ones gone, and Interrupted says so (exit 130 with that line)."""
    _earlier_pair(tmp_path)
    rename, sent = os.rename, []

    def rename_and_interrupt(src, dst) -> None:
        if not sent:
            sent.append(dst)
            os.kill(os.getpid(), signal.SIGINT)
        rename(src, dst)

    monkeypatch.setattr(os, "rename", rename_and_interrupt)
    with pytest.raises(outputs.Interrupted) as info:
        with outputs.file_set(tmp_path / "F.csv", tmp_path / "F.html") as (csv_, page):
            csv_.write_text("new forces\n")
            page.write_text("new page\n")
    assert sent and info.value.kept == (f"{tmp_path / 'F.csv'} and {tmp_path / 'F.html'} "
                                        "written whole (Ctrl-C came while they were moved "
                                        "into place)")
    assert _listing(tmp_path) == {"F.csv": "new forces\n", "F.html": "new page\n"}


def test_sigint_during_inverse_keeps_both_earlier_files(long_traj, tmp_path) -> None:
    """A real Ctrl-C while FORCES.csv is being written (its temporary started): exit 130,
    FORCES.csv and FORCES.html exactly the earlier ones, no temporary left."""
    _earlier_pair(tmp_path)
    out = tmp_path / "F.csv"
    status, err = signal_when_ready(_inverse(long_traj, out), out, lambda d: any(d.iterdir()))
    assert status == 130, err
    assert err.rstrip().splitlines()[-1] == (
        f"stewart-sim: error: interrupted: nothing new written, {out} left as it was, "
        f"{tmp_path / 'F.html'} left as it was")
    assert _listing(tmp_path) == EARLIER_PAIR
    assert partials(out) == []


def test_out_is_a_file_exit_1(tmp_path, capsys) -> None:
    out = tmp_path / "file"
    out.write_text("x")
    assert cli.main(["run", str(MICRO), "--out", str(out), "--duration", "0.5"]) == 1
    assert capsys.readouterr().err == (f"stewart-sim: error: cannot write {out}: exists and is "
                                       "not a directory\n")
    assert out.read_text() == "x"


# --- bad inputs: one line, exit 2, before any work -------------------------------------------

def _bad_files(tmp_path: Path) -> dict[str, Path]:
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    folder = tmp_path / "folder.toml"
    folder.mkdir()
    return {"binary": binary, "directory": folder}


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("stewart-sim: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("kind", ["binary", "directory"])
@pytest.mark.parametrize("command", ["scene-info", "run", "inverse", "export-fmu", "sweep",
                                     "demo", "accuracy", "paper", "compare"])
def test_unreadable_scene_exit_2(command, kind, tmp_path, capsys) -> None:
    scene = _bad_files(tmp_path)[kind]
    traj = tmp_path / "traj.csv"
    traj.write_text("t\n")
    out = tmp_path / "out"
    extra = {"scene-info": [], "run": ["--out", str(out)],
             "inverse": ["--trajectory", str(traj), "--out", str(out)],
             "export-fmu": ["-o", str(tmp_path / "p.fmu")],
             "sweep": ["--grid", str(MICRO), "--out", str(out)],
             "demo": ["--out", str(out)], "accuracy": ["--out", str(out)],
             "paper": ["--out", str(out)], "compare": ["--out", str(out)]}[command]
    if command == "sweep":  # the grid is read first: give a good one
        grid = tmp_path / "grid.toml"
        grid.write_text('evaluation = "inverse"\n[trajectory]\nduration = 0.01\n'
                        '[axes]\n"drive.gear_ratio" = [10.0, 20.0]\n')
        extra = ["--grid", str(grid), "--out", str(out), "--no-plots", "--workers", "1"]
    assert cli.main([command, str(scene), *extra]) == 2
    err = _one_error_line(capsys)
    assert str(scene) in err
    assert ("is a directory, not a scene file" if kind == "directory"
            else "not a text (TOML) file") in err
    assert not out.exists() and not (tmp_path / "p.fmu").exists()


@pytest.mark.parametrize("kind", ["binary", "directory"])
def test_unreadable_grid_exit_2(kind, tmp_path, capsys) -> None:
    grid = _bad_files(tmp_path)[kind]
    out = tmp_path / "out"
    assert cli.main(["sweep", str(MICRO), "--grid", str(grid), "--out", str(out)]) == 2
    err = _one_error_line(capsys)
    assert str(grid) in err
    assert ("is a directory, not a grid file" if kind == "directory"
            else "not a text (TOML) file") in err
    assert not out.exists()


@pytest.mark.parametrize("args, option", [
    (["run", "--duration", "1e9"], "--duration"),
    (["demo", "--duration", "1e9"], "--duration"),
    (["accuracy", "--horizon", "1e9"], "--horizon"),
    (["accuracy", "--comm-step", "1e-9"], "--horizon"),
    (["accuracy", "--closed-loop-duration", "1e6"], "--closed-loop-duration"),
])
def test_too_long_refused_before_work(args, option, tmp_path, capsys, monkeypatch) -> None:
    """A run whose samples would not fit the memory budget: the limit and why, in one line,
    before any work (every command works inside its result set, which is never opened)."""
    out = tmp_path / "out"
    opened = []

    def result_set(*a, **kw):
        opened.append(a)
        raise AssertionError("the result set was opened: work began before the refusal")

    monkeypatch.setattr(outputs, "result_set", result_set)
    assert cli.main([args[0], str(MICRO), "--out", str(out), *args[1:]]) == 2
    assert opened == []
    err = _one_error_line(capsys)
    assert f"{option} " in err and f"at most {run_length.MAX_SAMPLES:,}" in err
    assert "memory budget of 2 GiB" in err
    assert not out.exists()


def test_longest_run_allowed_fits_the_budget() -> None:
    run_length.check_samples("--duration", run_length.MAX_SAMPLES / 1000.0, 1000.0)
    with pytest.raises(run_length.StewartError):
        run_length.check_samples("--duration", run_length.MAX_SAMPLES / 1000.0 + 0.01, 1000.0)


def test_progress_covers_writing_the_table(tmp_path, monkeypatch, capsys) -> None:
    """A long run's table and plots are part of the progress: no silent minutes at 100 %."""
    monkeypatch.setattr(progress, "PROGRESS_SAMPLES", 50)
    monkeypatch.setattr(progress, "PROGRESS_INTERVAL", 0.0)
    monkeypatch.setattr("stewart_fmu.io.CHUNK_ROWS", 100)
    out = tmp_path / "out"
    assert cli.main(["run", str(MICRO), "--out", str(out), "--duration", "0.5"]) == 0
    err = capsys.readouterr().err
    assert "writing run.csv: 100/501 (20%) rows" in err
    assert "writing run.csv: 501/501 (100%) rows" in err
    assert "plotting: 3/3 (100%) figures" in err


def test_run_parquet_holds_the_csv_table(tmp_path, capsys) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    assert cli.main(["run", str(MICRO), "--out", str(tmp_path / "c"), "--duration", "0.5"]) == 0
    assert cli.main(["run", str(MICRO), "--out", str(tmp_path / "p"), "--duration", "0.5",
                     "--format", "parquet"]) == 0
    assert f"wrote {tmp_path / 'p' / 'run.parquet'}" in capsys.readouterr().out
    assert not (tmp_path / "p" / "run.csv").exists()
    table = pq.read_table(tmp_path / "p" / "run.parquet")
    with (tmp_path / "c" / "run.csv").open(newline="") as fh:
        rows = list(csv.reader(fh))
    assert table.column_names == rows[0]
    values = np.array([[float(c) for c in r] for r in rows[1:]])
    got = np.column_stack([table[c].to_numpy() for c in rows[0]])
    assert got.shape == values.shape  # wall-clock columns aside, the same run
    assert np.array_equal(got[:, 0], values[:, 0])


# --- scene-info, export-fmu ------------------------------------------------------------------

def _scene_with(tmp_path: Path, old: str, new: str) -> Path:
    text = MICRO.read_text()
    assert old in text
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace(old, new))
    return scene


def test_scene_info_rejects_what_run_rejects(tmp_path, capsys) -> None:
    """A typo in [controller]: scene-info and run say the same, exit 2."""
    scene = _scene_with(tmp_path, "[controller]\n", "[controller]\nbandwith = 20.0\n")
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    run_err = _one_error_line(capsys)
    assert cli.main(["scene-info", str(scene)]) == 2
    assert _one_error_line(capsys) == run_err
    assert "scene key 'controller.bandwith': unknown key" in run_err


def test_scene_info_shows_every_table(capsys) -> None:
    assert cli.main(["scene-info", str(MICRO)]) == 0
    out = capsys.readouterr().out
    assert "controller: rate 1000 Hz, bandwidth 20 Hz" in out
    assert "feedforward kane" in out and "constant load 0.481847 kg" in out
    assert "transmission: none (rigid" in out
    stiff = sorted((ROOT / "scenes").rglob("*.toml"))
    with_case = [p for p in stiff if "[case]" in p.read_text()]
    with_trans = [p for p in stiff if "[transmission]" in p.read_text()]
    assert with_case and with_trans
    assert cli.main(["scene-info", str(with_case[0])]) == 0
    assert "case: " in capsys.readouterr().out
    assert cli.main(["scene-info", str(with_trans[0])]) == 0
    text = capsys.readouterr().out
    assert "transmission: stiffness" in text and "effects: " in text


def test_export_fmu_refuses_a_directory(tmp_path, capsys) -> None:
    """-o names the FMU file; a directory is refused before the compiler runs."""
    assert cli.main(["export-fmu", str(MICRO), "-o", str(tmp_path)]) == 2
    err = _one_error_line(capsys)
    assert f"-o {tmp_path} is a directory" in err and "StewartPlant.fmu" in err
    assert list(tmp_path.iterdir()) == []


# --- start-up --------------------------------------------------------------------------------

HEAVY = ("numpy", "matplotlib", "scipy", "dask", "distributed", "fmpy", "control", "pymavlink",
         "stewart_fmu", "controller", "hil")


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["run", "--help"]])
def test_help_and_version_import_nothing_heavy(argv) -> None:
    code = ("import sys\nfrom stewart_sim import cli\n"
            f"status = cli.main({argv!r})\n"
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=WAIT, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert done.stdout.rstrip().splitlines()[-1] == "[]"


def test_version() -> None:
    from importlib.metadata import version
    done = subprocess.run([str(EXE), "--version"], capture_output=True, text=True, timeout=WAIT)
    assert done.returncode == 0 and done.stdout == f"stewart-sim {version('stewart-sim')}\n"


def test_help_defaults_are_the_librarys() -> None:
    """The commands read a few defaults from the library's source to stay light
    (stewart_sim.commands.constants); they must be the library's."""
    from controller import moves
    from stewart_sim.commands.constants import literals
    from stewart_sim.studies.accuracy import study

    assert literals("controller.moves", "DEMO_DURATION", "DEMO_RATE", "RUN_MOVE", "RUN_HOLD") == (
        moves.DEMO_DURATION, moves.DEMO_RATE, moves.RUN_MOVE, moves.RUN_HOLD)
    assert literals("stewart_sim.studies.accuracy.study", "HORIZON", "COMM_STEP",
                    "CLOSED_LOOP_DURATION") == (
        study.HORIZON, study.COMM_STEP, study.CLOSED_LOOP_DURATION)
    from hil import spawn
    from stewart_sim.studies.compare import study as compare
    from stewart_sim.view import data

    assert literals("stewart_sim.studies.accuracy.study", "REPEATS") == (study.REPEATS,)
    assert literals("stewart_sim.studies.compare.study", "N_POINTS") == (compare.N_POINTS,)
    assert literals("hil.spawn", "WATCHDOG") == (spawn.WATCHDOG,)
    assert literals("stewart_sim.view.data", "DEFAULT_FPS") == (data.DEFAULT_FPS,)


def test_any_run_files_covers_the_link_run() -> None:
    from stewart_sim.closed_loop.over_link import LINK_FILES
    from stewart_sim.closed_loop.run_files import ANY_RUN_FILES, RUN_FILES, run_files

    assert set(LINK_FILES) | set(RUN_FILES) | set(run_files("parquet")) == set(ANY_RUN_FILES)


# --- sweep: points the scene rejects ---------------------------------------------------------

def _grid(tmp_path: Path, axes: str) -> Path:
    grid = tmp_path / "grid.toml"
    grid.write_text('evaluation = "inverse"\n[trajectory]\nduration = 0.05\n[axes]\n' + axes)
    return grid


def test_sweep_point_the_scene_rejects_is_a_row(tmp_path, capsys) -> None:
    """leg_max below leg_min at one point: that point is a row naming the grid point and the
    key (not the scene file), the others are computed."""
    out = tmp_path / "out"
    grid = _grid(tmp_path, '"geometry.leg_max" = [0.05, 0.19]\n')
    assert cli.main(["sweep", str(MICRO), "--grid", str(grid), "--out", str(out),
                     "--workers", "1", "--no-plots"]) == 0
    assert "2 points, 0 already done, 2 computed" in capsys.readouterr().out
    with (out / "sweep.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["error", "ok"]
    assert rows[0]["error"].startswith("SceneError: grid point 0 (geometry.leg_max = 0.05): "
                                       "scene key 'geometry.leg_max': must exceed leg_min")
    assert str(MICRO) not in rows[0]["error"] and MICRO.name not in rows[0]["error"]


def test_sweep_value_breaking_its_keys_rule_is_refused_up_front(tmp_path, capsys) -> None:
    """A negative friction at the first point: exit 2 before anything runs, naming the grid
    file, the point and the key (tests/app/test_sweep.py: later points are rows)."""
    out = tmp_path / "out"
    grid = _grid(tmp_path, '"friction.viscous" = [-1.0, 1.0]\n')
    assert cli.main(["sweep", str(MICRO), "--grid", str(grid), "--out", str(out)]) == 2
    err = _one_error_line(capsys)
    assert err == (f"stewart-sim: error: {grid}: grid point 0 (friction.viscous = -1.0): scene key "
                   "'friction.viscous': must be >= 0, got -1.0\n")
    assert not out.exists()


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_swallowed_sigint_still_stops_the_set(tmp_path) -> None:
    """Ctrl-C raised where Python cannot propagate it ("Exception ignored in ..."): the set
    is not moved into place and the command still ends as interrupted."""
    from stewart_sim.shell import outputs

    class Swallowed:
        def __del__(self):
            interrupt.sigint_handler(signal.SIGINT, None)   # raised in __del__: ignored

    out = tmp_path / "out"
    interrupt.reset_interrupt()
    try:
        with pytest.raises(outputs.Interrupted) as info:
            with outputs.result_set(out) as stage:
                (stage / "run.csv").write_text("t\n")
                obj = Swallowed()
                del obj
        assert info.value.kept == f"nothing new written, {out} not created"
    finally:
        interrupt.reset_interrupt()
    assert not out.exists() and partials(out) == []
