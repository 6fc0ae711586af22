"""Result sets written all or nothing, and Ctrl-C that always ends the command.

A command that writes several files into --out DIR builds them in a temporary directory beside
DIR (same file system: `.DIR.partial-PID-XXXX`) and puts that directory in the place of DIR at
the end (`result_set`) by one rename (stewart_sim/shell/dirswap.py: renameat2 RENAME_EXCHANGE, or
where the system lacks it, DIR aside then the new one in). A reader, or a process killed at any
instant, SIGKILL included, finds the earlier set whole or the new one whole, never a mix. The
files of the set are listed in DIR/.stewart-sim-set; the next set written into DIR replaces
every file of the earlier one. Files in DIR that belong to no set are kept: hard links to them
(a directory: the same tree of links) are made in the temporary before the swap, so they are
the same files afterwards (DIR's own mode is kept too; its owner, ACLs and extended attributes
are those of a directory the user creates). One that cannot be linked (another file system
mounted inside DIR, a file of another user under fs.protected_hardlinks) is refused in one line
before anything changes. DIR a symbolic link to a directory: the set is written through it (the
directory it names is swapped, the link stays); a link to nothing is refused, and so is a DIR
that holds the working directory (`--out .`: the command's shell would be left in the earlier,
removed, directory; another shell inside DIR is, and sees the new set after `cd DIR`). DIR
cannot be a mount point (the swap renames it: EBUSY, one line, exit 1).
SIGINT (and SIGTERM, SIGHUP) while the set is built removes the temporary directory and leaves
DIR as it was; the swap itself runs with them held back.
The temporary carries the writer's process id (stewart_fmu.io.partial_prefix): one left by a
process that is gone (killed outright, before or after its swap) is removed by the next set
written beside it, and an earlier DIR left aside by the fallback is put back or removed
(dirswap.recover). A command that writes a few named files instead (`inverse`: FORCES.csv and
FORCES.html) stages them the same way (`file_set`: `.FORCES.csv.partial-PID-XXXX` beside them)
and moves them in together, one rename a file (an error or Ctrl-C puts the earlier ones back;
SIGKILL between the renames can leave one new and one earlier file).

SIGINT is handled by `sigint_handler` (stewart_sim/shell/interrupt.py, installed by cli.main): it
records the signal and raises KeyboardInterrupt (inside an import: when the import returns). A KeyboardInterrupt raised where Python cannot propagate it (a
callback from C, a destructor: "Exception ignored in ...") is therefore not lost: the flag
stops the set before it is moved into place, and the command still exits 130.
"""
from __future__ import annotations

import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterable, Iterator

from stewart_fmu.io import (WRITE_ERRNOS, OutputError, check_output, partial_prefix,
                            remove_stale_partials, write_text)
from stewart_sim.shell import dirswap
from stewart_sim.shell.interrupt import check_interrupted, signals_held

MANIFEST = ".stewart-sim-set"   # names of the files of the set in DIR, one a line
# the trash folder a set swapped file by file left in DIR when killed mid-swap: part of no set
_FILEWISE_TRASH = re.compile(r"^\.old-[a-z0-9_]{8}$")

class Interrupted(KeyboardInterrupt):
    """Ctrl-C, with the line saying what was kept (cli.main prints it and exits 130)."""

    def __init__(self, kept: str):
        super().__init__(kept)
        self.kept = kept


@contextmanager
def result_set(out: str | Path, known: Iterable[str] = ()) -> Iterator[Path]:
    """Yield a temporary directory beside `out`; on success its files replace the earlier set
    in `out` (the names in out/MANIFEST, else `known`: what the command writes). On any error
    or Ctrl-C the temporary directory goes and `out` stays as it was (Interrupted says so)."""
    out = Path(out)
    check_output(out)
    place = _through_link(out)
    existed = place.exists()
    if existed and not place.is_dir():
        raise OutputError(f"cannot write {out}: exists and is not a directory")
    kept = f"{out} " + ("left as it was (the earlier set untouched)" if existed else "not created")
    try:
        dirswap.recover(place)
    except OSError as exc:
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    with _staged(place, out, kept, lambda stage: _commit(stage, place, set(known)),
                 f"{out} holds the complete new set (Ctrl-C came while it was moved into "
                 "place)") as stage:
        yield stage


def _through_link(out: Path) -> Path:
    """The directory the set replaces: `out`, or the one a symbolic link `out` names (the set
    is written through the link, which stays). Refused: a link to nothing, and a directory
    that holds this process's working directory (the swap would leave the shell that ran the
    command in the earlier, removed, directory)."""
    place = out
    if out.is_symlink():
        place = Path(os.path.realpath(out))
        if not place.exists():
            raise OutputError(f"cannot write {out}: a symbolic link to {os.readlink(out)}, "
                              "which does not exist")
    real, cwd = os.path.realpath(place), os.getcwd()
    if cwd == real or cwd.startswith(real.rstrip(os.sep) + os.sep):
        raise OutputError(f"cannot write {out}: it holds the working directory, and a result "
                          "set replaces its directory whole; give a directory beneath it")
    return place


def written_in(stage: Path, out: Path, paths: Iterable[str | Path]) -> list[Path]:
    """The paths written into the stage of a result_set, as they are in `out` once moved in."""
    return [out / Path(p).relative_to(stage) for p in paths]


