"""The output, input and terminal rules of the command line, one repro each: what `--out` may
name (no device, FIFO, socket, /proc, /sys, /dev), SIGTERM and SIGHUP ending a command as
Ctrl-C does, stale temporaries of a killed writer removed, a full disk or a refused write as one
line (exit 1, nothing half-written), input files regular and within their budget (a device, a
FIFO, an endless file), counts from an input checked before they are allocated (a trajectory
whose times are stretched 2e7 times), control characters escaped, a closed pipe quiet."""
from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import budget, io
from stewart_fmu.errors import SceneError, TrajectoryError
from stewart_sim import cli
from stewart_sim.shell import interrupt, outputs, terminal
from stewart_sim.view.data import frame_indices
from tests.app.console import EXE, WAIT, console_env, partials, signal_when_ready

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
EARLIER = {"summary.md": "# an earlier result that must survive\n", "run.csv": "t,x\n0.0,1.0\n"}


def _error(capsys) -> str:
    """The one line a refused command printed on stderr."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("stewart-sim: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture(scope="module")
def traj(tmp_path_factory) -> Path:
    """A short demo trajectory of the micro-manipulator (0.2 s at 1 kHz)."""
    path = tmp_path_factory.mktemp("traj") / "T.csv"
    assert cli.main(["trajectory", str(MICRO), "--move", "demo", "--duration", "0.2",
                     "--out", str(path)]) == 0
    return path


# --- output rule ---------------------------------------------------------------------------

@pytest.mark.parametrize("device", ["/dev/full", "/dev/null"])
def test_out_a_device_is_refused_before_any_work(device, traj, capsys) -> None:
    """`inverse SCENE --trajectory T --out /dev/full` printed "wrote /dev/full" after replacing
    the device node with a regular file: now one line, exit 2, the node as it was."""
    before = os.stat(device)
    assert cli.main(["inverse", str(MICRO), "--trajectory", str(traj), "--out", device]) == 2
    line = _error(capsys)
    assert f"cannot write {device}: it is a device, pipe or socket" in line
    after = os.stat(device)
    assert (after.st_mode, after.st_rdev, after.st_ino) == (before.st_mode, before.st_rdev,
                                                            before.st_ino)


def test_out_a_fifo_and_a_socket_are_refused(traj, tmp_path, capsys) -> None:
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    sock_path = tmp_path / "s.csv"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    try:
        for special in (fifo, sock_path):
            assert cli.main(["trajectory", str(MICRO), "--move", "demo", "--duration", "0.1",
                             "--out", str(special)]) == 2
            assert "it is a device, pipe or socket" in _error(capsys)
    finally:
        sock.close()
    assert fifo.is_fifo() and sock_path.is_socket()


@pytest.mark.parametrize("path", ["/proc/self/status", "/sys/kernel/x.csv", "/dev/x.csv",
                                  "/proc/new_dir/out"])
def test_out_in_proc_sys_dev_is_refused(path, traj, capsys) -> None:
    assert cli.main(["inverse", str(MICRO), "--trajectory", str(traj), "--out", path]) == 2
    line = _error(capsys)
    assert f"cannot write {path}" in line and "a command may write" in line


def test_out_a_link_to_a_device_is_refused(traj, tmp_path, capsys) -> None:
    link = tmp_path / "out"
    link.symlink_to("/dev/null")
    assert cli.main(["run", str(MICRO), "--duration", "0.1", "--out", str(link)]) == 2
    assert "it is a device, pipe or socket" in _error(capsys)
    assert link.is_symlink() and os.readlink(link) == "/dev/null"


def test_record_a_device_is_refused(tmp_path, capsys) -> None:
    """--record (run --link's measured run) is an output too: refused before the link starts."""
    out = tmp_path / "out"
    assert cli.main(["run", str(MICRO), "--link", "serial", "--record", "/dev/null", "--out",
                     str(out)]) == 2
    assert "cannot write /dev/null" in _error(capsys)
    assert not out.exists()


def test_every_writer_refuses_a_device(tmp_path) -> None:
    """The rule is the writers' too, not only the command line's (a side file beside --out)."""
    with pytest.raises(io.SpecialOutputError, match="device, pipe or socket"):
        io.write_text("/dev/null", "x")
    with pytest.raises(io.SpecialOutputError):
        with outputs.result_set("/dev/null"):
            pass
    with pytest.raises(io.SpecialOutputError):
        with outputs.file_set("/dev/full"):
            pass


def _signal_mid_run(sig: int, out: Path) -> tuple[int, str]:
    """`run` into `out` (holding EARLIER), sent `sig` once run.csv is in its temporary
    directory; returns (status, stderr)."""
    return signal_when_ready(["run", str(MICRO), "--duration", "1", "--out", str(out)], out,
                             lambda part: (part / "run.csv").exists(), sig)


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGHUP, 129)],
                         ids=["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_end_a_run_as_ctrl_c(sig, status, tmp_path) -> None:
    """SIGTERM during `run` exited 143 with no handler and left `.DIR.partial-*` behind: now
    the same as Ctrl-C: exit 128 + the signal, one line, the earlier set whole, no temporary."""
    out = tmp_path / "out"
    out.mkdir()
    for name, text in EARLIER.items():
        (out / name).write_text(text)
    code, err = _signal_mid_run(sig, out)
    assert code == status, err
    assert "Traceback" not in err
    line = err.rstrip().splitlines()[-1]
    assert line == (f"stewart-sim: error: interrupted ({signal.Signals(sig).name}): nothing "
                    f"new written, {out} left as it was (the earlier set untouched)")
    assert {p.name: p.read_text() for p in out.iterdir()} == EARLIER
    assert partials(out) == []


def test_a_signal_held_during_the_moves_sets_the_exit_status(tmp_path, monkeypatch) -> None:
    """A SIGTERM that comes while the set is moved into place is held; the set is complete and
    the command still ends with 143."""
    out = tmp_path / "out"
    rename = os.rename

    def rename_signalled(src, dst):
        os.kill(os.getpid(), signal.SIGTERM)   # arrives during the moves
        return rename(src, dst)
    previous = signal.signal(signal.SIGTERM, interrupt.sigint_handler)
    interrupt.reset_interrupt()
    try:
        with pytest.raises(outputs.Interrupted) as info:
            with outputs.result_set(out) as stage:
                (stage / "a.txt").write_text("a\n")
                monkeypatch.setattr(outputs.os, "rename", rename_signalled)
        monkeypatch.undo()
        assert "holds the complete new set" in info.value.kept
        assert interrupt.exit_status() == 143
    finally:
        signal.signal(signal.SIGTERM, previous)
        interrupt.reset_interrupt()
    assert (out / "a.txt").read_text() == "a\n" and partials(out) == []


def _dead_pid() -> int:
    """The id of a process that has ended (a child reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_partials_of_a_gone_process_are_removed(tmp_path, capsys) -> None:
    """A writer killed outright (SIGKILL) leaves its temporary: the next command into DIR
    removes it; a live process's temporary and foreign names are left alone."""
    out = tmp_path / "out"
    dead, live = _dead_pid(), os.getppid()
    stale_dir = tmp_path / f".out.partial-{dead}-abcd"
    stale_dir.mkdir()
    (stale_dir / "run.csv").write_text("half\n")
    live_dir = tmp_path / f".out.partial-{live}-efgh"
    live_dir.mkdir()
    foreign = tmp_path / ".out.partial-old1234"     # no process id: not ours to judge
    foreign.mkdir()
    assert cli.main(["run", str(MICRO), "--duration", "0.1", "--no-view", "--out",
                     str(out)]) == 0
    capsys.readouterr()
    assert not stale_dir.exists()
    assert live_dir.exists() and foreign.exists()
    assert (out / "run.csv").exists()


def test_stale_temporaries_of_a_single_file_are_removed(tmp_path) -> None:
    target = tmp_path / "T.csv"
    stale = tmp_path / f".T.csv.partial-{_dead_pid()}-x1y2.tmp"
    stale.write_text("half")
    io.write_text(target, "t\n")
    assert not stale.exists() and target.read_text() == "t\n"
    assert [p.name for p in tmp_path.iterdir()] == ["T.csv"]


def test_sigkill_leaves_a_partial_that_the_next_run_removes(tmp_path, capsys) -> None:
    """The repro end to end: `run` killed by SIGKILL mid-way, then `run` again into DIR."""
    out = tmp_path / "out"
    signal_when_ready(["run", str(MICRO), "--duration", "1", "--out", str(out)], out,
                      lambda part: True, signal.SIGKILL)
    assert partials(out)
    assert cli.main(["run", str(MICRO), "--duration", "0.1", "--no-view", "--out",
                     str(out)]) == 0
    capsys.readouterr()
    assert partials(out) == []


class _FullDisk:
    """A file object whose writes fail as on a full disk."""

    def __init__(self, fh, code: int):
        self._fh, self._code = fh, code

    def write(self, _data):
        raise OSError(self._code, os.strerror(self._code))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()

    def __getattr__(self, name):
        return getattr(self._fh, name)


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EACCES, errno.EROFS, errno.EDQUOT],
                         ids=["ENOSPC", "EACCES", "EROFS", "EDQUOT"])
