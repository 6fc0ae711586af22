"""A result set is all or nothing under SIGKILL too: the writer (tests/app/set_writer_child.py)
killed before each of its file-system steps in turn, and at seeded random instants of its
life, leaves DIR holding the earlier set whole or the new one whole, the user's own files the
same files; the next run leaves no temporary behind. Both swaps: renameat2's exchange and the
two-rename fallback (whose window, DIR missing, the next run repairs: dirswap.recover)."""
from __future__ import annotations

import os
import random
import signal
import time
from pathlib import Path

import pytest

from stewart_sim.shell import dirswap, outputs
from stewart_sim.shell.outputs import MANIFEST
from tests.app.set_writer_child import NEW_SET, fork_writer

EARLIER = {"a.csv": "t,x\n0,old\n", "b.csv": "t,y\n0,old\n", "gone.png": "old figure\n"}
MINE = {"notes.txt": "mine\n", "mine/deep/notes.txt": "deep\n"}
SWAPS = ["exchange", "fallback"]


def _earlier_set(out: Path) -> None:
    out.mkdir()
    for name, text in {**EARLIER, **MINE}.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
    (out / MANIFEST).write_text("".join(f"{n}\n" for n in sorted(EARLIER)))
    os.symlink("notes.txt", out / "link")


def _listing(out: Path) -> dict[str, str] | None:
    """Every entry below `out` by its relative path: a file's text, a link's target."""
    if not out.exists():
        return None
    found = {}
    for directory, _, files in os.walk(out):
        for name in files:
            path = Path(directory, name)
            found[str(path.relative_to(out))] = (
                f"-> {os.readlink(path)}" if path.is_symlink() else path.read_text())
    return found


def _set(files: dict[str, str]) -> dict[str, str]:
    return {**files, **MINE, "link": "-> notes.txt",
            MANIFEST: "".join(f"{n}\n" for n in sorted(files))}


WHOLE = {"earlier": _set(EARLIER), "new": _set(NEW_SET)}


def _run(out: Path, kill_at: int, swap: str) -> tuple[int, str]:
    """The writer's exit status (a signal's negative number) and what it wrote to its pipe."""
    pid, pipe = fork_writer(out, kill_at, swap == "fallback")
    with os.fdopen(pipe) as said:
        text = said.read()
    return _status(pid), text


def _status(pid: int) -> int:
    status = os.waitpid(pid, 0)[1]     # reaped: its temporaries are those of a process gone
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _which(out: Path, swap: str) -> str:
    """The whole set `out` holds ("earlier" or "new"), the fallback's window repaired first."""
    if swap == "fallback":
        dirswap.recover(out)
    listing = _listing(out)
    assert listing in WHOLE.values(), listing
    return next(name for name, whole in WHOLE.items() if listing == whole)


