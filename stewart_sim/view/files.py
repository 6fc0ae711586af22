"""The 3D view file a command writes beside its results (`run`, `inverse`, `demo`, `paper`,
`cue`, `view`): VIEW_FILE, write_beside and its one-line description."""
from __future__ import annotations

from pathlib import Path

from stewart_fmu.io import writing
from stewart_sim.view.data import ViewData
from stewart_sim.view.html import write_view

VIEW_FILE = "view.html"


def describe(view: ViewData, size: int) -> str:
    """One line: the page's size and what it shows."""
    return (f"{size / 1e6:.2f} MB, {view.frames} frames at {view.fps:g} frames/s from "
            f"{view.source_samples} samples")


def write_beside(path: Path, view: ViewData) -> str:
    """Write a command's view (inside its result set); returns the describe() line."""
    with writing(path):
        size = write_view(path, view)
    return describe(view, size)