def test_a_full_disk_is_one_line_exit_1_nothing_half_written(code, traj, tmp_path, capsys,
                                                             monkeypatch) -> None:
    """A full disk during a rewrite was an OSError traceback: now one line naming the output,
    exit 1, the earlier file as it was and no temporary beside it."""
    out = tmp_path / "F.csv"
    out.write_text("earlier\n")
    fdopen = os.fdopen
    monkeypatch.setattr(io.os, "fdopen", lambda fd, *a, **k: _FullDisk(fdopen(fd, *a, **k),
                                                                         code))
    assert cli.main(["inverse", str(MICRO), "--trajectory", str(traj), "--out", str(out),
                     "--no-view"]) == 1
    line = _error(capsys)
    assert line == f"stewart-sim: error: cannot write {out}: {os.strerror(code)}"
    assert out.read_text() == "earlier\n"
    assert [p.name for p in tmp_path.iterdir()] == ["F.csv"]


def test_a_full_disk_in_a_result_set_keeps_the_earlier_set(tmp_path) -> None:
    """A writer of the set that is not ours (a figure, an archive) meets a full disk: one
    OutputError naming DIR, DIR as it was, no temporary."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "run.csv").write_text("earlier\n")
    with pytest.raises(io.OutputError, match=rf"cannot write {out}: No space left on device"):
        with outputs.result_set(out) as stage:
            (stage / "run.csv").write_text("new\n")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(stage / "fig.png"))
    assert (out / "run.csv").read_text() == "earlier\n" and partials(out) == []


def test_an_oserror_of_a_write_escaping_a_command_is_one_line(monkeypatch, capsys) -> None:
    """The command line's last net: any EACCES/ENOSPC that reaches it is exit 1, one line."""
    from stewart_sim.commands import scene_info

    def denied(args):
        raise PermissionError(errno.EACCES, "Permission denied", "/somewhere/out.csv")
    monkeypatch.setattr(scene_info, "run", denied)
    assert cli.main(["scene-info", str(MICRO)]) == 1
    assert _error(capsys) == ("stewart-sim: error: cannot write /somewhere/out.csv: "
                              "Permission denied")


