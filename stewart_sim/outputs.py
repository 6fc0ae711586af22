"""Result sets written all or nothing, and Ctrl-C that always ends the command.

A command that writes several files into --out DIR builds them in a temporary directory beside
DIR (same file system: `.DIR.partial-XXXX`) and moves them into place at the end
(`result_set`). The files of the set are listed in DIR/.stewart-sim-set; the next set written
into DIR removes every file of the earlier one, so that DIR never mixes two runs. Files in DIR
that belong to no set are left alone. SIGINT while the set is built removes the temporary
directory and leaves DIR as it was; the moves themselves run with SIGINT held back.

SIGINT is handled by `sigint_handler` (installed by cli.main): it records the signal and
raises KeyboardInterrupt. A KeyboardInterrupt raised where Python cannot propagate it (a
callback from C, a destructor: "Exception ignored in ...") is therefore not lost: the flag
stops the set before it is moved into place, and the command still exits 130.
"""
from __future__ import annotations

import os
import shutil
import signal
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from stewart_fmu.io import OutputError, write_text

MANIFEST = ".stewart-sim-set"   # names of the files of the set in DIR, one a line

_interrupted = threading.Event()


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, with the line saying what was kept (cli.main prints it and exits 130)."""

    def __init__(self, kept: str):
        super().__init__(kept)
        self.kept = kept


def sigint_handler(signum, frame) -> None:
    """SIGINT: remember it (see the module doc), then interrupt like Python's default."""
    _interrupted.set()
    raise KeyboardInterrupt


def reset_interrupt() -> None:
    """Forget an earlier SIGINT (a new command starts)."""
    _interrupted.clear()


def interrupted() -> bool:
    """Whether SIGINT arrived since the command started (also when it was swallowed)."""
    return _interrupted.is_set()


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if SIGINT arrived, even if the exception was swallowed."""
    if _interrupted.is_set():
        raise KeyboardInterrupt


@contextmanager
def result_set(out: str | Path, known: Iterable[str] = ()) -> Iterator[Path]:
    """Yield a temporary directory beside `out`; on success its files replace the earlier set
    in `out` (the names in out/MANIFEST, else `known`: what the command writes). On any error
    or Ctrl-C the temporary directory goes and `out` stays as it was (Interrupted says so)."""
    out = Path(out)
    existed = out.exists()
    if existed and not out.is_dir():
        raise OutputError(f"cannot write {out}: exists and is not a directory")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.partial-"))
    except OSError as exc:
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    try:
        try:
            yield stage
            check_interrupted()
        except KeyboardInterrupt:
            raise Interrupted(f"nothing new written, {out} "
                              + ("left as it was (the earlier set untouched)" if existed
                                 else "not created")) from None
        with _sigint_held() as held:
            try:
                _commit(stage, out, set(known))
            except OSError as exc:
                raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
        if held:
            raise Interrupted(f"{out} holds the complete new set (Ctrl-C came while it was "
                              "moved into place)")
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _commit(stage: Path, out: Path, known: set[str]) -> None:
    """Move the staged set into `out`: the earlier set's files aside, the new ones in, the
    earlier ones deleted; on an OSError undo what was done."""
    new = sorted(p.name for p in stage.iterdir())
    write_text(stage / MANIFEST, "".join(f"{n}\n" for n in new))
    if not out.exists():
        os.rename(stage, out)
        stage.mkdir()          # for the caller's rmtree
        return
    old = known | _manifest(out)
    trash = Path(tempfile.mkdtemp(dir=out, prefix=".old-"))
    moved_aside, moved_in = [], []
    try:
        for name in sorted((old | set(new) | {MANIFEST}) - {trash.name}):
            if os.path.lexists(out / name):
                os.rename(out / name, trash / name)
                moved_aside.append(name)
        for name in [*new, MANIFEST]:
            os.rename(stage / name, out / name)
            moved_in.append(name)
    except OSError:
        for name in moved_in:
            os.rename(out / name, stage / name)
        for name in moved_aside:
            os.rename(trash / name, out / name)
        shutil.rmtree(trash, ignore_errors=True)
        raise
    shutil.rmtree(trash, ignore_errors=True)


def _manifest(out: Path) -> set[str]:
    """The names of the set in `out` (its MANIFEST), or none."""
    try:
        text = (out / MANIFEST).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return set()
    return {n for n in text.splitlines() if n and "/" not in n and n not in (".", "..")}


@contextmanager
def _sigint_held() -> Iterator[list]:
    """SIGINT only recorded (not raised) inside; the list yielded is non-empty if one came."""
    held: list = []
    if threading.current_thread() is not threading.main_thread():
        yield held
        return
    previous = signal.signal(signal.SIGINT, lambda s, f: held.append(s))
    try:
        yield held
    finally:
        signal.signal(signal.SIGINT, previous)