def _rerun_leaves_nothing(tmp_path: Path, out: Path, swap: str, inode: int) -> None:
    status, _ = _run(out, 0, swap)
    assert status == 0
    assert _listing(out) == WHOLE["new"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (out / "notes.txt").stat().st_ino == inode      # the user's file, not a copy


def _steps(tmp_path: Path, swap: str) -> int:
    out = tmp_path / "count" / "out"
    out.parent.mkdir()
    _earlier_set(out)
    status, said = _run(out, 0, swap)
    assert status == 0 and _listing(out) == WHOLE["new"]
    return int(said.split()[-1])


@pytest.mark.parametrize("swap", SWAPS)
def test_a_kill_before_any_step_leaves_one_whole_set(swap, tmp_path) -> None:
    """SIGKILL before each file-system step of the writer, every one in turn."""
    steps = _steps(tmp_path, swap)
    assert steps >= (12 if swap == "exchange" else 13)
    seen = []
    for kill_at in range(1, steps + 1):
        case = tmp_path / f"kill{kill_at}"
        out = case / "out"
        case.mkdir()
        _earlier_set(out)
        inode = (out / "notes.txt").stat().st_ino
        status, _ = _run(out, kill_at, swap)
        assert status == -signal.SIGKILL, kill_at
        seen.append(_which(out, swap))
        assert (out / "notes.txt").stat().st_ino == inode
        _rerun_leaves_nothing(case, out, swap, inode)
    # the kills fell on both sides of the one rename that swaps the sets
    assert seen[0] == "earlier" and seen[-1] == "new"
    assert seen == sorted(seen, key=["earlier", "new"].index)


@pytest.mark.parametrize("swap", SWAPS)
def test_a_kill_at_random_instants_leaves_one_whole_set(swap, tmp_path) -> None:
    """SIGKILL at 30 seeded random instants over the writer's life, from its fork to its end
    (the swap is a small part of it: the kill before each step covers it one by one)."""
    out = tmp_path / "time" / "out"
    out.parent.mkdir()
    _earlier_set(out)
    window = 1.2 * _life(out, swap)
    rng = random.Random(34)
    for trial in range(30):
        case = tmp_path / f"trial{trial}"
        out = case / "out"
        case.mkdir()
        _earlier_set(out)
        inode = (out / "notes.txt").stat().st_ino
        pid, pipe = fork_writer(out, 0, swap == "fallback")
        time.sleep(rng.uniform(0, window))
        os.kill(pid, signal.SIGKILL)
        assert _status(pid) in (0, -signal.SIGKILL)
        os.close(pipe)                 # after its end: the writer never meets a closed pipe
        _which(out, swap)
        _rerun_leaves_nothing(case, out, swap, inode)


def _life(out: Path, swap: str) -> float:
    """Seconds from the writer's fork to its end."""
    start = time.perf_counter()
    status, _ = _run(out, 0, swap)
    assert status == 0
    return time.perf_counter() - start


def test_out_a_link_writes_through_it(tmp_path, capsys) -> None:
    """--out a symbolic link to a directory: the set goes into the directory it names and
    the link stays; a link to nothing is refused in one line, nothing created."""
    target = tmp_path / "runs" / "today"
    target.parent.mkdir()
    _earlier_set(target)
    link = tmp_path / "latest"
    os.symlink("runs/today", link)
    with outputs.result_set(link, known=NEW_SET) as stage:
        for name, text in NEW_SET.items():
            (stage / name).write_text(text)
    assert os.readlink(link) == "runs/today" and _listing(target) == WHOLE["new"]
    dangling = tmp_path / "dangling"
    os.symlink("nowhere", dangling)
    with pytest.raises(outputs.OutputError) as info:
        with outputs.result_set(dangling):
            pass
    assert str(info.value) == f"cannot write {dangling}: a symbolic link to nowhere, which " \
                              "does not exist"
    assert not (tmp_path / "nowhere").exists() and os.path.islink(dangling)


def test_a_file_that_cannot_be_kept_is_refused_before_the_swap(tmp_path, monkeypatch) -> None:
    """A file of no set that cannot be linked into the new directory: one line naming it,
    DIR as it was, no temporary left."""
    out = tmp_path / "out"
    _earlier_set(out)

    def refuse(*args, **kwargs):
        raise OSError(18, "Invalid cross-device link")
    monkeypatch.setattr(os, "link", refuse)
    with pytest.raises(outputs.OutputError) as info:
        with outputs.result_set(out, known=NEW_SET) as stage:
            (stage / "a.csv").write_text("new\n")
    assert str(info.value).startswith(f"cannot write {out}: {out / 'link'} (no file of a set) "
                                      "cannot be kept across the swap: Invalid cross-device link")
    assert _listing(out) == WHOLE["earlier"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_trash_of_a_set_swapped_file_by_file_goes(tmp_path) -> None:
    """The hidden .old-XXXXXXXX folder a file-by-file swap killed midway left in DIR is part of
    no set: the next set does not carry it."""
    out = tmp_path / "out"
    _earlier_set(out)
    (out / ".old-abcd1234").mkdir()
    (out / ".old-abcd1234" / "a.csv").write_text("older\n")
    with outputs.result_set(out, known=NEW_SET) as stage:
        for name, text in NEW_SET.items():
            (stage / name).write_text(text)
    assert _listing(out) == WHOLE["new"]


@pytest.mark.parametrize("given", [".", "..", "out"])
def test_out_holding_the_working_directory_is_refused(given, tmp_path, monkeypatch) -> None:
    """--out . (or a directory above the working one): swapping it would leave the shell
    that ran the command in a removed directory; one line, nothing changed."""
    out = tmp_path / "out"
    _earlier_set(out)
    monkeypatch.chdir(out / "mine" if given == ".." else out)
    target = Path(given) if given != "out" else out
    with pytest.raises(outputs.OutputError) as info:
        with outputs.result_set(target, known=NEW_SET):
            pass
    assert str(info.value) == (f"cannot write {target}: it holds the working directory, and a "
                               "result set replaces its directory whole; give a directory "
                               "beneath it")
    assert _listing(out) == WHOLE["earlier"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