# --- input rule ----------------------------------------------------------------------------

@pytest.mark.parametrize("special", ["/dev/zero", "/dev/urandom", "/dev/null"])
def test_scene_info_of_a_device_is_one_line(special, capsys) -> None:
    """`scene-info /dev/zero` read until MemoryError."""
    assert cli.main(["scene-info", special]) == 2
    assert _error(capsys) == (f"stewart-sim: error: {special}: is a device, pipe or socket, "
                              "not a scene file")


def test_a_fifo_scene_is_refused_without_waiting_for_a_writer(tmp_path) -> None:
    """A FIFO as the scene hung (opening it waits for a writer): refused at once."""
    fifo = tmp_path / "scene.toml"
    os.mkfifo(fifo)
    r = subprocess.run([str(EXE), "scene-info", str(fifo)], capture_output=True, text=True,
                       env=console_env(), timeout=WAIT)
    assert r.returncode == 2, r.stderr
    assert r.stderr == (f"stewart-sim: error: {fifo}: is a device, pipe or socket, not a "
                        "scene file\n")


@pytest.mark.parametrize("option", ["--trajectory", "--scene"])
def test_a_fifo_trajectory_or_scene_for_inverse_is_refused(option, traj, tmp_path) -> None:
    fifo = tmp_path / "in"
    os.mkfifo(fifo)
    args = (["inverse", str(MICRO), "--trajectory", str(fifo)] if option == "--trajectory"
            else ["inverse", str(fifo), "--trajectory", str(traj)])
    r = subprocess.run([str(EXE), *args, "--out", str(tmp_path / "F.csv")],
                       capture_output=True, text=True, env=console_env(), timeout=WAIT)
    assert r.returncode == 2 and "device, pipe or socket" in r.stderr, r.stderr
    assert len(r.stderr.splitlines()) == 1 and not (tmp_path / "F.csv").exists()


