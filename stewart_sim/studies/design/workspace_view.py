"""The design's 3D view (DIR/view.html): the chosen design (with none chosen, the
least-violating candidate) drawn at home in the project's view (stewart_sim.view), with

- its constant-orientation workspace at home's angles: the map of the workspace engine
  (stewart_sim.studies.workspace.maps.constant_orientation, the engine of the design's
  cond(J) limit, x-y step the characteristic length / MAP_STEPS), drawn as its surface, the
  closed translucent mesh `workspace --map` draws too (studies.workspace.map_surface, at
  "/design/workspace/surface");
- the required poses of the dense check (the workspace's check_points grid), a point each at
  its position ("/design/required"), coloured by its least relative geometric margin (each
  limit's margin over the scale the search uses, candidate.margin_scales): green at least the
  [search] reserve, amber from 0 to it, red below 0 (outside a limit).

The page's frames are home, then each required pose in the grid's order (at most
MAX_POSE_FRAMES; beyond, home alone), so the slider shows the mechanism at each: its legs' stroke
and cond(J) marked as in every view. No forces are computed (the legs are drawn at 0 N)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.reach import Engine
from stewart_sim.studies.workspace.map_surface import surface_object
from stewart_sim.studies.workspace.maps import WorkspaceMap, constant_orientation
from stewart_sim.view.data import ViewData, view_data
from stewart_sim.view.meshcat_scene import buffer_object

from .candidate import Candidate, candidate_model, margin_scales, workspace_poses
from .search import SearchResult
from .spec import DesignSpec

MAP_STEPS = 20           # the map's x-y step: the characteristic length / MAP_STEPS
MAX_POSE_FRAMES = 5000   # required poses shown as frames (about 1 kB each in the page)
PLATE_OPACITY = 0.35     # the platform plate, translucent: the workspace about C shows through
GOOD, SHORT, OUT = (0.18, 0.62, 0.27), (0.96, 0.62, 0.04), (0.85, 0.12, 0.12)


@dataclass(frozen=True, eq=False)
class DesignView:
    """What the page draws: the view (mechanism, frames, extra objects), the map drawn, the
    required poses (P, 6) and their least relative geometric margins (P,)."""

    view: ViewData
    map: WorkspaceMap
    poses: np.ndarray
    margin: np.ndarray
    label: str                 # which candidate: "chosen candidate 17"


def pose_margins(spec: DesignSpec, model, values: dict, Q: np.ndarray) -> np.ndarray:
    """Each pose's least relative geometric margin (the engine's limits over their scales)."""
    eng = Engine(model, None, spec.requirements.cond_limit)
    res = eng.check(Q)
    scale = margin_scales(spec, model, values)
    return np.min([res[lim.name] / scale[lim.name] for lim in eng.present()], axis=0)


def margin_colours(margin: np.ndarray, reserve: float) -> np.ndarray:
    """(P, 3): GOOD at least `reserve`, SHORT from 0 to it, OUT below 0."""
    out = np.empty((len(margin), 3))
    out[:] = GOOD
    out[margin < reserve] = SHORT
    out[margin < 0] = OUT
    return out


def _shown(r: SearchResult) -> tuple[Candidate | None, str]:
    if r.chosen is not None:
        return r.chosen, f"chosen candidate {r.chosen_index}"
    return r.closest, "least-violating candidate (no design)"


def design_view(spec: DesignSpec, r: SearchResult) -> DesignView | None:
    """The view of the chosen design (or the least-violating candidate); None when that one's
    model cannot be built (its home outside its stroke)."""
    c, label = _shown(r)
    if c is None:
        return None
    try:
        model = candidate_model(spec, c.values)
    except StewartError:
        return None
    eng = Engine(model, None, spec.requirements.cond_limit)
    h = model.characteristic_length / MAP_STEPS
    m = constant_orientation(eng, np.asarray(model.home, dtype=float), "platform", h)
    Q = workspace_poses(spec.workspace, np.asarray(model.home, dtype=float),
                        spec.workspace.check_points)
    margin = pose_margins(spec, model, c.values, Q)
    size = model.characteristic_length
    extra = (
        surface_object("/design/workspace/surface", m)[0],
        buffer_object("/design/required", "Points", Q[:, :3],
                      margin_colours(margin, spec.search.reserve), size / 25),
    )
    frames = np.vstack([model.home, Q]) if len(Q) <= MAX_POSE_FRAMES else \
        np.asarray(model.home, dtype=float)[None, :]
    title = (f"{label}: workspace ({m.volume * 1e3:.4g} l, blue), {len(Q)} required poses "
             "by margin")
    view = view_data(model, np.arange(len(frames), dtype=float), frames,
                     np.zeros((len(frames), 6)), controller=None, fps=1.0,
                     force_label="no forces computed (the geometry)", title=title,
                     source=f"{Path(spec.source).name}; dots: green >= "
                            f"{spec.search.reserve:.0%}, amber >= 0, red < 0")
    return DesignView(replace(view, extra=extra, plate_opacity=PLATE_OPACITY), m, Q, margin,
                      label)


def write_design_view(folder: Path, spec: DesignSpec, r: SearchResult) -> str | None:
    """view.html into `folder` (a result set's stage); the line saying what it shows, or None
    when there is no candidate to draw."""
    from stewart_sim.view.files import VIEW_FILE, write_beside

    dv = design_view(spec, r)
    if dv is None:
        return None
    line = write_beside(Path(folder) / VIEW_FILE, dv.view)
    return (f"{VIEW_FILE} ({dv.label}; workspace map {len(dv.map.runs)} runs; "
            f"{len(dv.poses)} required poses; {line})")
