"""A set of result files written all or nothing: every file goes to a temporary directory beside
the output directory, and only once the whole set is complete are the files moved in (an
existing directory keeps its other files; a failure leaves it as it was)."""
from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from stewart_fmu.io import OutputError


@contextmanager
def result_set(out: Path) -> Iterator[Path]:
    """Yield a temporary directory to write the set into; on success its files replace those of
    the same names in `out` (created if needed). Any exception leaves `out` untouched; an OSError
    becomes an OutputError naming `out`."""
    out = Path(out)
    try:
        if out.exists() and not out.is_dir():
            raise OutputError(f"cannot write {out}: it exists and is not a directory")
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp"))
    except OSError as exc:
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    try:
        yield tmp
        try:
            if not out.exists():
                os.chmod(tmp, 0o777 & ~_umask())
                os.replace(tmp, out)          # one rename: the whole set appears at once
                return
            for path in sorted(tmp.iterdir()):
                os.replace(path, out / path.name)
        except OSError as exc:
            raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