def test_bounded_reading_refuses_a_file_over_its_budget(tmp_path, monkeypatch) -> None:
    """The size budget: at open (the size the file system reports) and while reading (a file
    that grows, or /proc reporting 0)."""
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * 2000)
    with pytest.raises(budget.InputFileError, match="larger than the 1000 bytes") as info:
        budget.read_input(big, 1000)
    assert info.value.kind == "large"
    assert budget.read_input(big, 2000) == b"#" * 2000
    status = budget.read_input("/proc/self/status", budget.SCENE_BYTES)   # reports size 0
    assert b"Name:" in status
    with pytest.raises(budget.InputFileError, match="larger than the 16 bytes"):
        budget.read_input("/proc/self/status", 16)
    monkeypatch.setattr(budget, "SCENE_BYTES", 1000)
    monkeypatch.setattr("stewart_fmu.scene.SCENE_BYTES", 1000)
    from stewart_fmu.scene import read_scene_bytes
    with pytest.raises(SceneError, match="larger than the 1000 bytes an input of this kind"):
        read_scene_bytes(big)


def test_csv_budget_and_line_bound(tmp_path, monkeypatch) -> None:
    """A CSV over the CSV budget, or a line longer than LINE_BYTES, is one TrajectoryError."""
    path = tmp_path / "T.csv"
    path.write_text("t," + ",".join(io.TRAJECTORY_COLUMNS[1:]) + "\n" + "0" + ",0" * 18 + "\n")
    monkeypatch.setattr(io, "CSV_BYTES", 40)
    with pytest.raises(TrajectoryError, match="cannot read trajectory: larger than the 40 bytes"):
        io.read_trajectory(path)
    monkeypatch.setattr(io, "CSV_BYTES", budget.CSV_BYTES)
    monkeypatch.setattr(io, "LINE_BYTES", 30)
    with pytest.raises(TrajectoryError, match=r"line 1 is longer than 30 characters"):
        io.read_trajectory(path)


def test_samples_of_a_csv_are_checked_against_the_memory_budget(tmp_path, monkeypatch) -> None:
    path = tmp_path / "T.csv"
    rows = "\n".join(f"{k}" + ",0" * 18 for k in range(50))
    path.write_text(",".join(io.TRAJECTORY_COLUMNS) + "\n" + rows + "\n")
    monkeypatch.setattr(budget, "MEMORY_BUDGET", 40 * 2 * 8 * 19)
    with pytest.raises(budget.BudgetError, match=r"T.csv: samples: 50 are more than the 40"):
        io.read_trajectory(path)


def _stretched(traj: Path, factor: float, tmp_path: Path) -> Path:
    t, q, qd, qdd = io.read_trajectory(traj)
    out = tmp_path / "stretched.csv"
    io.write_csv(out, io.trajectory_table(t * factor, q, qd, qdd))
    return out


def test_view_of_stretched_times_is_bounded_by_the_samples(traj, tmp_path, capsys) -> None:
    """Times x 2e7: the frame grid (span x fps) took 7.2 GB; the frames are now bounded by the
    samples (each shown once)."""
    stretched = _stretched(traj, 2e7, tmp_path)
    page = tmp_path / "v.html"
    assert cli.main(["view", str(stretched), "--scene", str(MICRO), "-o", str(page)]) == 0
    out = capsys.readouterr().out
    samples = io.read_trajectory(traj)[0].size
    assert f"{samples} frames at 30 frames/s from {samples} samples" in out