@contextmanager
def file_set(*paths: str | Path) -> Iterator[list[Path]]:
    """Files of one directory written together or not at all (`inverse`: FORCES.csv and its
    FORCES.html): yields a temporary path for each, in a temporary directory beside them; on
    success they replace the files at once. On any error or Ctrl-C the temporaries go and
    every file stays as it was (Interrupted says so); the files not given are left alone."""
    paths = [Path(p) for p in paths]
    directory = paths[0].parent
    if any(p.parent != directory for p in paths) or len({p.name for p in paths}) < len(paths):
        raise ValueError(f"file_set: {', '.join(map(str, paths))}: not distinct files of one "
                         "directory")
    for p in paths:
        check_output(p)
        if p.is_dir():
            raise OutputError(f"cannot write {p}: is a directory")
    kept = ", ".join(f"{p} " + ("left as it was" if p.exists() else "not created")
                     for p in paths)
    names = [p.name for p in paths]
    with _staged(paths[0], directory, kept,
                 lambda stage: _swap(stage, directory, names, names,
                                     Path(tempfile.mkdtemp(dir=stage, prefix=".old-"))),
                 f"{' and '.join(map(str, paths))} written whole (Ctrl-C came while they "
                 "were moved into place)") as stage:
        yield [stage / name for name in names]


@contextmanager
def _staged(beside: Path, target: Path, kept: str, commit: Callable[[Path], None],
            complete: str) -> Iterator[Path]:
    """A temporary directory `.NAME.partial-XXXX` beside `beside` (same file system), moved
    into place by `commit(stage)` with SIGINT held; removed in every case. `kept`: what a
    Ctrl-C before the move left as it was; `complete`: the line for a Ctrl-C during it. An
    OutputError raised inside names the file as it would be in `target`, not the temporary."""
    try:
        beside.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(beside)
        stage = Path(tempfile.mkdtemp(dir=beside.parent, prefix=partial_prefix(beside)))
    except OSError as exc:
        raise OutputError(f"cannot write {beside}: {exc.strerror or exc}") from None
    try:
        try:
            yield stage
            check_interrupted()
        except KeyboardInterrupt:
            raise Interrupted(f"nothing new written, {kept}") from None
        except OutputError as exc:
            raise OutputError(str(exc).replace(str(stage), str(target))) from None
        except OSError as exc:   # a writer of the set (a figure, an archive) met a full disk
            if exc.errno not in WRITE_ERRNOS:
                raise
            raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from None
        with signals_held() as held:
            try:
                commit(stage)
            except OSError as exc:
                raise OutputError(f"cannot write {beside}: {exc.strerror or exc}") from None
        if held:
            raise Interrupted(complete)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _commit(stage: Path, out: Path, known: set[str]) -> None:
    """Put the staged set in the place of `out` by one rename (dirswap.swap_in), the files of
    `out` that belong to no set linked into it first; the earlier set ends at `stage` (removed
    by the caller) or is gone. On an OSError `out` is as it was."""
    new = sorted(p.name for p in stage.iterdir())
    write_text(stage / MANIFEST, "".join(f"{n}\n" for n in new))
    if not out.exists():
        os.rename(stage, out)
        stage.mkdir()          # for the caller's rmtree
        return
    ours = known | _manifest(out) | set(new) | {MANIFEST}
    for entry in sorted(os.scandir(out), key=lambda e: e.name):
        if entry.name in ours or (_FILEWISE_TRASH.match(entry.name)
                                  and entry.is_dir(follow_symlinks=False)):
            continue
        try:
            _link_tree(Path(entry.path), stage / entry.name)
        except OSError as exc:
            raise OutputError(f"cannot write {out}: {entry.path} (no file of a set) cannot be "
                              f"kept across the swap: {exc.strerror or exc}; move it out of "
                              f"{out}") from None
    shutil.copymode(out, stage)
    dirswap.swap_in(stage, out)


def _link_tree(source: Path, target: Path) -> None:
    """Hard links at `target` to `source` and, for a directory, to everything below it (the
    same files, in directories of the same modes and times)."""
    pending, directories = [(source, target)], []
    while pending:
        src, dst = pending.pop()
        if src.is_dir() and not src.is_symlink():
            os.mkdir(dst)
            directories.append((src, dst))
            pending.extend((Path(e.path), dst / e.name) for e in os.scandir(src))
        else:
            os.link(src, dst, follow_symlinks=False)
    for src, dst in reversed(directories):    # after their entries: keep their times
        shutil.copystat(src, dst, follow_symlinks=False)


def _swap(stage: Path, out: Path, new: Iterable[str], aside: Iterable[str], trash: Path) -> None:
    """Move the files `aside` that are in `out` into `trash`, then `new` from `stage` into
    `out`; on an OSError move them back (the earlier files where they were) and raise it."""
    moved_aside, moved_in = [], []
    try:
        for name in aside:
            if os.path.lexists(out / name):
                os.rename(out / name, trash / name)
                moved_aside.append(name)
        for name in new:
            os.rename(stage / name, out / name)
            moved_in.append(name)
    except OSError:
        for name in moved_in:
            os.rename(out / name, stage / name)
        for name in moved_aside:
            os.rename(trash / name, out / name)
        raise


def _manifest(out: Path) -> set[str]:
    """The names of the set in `out` (its MANIFEST), or none."""
    try:
        text = (out / MANIFEST).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return set()
    return {n for n in text.splitlines() if n and "/" not in n and n not in (".", "..")}


