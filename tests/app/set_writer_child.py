"""A result set written into OUT by a forked child process, for test_set_swap.py: the new set's
files (NEW_SET), the child killed with SIGKILL just before its KILL_AT-th file-system step (a
rename, link, unlink, mkdir, rmdir, chmod or directory exchange), counted from the start of
result_set; KILL_AT 0: no kill. The child writes "go" to a pipe when the set is staged, just
before it is moved into place, then the number of steps it took. `fallback`: the two-rename
swap (as on a system without renameat2 RENAME_EXCHANGE)."""
from __future__ import annotations

import os
import signal
from pathlib import Path

from stewart_sim.shell import dirswap, outputs

NEW_SET = {"a.csv": "t,x\n0,new\n", "b.csv": "t,y\n0,new\n", "c.md": "# new\n"}
STEPS = ("rename", "replace", "link", "symlink", "unlink", "remove", "mkdir", "rmdir", "chmod")


def _counting(kill_at: int) -> list[int]:
    count = [0]

    def step() -> None:
        count[0] += 1
        if count[0] == kill_at:
            os.kill(os.getpid(), signal.SIGKILL)

    def wrap(function):
        def wrapped(*args, **kwargs):
            step()
            return function(*args, **kwargs)
        return wrapped

    for name in STEPS:
        setattr(os, name, wrap(getattr(os, name)))
    dirswap.exchange = wrap(dirswap.exchange)
    return count


def fork_writer(out: Path, kill_at: int, fallback: bool) -> tuple[int, int]:
    """Fork the writer: (its process id, the read end of its pipe)."""
    read, write = os.pipe()
    pid = os.fork()
    if pid:
        os.close(write)
        return pid, read
    status = 1
    try:
        os.close(read)
        _write(out, kill_at, fallback, write)
        status = 0
    finally:
        os._exit(status)


def _write(out: Path, kill_at: int, fallback: bool, pipe: int) -> None:
    if fallback:
        dirswap.exchange = lambda a, b: False
    count = _counting(kill_at)
    with outputs.result_set(out, known=NEW_SET) as stage:
        for name, text in NEW_SET.items():
            (stage / name).write_text(text)
        os.write(pipe, b"go\n")
    os.write(pipe, f"{count[0]}\n".encode())