def test_frames_beyond_the_samples_are_the_grids_frames() -> None:
    """Where the grid has more frame times than samples, the frames are those the grid would
    pick (checked here on grids small enough to build)."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        t = np.cumsum(rng.uniform(1e-3, 0.2, rng.integers(2, 300)))
        fps = float(rng.uniform(20.0, 500.0))
        span = t[-1] - t[0]
        grid = t[0] + np.arange(int(np.floor(span * fps + 1e-9)) + 1) / fps
        idx = np.minimum(np.searchsorted(t, grid - 1e-12 * max(1.0, span)), t.size - 1)
        assert np.array_equal(frame_indices(t, fps), np.unique(np.r_[idx, t.size - 1]))
    assert frame_indices(np.array([0.0, 1e300]), 1e10).tolist() == [0, 1]


def test_waypoints_of_stretched_times_are_one_line(traj, tmp_path, capsys) -> None:
    stretched = _stretched(traj, 2e7, tmp_path)
    out = tmp_path / "W.csv"
    assert cli.main(["trajectory", str(MICRO), "--waypoints", str(stretched), "--out",
                     str(out)]) == 2
    line = _error(capsys)
    assert str(stretched) in line and "fit the memory budget" in line
    assert not out.exists()


def test_check_count() -> None:
    assert budget.check_count("frames", 10, 8) == 10
    for bad in (float("nan"), float("inf"), -1.0, 1e300):
        with pytest.raises(budget.BudgetError, match="frames"):
            budget.check_count("frames", bad, 8)


# --- terminal ------------------------------------------------------------------------------

def test_printable_escapes_control_characters() -> None:
    assert terminal.printable("a\x1b[31mb\x07\x9b\x7f\u202e\tc\nd") == \
        "a\\x1b[31mb\\x07\\x9b\\x7f\\u202e\tc\nd"
    assert terminal.printable("plain text, é, 1e-3 m") == "plain text, é, 1e-3 m"


def test_an_ansi_scene_name_is_escaped(tmp_path, capsys) -> None:
    """A scene `name` with ANSI escapes was printed raw by scene-info."""
    text = MICRO.read_text().replace('name = "micro-manipulator"',
                                     'name = "\\u001b[2J\\u001b[31mowned\\u0007"')
    assert text != MICRO.read_text()
    scene = tmp_path / "ansi.toml"
    scene.write_text(text)
    assert cli.main(["scene-info", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out
    assert "\\x1b[2J\\x1b[31mowned\\x07" in out


def test_a_file_name_with_escapes_in_an_error_is_escaped(tmp_path, capsys) -> None:
    name = tmp_path / "a\x1b]0;title\x07.toml"
    assert cli.main(["scene-info", str(name)]) == 2
    line = _error(capsys)
    assert "\x1b" not in line and "\\x1b]0;title\\x07.toml" in line


def test_a_closed_pipe_ends_quietly() -> None:
    """`scene-info ... | head -1` was a BrokenPipeError traceback: the reader is gone before
    the command writes, and the command ends as a POSIX tool does (141, nothing on stderr)."""
    read, write = os.pipe()
    os.close(read)          # the reader has gone before anything is written
    try:
        r = subprocess.run([str(EXE), "scene-info", str(MICRO)], stdout=write,
                           stderr=subprocess.PIPE, text=True, env=console_env(), timeout=WAIT)
    finally:
        os.close(write)
    assert r.returncode == 141, r.stderr
    assert r.stderr == ""


def test_head_1_through_a_shell_is_quiet() -> None:
    r = subprocess.run(f"'{EXE}' scene-info '{MICRO}' | head -1", shell=True,
                       capture_output=True, text=True, env=console_env(), timeout=WAIT)
    assert r.returncode == 0 and r.stderr == ""
    assert r.stdout.startswith("scene: micro-manipulator")


def test_control_characters_in_a_figure_are_drawn_escaped(tmp_path) -> None:
    """A scene name with an ANSI escape and a tab in a plot's title: drawn as printed (\\x1b),
    the tab a space, with no missing-glyph warning (the scene fuzz met one)."""
    import warnings

    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    fig = Figure()
    ax = fig.add_subplot()
    ax.set_title("evil\x1b[31mname\ttab")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        save_figure(fig, tmp_path / "f.png")
    assert ax.get_title() == "evil\\x1b[31mname tab"
    assert (tmp_path / "f.png").stat().st_size > 0
