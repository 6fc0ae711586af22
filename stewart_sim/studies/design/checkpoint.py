"""A design search's checkpoint (DIR/design-checkpoint.npz): every generation evaluated so far,
what `design --resume` continues from.

Format: NPZ of plain arrays, read with allow_pickle=False (nothing in it can run code): X (N,
free) the candidates, margins (N, requirements) their relative margins, generation (N,), and
`meta`, one JSON string (the format's version, the requirement's hash, the free parameters' and
the requirements' names, pymoo's version). Written after each generation through a temporary
file renamed into place (stewart_fmu.io.atomic_write): a Ctrl-C or a kill leaves the earlier
checkpoint or the new one, whole.

Resuming replays, it does not restore: the search starts again from the seed and, for each
generation the checkpoint holds, pymoo's NSGA-II asks its population, which must equal the
stored one bit for bit, and is told the stored margins instead of evaluating them; the
generations after those are evaluated as usual. The random state is therefore the seed's, and
the resumed search is the uninterrupted one (tests/app/test_design_resume.py). A checkpoint of
another requirement (the hash of the parsed design.toml, its base scene, payload, population
and seed: `requirement_hash`), of another pymoo, or whose populations differ from those asked,
is refused (CheckpointError: one line, exit 2)."""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import zipfile
from pathlib import Path

import numpy as np

from stewart_fmu.budget import InputFileError, read_input
from stewart_fmu.errors import StewartError
from stewart_fmu.io import atomic_write

from .spec import MAX_GENERATIONS, DesignSpec

CHECKPOINT_FILE = "design-checkpoint.npz"
FORMAT = 1
ROW_BYTES = 64       # a generation's share of the file beyond its numbers (the NPZ's overhead)


class CheckpointError(StewartError, ValueError):
    """A checkpoint that cannot be resumed from: the message names the file and the reason."""


def requirement_hash(spec: DesignSpec) -> str:
    """sha256 of what decides the search's candidates and margins: every table of the spec
    (the base scene as parsed, the parameters, the workspace, the payload, the requirements,
    the motions to fly and the drives) and the search's population and seed; not the
    generations (a resume may go further) nor the reserve (it only picks among the
    evaluated)."""
    d = dataclasses.asdict(spec)
    d.pop("source")
    d["search"] = {"population": spec.search.population, "seed": spec.search.seed}
    text = json.dumps(d, sort_keys=True, separators=(",", ":"), default=_plain, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _plain(o):
    """A value json cannot write as one: an array by its dtype, shape and the sha256 of every
    byte (the motions' samples: all of them count, not a printed summary), a NumPy scalar as
    its number, a path as its text."""
    if isinstance(o, np.ndarray):
        if o.dtype.hasobject:
            return o.tolist()
        a = np.ascontiguousarray(o)
        return {"dtype": a.dtype.str, "shape": list(a.shape),
                "sha256": hashlib.sha256(a.tobytes()).hexdigest()}
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"the requirement's hash: a {type(o).__name__} in the spec")


def _pymoo_version() -> str:
    import pymoo

    return str(pymoo.__version__)


class Checkpoint:
    """The generations of one search: those read back (`stored`) and those added (`record`)."""

    def __init__(self, path: Path, spec: DesignSpec, names: tuple[str, ...]):
        self.path = Path(path)
        self.meta = {"format": FORMAT, "requirement": requirement_hash(spec),
                     "free": [p.name for p in spec.free], "requirements": list(names),
                     "pymoo": _pymoo_version()}
        self.X = np.empty((0, len(spec.free)))
        self.margins = np.empty((0, len(names)))
        self.generation = np.empty(0, dtype=np.int64)

    @property
    def generations(self) -> int:
        return int(self.generation.max()) + 1 if self.generation.size else 0

    def stored(self, g: int, X: np.ndarray) -> np.ndarray | None:
        """The stored margins of generation g, whose population must be X (asked again from
        the seed); None when the checkpoint does not reach g."""
        if g >= self.generations:
            return None
        rows = self.generation == g
        if self.X[rows].shape != X.shape or not np.array_equal(self.X[rows], X):
            raise CheckpointError(f"{self.path}: generation {g + 1}'s candidates are not those "
                                  "the search asks from its seed (written by another version "
                                  "of the search?); run without --resume")
        return self.margins[rows]

    def record(self, g: int, X: np.ndarray, margins: np.ndarray) -> None:
        """Add generation g (the next one) and write the file (atomically)."""
        if g != self.generations:
            raise ValueError(f"checkpoint: generation {g} recorded after {self.generations}")
        self.X = np.vstack([self.X, X])
        self.margins = np.vstack([self.margins, margins])
        self.generation = np.concatenate([self.generation, np.full(len(X), g, dtype=np.int64)])
        meta = json.dumps({**self.meta, "generations": self.generations})

        def write(fh) -> None:
            np.savez(fh, X=self.X, margins=self.margins, generation=self.generation,
                     meta=np.array(meta))

        atomic_write(self.path, write, binary=True)


