"""`workspace --map`'s 3D view (DIR/view.html): the mechanism at the map's start pose (--from,
default home) in the project's view (stewart_sim.view), with the constant-orientation
workspace drawn as its surface (map_surface.surface_object, "/workspace/surface", in N: where C
goes) and the platform plate translucent so the surface about C shows through. One frame; no
forces are computed (the legs are drawn at 0 N)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stewart_fmu.frames import to_platform
from stewart_sim.studies.workspace.map_surface import surface_object
from stewart_sim.studies.workspace.maps import WorkspaceMap
from stewart_sim.view.data import ViewData, view_data

PLATE_OPACITY = 0.35
SURFACE_PATH = "/workspace/surface"


def map_view(scene, m: WorkspaceMap, start: np.ndarray, source: str) -> tuple[ViewData, str]:
    """The view: the mechanism at `start` (a pose in the map's frame) and the map's surface;
    `source`: the scene file's name. Returns it and what the surface drawn is."""
    model = scene.model
    q = to_platform(model, np.asarray(start, dtype=float)[None, :], m.frame)
    obj, s = surface_object(SURFACE_PATH, m, model)
    k = round(s.step / m.h)
    grid = f"{m.h * 1e3:.4g} mm" if k == 1 else \
        f"{s.step * 1e3:.4g} mm (1 column in {k} of the map's {m.h * 1e3:.4g} mm, each way)"
    title = (f"{model.name}: constant-orientation workspace {m.volume * 1e3:.4g} l "
             f"(blue, where C goes; angles {', '.join(f'{a:.3g}' for a in m.angles)} rad, "
             f"{m.frame} frame)")
    drawn = f"surface drawn on a {grid} grid, {len(s.triangles)} triangles"
    view = view_data(model, np.zeros(1), q, np.zeros((1, 6)), controller=scene.controller,
                     fps=1.0, force_label="no forces computed (the geometry)", title=title,
                     source=f"{source}; {drawn}")
    return replace(view, extra=(obj,), plate_opacity=PLATE_OPACITY), drawn


def write_map_view(folder: Path, scene, m: WorkspaceMap, start: np.ndarray,
                   source: str) -> str:
    """view.html into `folder` (a result set's stage); the line saying what it holds."""
    from stewart_sim.view.files import VIEW_FILE, write_beside

    view, drawn = map_view(scene, m, start, source)
    path = Path(folder) / VIEW_FILE
    write_beside(path, view)
    return f"{VIEW_FILE} ({path.stat().st_size / 1e6:.2f} MB; {drawn})"
