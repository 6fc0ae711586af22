"""design.toml's [motions] and [drives] read and checked: the motions each candidate must fly
(read as `size` reads them: stewart_sim.studies.sizing.motions, a vehicle motion cued with the
base scene's [cueing]) and the catalogue drives to choose from (`size`'s catalogue format:
stewart_sim.studies.sizing.catalogue). A bad key is the spec's error naming it (exit 2)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from stewart_fmu.errors import StewartError

from .keys import DesignInputError
from .keys import integer, number, only

MAX_MOTIONS = 16
MOTION_EVERY = 100  # the most a search may thin a motion's samples


@dataclass(frozen=True)
class Flight:
    """The motions each candidate must fly (docs/guides/design.md, [motions] and [drives]):
    platform trajectories about home (`size`'s Motion, q minus the base scene's home: each
    candidate flies them about its own), the samples the search keeps (every `every`-th; the
    dense check keeps all), the fraction of every drive rating kept free (`size --margin`),
    the catalogue drives to choose from in cost order (None: the base scene's [drive] with its
    [controller.motor]) and the base scene's [controller] (its motor and load)."""

    motions: tuple[Any, ...]             # stewart_sim.studies.sizing.motions.Motion
    every: int
    margin: float
    drives: tuple[Any, ...] | None       # stewart_sim.studies.sizing.catalogue.Drive
    controller: Any | None               # controller.config.ControllerConfig


def flight(motions: dict, drives: dict, path: Path, scene_path: Path) -> Flight | None:
    """The Flight of the two tables (None when [motions] is absent) of the design file at
    `path` whose base scene is at `scene_path`."""
    src = str(path)
    if not motions:
        if drives:
            raise DesignInputError(f"{src}: [drives]: a drive is chosen for the motions: give "
                                   "[motions]")
        return None
    from stewart_sim.studies.sizing.study import DEFAULT_MARGIN

    only(motions, {"files", "every", "margin"}, "motions.", src)
    only(drives, {"catalogue", "names"}, "drives.", src)
    files = motions.get("files")
    if not (isinstance(files, list) and 1 <= len(files) <= MAX_MOTIONS
            and all(isinstance(f, str) and f for f in files)):
        raise DesignInputError(f"{src}: motions.files: need a list of 1 to {MAX_MOTIONS} "
                               f"paths (platform trajectories or vehicle motions, relative "
                               f"to the file), got {files!r}")
    every = integer(motions, "every", 1, 1, MOTION_EVERY, "motions.", src)
    margin = number(motions, "margin", DEFAULT_MARGIN, 0.0, 10.0, "motions.", src, "1")
    catalogue = _drives(drives, path) if drives else None
    base = _base_scene(scene_path, src)
    if catalogue is None and (base.controller is None or base.model.drive is None):
        raise DesignInputError(f"{src}: [motions]: the base scene has no [drive] and "
                               "[controller.motor] to fly them with: give them, or [drives] "
                               "catalogue")
    read = _motions(base, files, path)
    return Flight(read, every, margin, catalogue, base.controller)


def _base_scene(scene_path: Path, src: str):
    from stewart_sim.scene.load import load

    try:
        return load(scene_path)
    except StewartError as exc:
        raise DesignInputError(f"{src}: design.base_scene: {exc}") from None


def _motions(base, files: list[str], path: Path) -> tuple:
    """Each file read as `size` reads it (cued about the base scene's home), kept about home:
    q minus home, so that each candidate flies it about its own."""
    from stewart_sim.studies.sizing.motions import read_one

    home = np.asarray(base.model.home, dtype=float)
    seen, out = set(), []
    for k, name in enumerate(files):
        where = f"{path}: motions.files[{k}]"
        file = (path.parent / name).resolve()
        if file in seen:
            raise DesignInputError(f"{where}: {name} given twice")
        seen.add(file)
        try:
            m = read_one(base, file, name)
        except StewartError as exc:
            raise DesignInputError(f"{where}: {exc}") from None
        if not np.all(np.isfinite(m.q)):
            raise DesignInputError(f"{where}: {name}: a pose is not finite")
        out.append(replace(m, q=m.q - home))
    return tuple(out)


def _drives(t: dict, path: Path) -> tuple:
    """The catalogue's drives (those of `names` when given), cheapest first (then by name)."""
    from stewart_sim.studies.sizing.catalogue import read_catalogue

    src = str(path)
    where = t.get("catalogue")
    if not isinstance(where, str) or not where:
        raise DesignInputError(f"{src}: drives.catalogue: required, a path (relative to the "
                               "file)")
    try:
        drives = read_catalogue(path.parent / where)
    except StewartError as exc:
        raise DesignInputError(f"{src}: drives.catalogue: {exc}") from None
    names = t.get("names")
    if names is not None:
        known = {d.name for d in drives}
        if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)
                and len(set(names)) == len(names)):
            raise DesignInputError(f"{src}: drives.names: need a list of distinct drive "
                                   f"names, got {names!r}")
        for n in names:
            if n not in known:
                raise DesignInputError(f"{src}: drives.names: {n!r} is not in the catalogue")
        drives = tuple(d for d in drives if d.name in names)
    return tuple(sorted(drives, key=lambda d: (d.cost, d.name)))