def load(path: Path, spec: DesignSpec, names: tuple[str, ...]) -> Checkpoint:
    """The checkpoint at `path`, checked against the spec (CheckpointError naming the file and
    why it cannot be resumed from)."""
    cp = Checkpoint(path, spec, names)
    # the most generations a search runs, each of `population` rows of float64 and int64
    limit = (spec.search.population * MAX_GENERATIONS * (len(spec.free) + len(names) + 1) * 8
             + MAX_GENERATIONS * ROW_BYTES + 65536)
    try:
        raw = read_input(path, limit)
    except InputFileError as exc:
        raise CheckpointError(f"{path}: cannot resume: {exc.reason}") from None
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            arrays = {k: z[k] for k in ("X", "margins", "generation", "meta")}
        meta = json.loads(str(arrays["meta"]))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"{path}: not a design checkpoint ({type(exc).__name__}: "
                              f"{str(exc)[:80]})") from None
    _check_meta(path, meta, cp.meta)
    cp.X, cp.margins, cp.generation = _checked_arrays(path, arrays, len(spec.free), len(names))
    return cp


def _check_meta(path: Path, meta, want: dict) -> None:
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CheckpointError(f"{path}: not a design checkpoint of format {FORMAT}")
    if meta.get("requirement") != want["requirement"]:
        raise CheckpointError(f"{path}: was written for another requirement (design.toml, its "
                              "base scene, payload, population or seed differ); run without "
                              "--resume, or give the file, population and seed it was run with")
    for key in ("free", "requirements", "pymoo"):
        if meta.get(key) != want[key]:
            raise CheckpointError(f"{path}: its {key} ({meta.get(key)!r}) differ from this "
                                  f"search's ({want[key]!r}); run without --resume")


def _checked_arrays(path: Path, a: dict, free: int, requirements: int):
    X, M, gen = a["X"], a["margins"], a["generation"]
    n = len(gen)
    ok = (X.dtype == np.float64 and M.dtype == np.float64 and gen.dtype == np.int64
          and X.shape == (n, free) and M.shape == (n, requirements) and gen.ndim == 1
          and bool(np.all(np.isfinite(X))) and not bool(np.any(np.isinf(M))))
    # generations 0, 1, ..., in order, each a block of rows
    ok = ok and (n == 0 or (gen[0] == 0 and bool(np.all(np.diff(gen) >= 0))
                            and bool(np.all(np.diff(gen) <= 1))))
    if not ok:
        raise CheckpointError(f"{path}: its arrays are not a search's generations (shapes, "
                              "types or values out of form)")
    return X, M, gen


def open_checkpoint(out: str | Path, spec: DesignSpec, resume: bool) -> Checkpoint:
    """The checkpoint of a search into `out`: read back with `resume` (CheckpointError when
    there is none, or it is not this requirement's), else a new one (replacing any there at
    the first generation evaluated)."""
    from .candidate import requirement_names

    names = requirement_names(spec)
    path = Path(out) / CHECKPOINT_FILE
    if not resume:
        return Checkpoint(path, spec, names)
    if not path.is_file():
        raise CheckpointError(f"--resume: {path}: no checkpoint to resume from (a design "
                              "search into that directory writes one after each generation)")
    return load(path, spec, names)


def stopped(out: str | Path, cp: Checkpoint):
    """The Interrupted of a Ctrl-C in the search: what the checkpoint kept."""
    from stewart_sim.shell.outputs import Interrupted

    if cp.generations == 0:
        return Interrupted(f"{out}: no generation finished, nothing new written")
    return Interrupted(f"{cp.path} kept the {cp.generations} generation"
                       f"{'s' if cp.generations > 1 else ''} evaluated ({len(cp.X)} candidates)"
                       f"; the result set in {out} not written; continue with --resume")
