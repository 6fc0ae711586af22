"""The view as one self-contained HTML file: meshcat's three.js viewer (the pip package's
bundled `viewer/dist/main.min.js`, embedded unchanged), the scene as meshcat commands, the
frames as base64 float32 arrays embedded once, and page.js, which shows a frame through the
viewer's commands. The same page shows frames from a URL polled live (`live_view_html`).

Why meshcat: it is the three.js viewer Drake and Pinocchio use; it takes scene commands
(set_object / set_transform / set_property) as plain data and runs from one offline file.
"""
from __future__ import annotations

import base64
import html
import importlib.util
import json
import re
from pathlib import Path

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.io import write_text
from stewart_sim.view.colours import colour_table, nice_ceiling
from stewart_sim.view.data import ViewData
from stewart_sim.view.geometry import ViewGeometry
from stewart_sim.view.geometry import CUES
from stewart_sim.view.meshcat_scene import CUE_COLOURS, PLATE, rgb, scene_commands

_HERE = Path(__file__).resolve().parent
LIVE_PERIOD_MS = 50     # the live page asks for a state every 50 ms (20 Hz)


def meshcat_viewer_js() -> str:
    """The meshcat package's bundled viewer (found without importing meshcat: its Python side
    starts with its server's imports)."""
    spec = importlib.util.find_spec("meshcat")
    if spec is None or not spec.submodule_search_locations:
        raise StewartError("view: the meshcat package is missing (pip install meshcat)")
    path = Path(list(spec.submodule_search_locations)[0]) / "viewer" / "dist" / "main.min.js"
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise StewartError(f"view: cannot read meshcat's viewer {path}: {exc}") from None


def _b64(a: np.ndarray, dtype) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def _page(title: str, subtitle: str, force_label: str, status: str, geometry: ViewGeometry,
          ghost: bool, force_scale: float | None, source: dict, cues: bool = False,
          extra: tuple[dict, ...] = (), plate_opacity: float = 1.0) -> str:
    """page.html filled in (one pass, so no inserted text is read as a placeholder); its data:
    the scene's commands, the colour map and the frame source (frames, or the live URL);
    `cues`: the frames may carry the specific-force arrows (geometry.CUES); `extra`: a study's
    own objects' commands, after the scene's; `plate_opacity`: the platform plate's."""
    data = {"geometry": geometry.to_json(),
            "scene": scene_commands(geometry, ghost, cues) + list(extra),
            "ghost": ghost, "lut": colour_table().tolist(), "force_scale": force_scale,
            "plate_rgb": rgb(PLATE), "plate_opacity": plate_opacity, "live": None, "cues": cues,
            "cue_rgb": {name: rgb(CUE_COLOURS[name]) for name in CUES}, **source}
    text = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    parts = {
        "TITLE": html.escape(title), "SUBTITLE": html.escape(subtitle),
        "FORCE_LABEL": html.escape(force_label), "STATUS": html.escape(status),
        "COND_WARN": f"{geometry.cond_warn:g}",
        "GHOST_NOTE": "<br>translucent: the reference pose" if ghost else "",
        "DATA": text, "MESHCAT": meshcat_viewer_js(),
        "PAGE_JS": (_HERE / "page.js").read_text(encoding="utf-8"),
    }
    template = (_HERE / "page.html").read_text(encoding="utf-8")
    return re.sub(r"\{\{([A-Z_]+)\}\}", lambda m: parts[m.group(1)], template)


_PAGE_MAX = float(np.finfo(np.float32).max)   # the page's frames are float32


def _finite(a: np.ndarray | None, name: str) -> None:
    """Refuse values the page cannot hold: non-finite, or beyond float32 (they would be inf)."""
    if a is not None and not np.all(np.abs(a) <= _PAGE_MAX):
        raise StewartError(f"view: {name} holds values that are not finite or beyond the "
                           f"page's float32 range (|x| > {_PAGE_MAX:.3g})")


def static_view_html(view: ViewData) -> str:
    """The page of a run, its frames embedded (file size ~ 100 bytes per frame + 0.9 MB)."""
    g = view.geometry
    for name in ("t", "q", "q_ref", "lengths", "forces", "cond", *CUES):
        _finite(getattr(view, name), name)
    scale = nice_ceiling(view.force_peak) if view.force_peak > 0 else (g.force_scale or 1.0)
    frames = {"count": view.frames, "t": _b64(view.t, "<f4"), "q": _b64(view.q, "<f4"),
              "q_ref": None if view.q_ref is None else _b64(view.q_ref, "<f4"),
              "lengths": _b64(view.lengths, "<f4"), "forces": _b64(view.forces, "<f4"),
              "cond": _b64(view.cond, "<f4"), "at_limit": _b64(view.at_limit, "u1"),
              **{name: None if getattr(view, name) is None else _b64(getattr(view, name), "<f4")
                 for name in CUES}}
    meta = {"fps": view.fps, "frames": view.frames, "speed": view.speed,
            "source_samples": view.source_samples, "source": view.source,
            "chapters": [{"label": label, "t": float(t)} for label, t in view.chapters]}
    span = float(view.t[-1] - view.t[0])
    subtitle = (f"{span:.6g} s, {view.frames} frames at {view.fps:g} frames/s of simulated time "
                f"from {view.source_samples} samples"
                + (f" of {view.source}" if view.source else ""))
    status = "drag: orbit, right-drag: pan, wheel: zoom"
    cues = any(getattr(view, name) is not None for name in CUES)
    return _page(view.title, subtitle, view.force_label, status, g, view.q_ref is not None,
                 scale, {"frames": frames, "meta": meta}, cues, view.extra,
                 view.plate_opacity)


def live_view_html(geometry: ViewGeometry, state_url: str = "/state") -> str:
    """The page of a live device: it polls `state_url` (fetch, every LIVE_PERIOD_MS) for one
    frame as JSON {"t": s, "q": [6], "q_ref": [6] or null, "lengths": [6], "forces": [6],
    "cond": float, "f_vehicle": [3] or null, "f_delivered": [3] or null} and shows it with the
    static page's code (the specific-force arrows when the state has them). The colour bar
    spans the drives' peak force (geometry.force_scale), or grows with the largest force seen."""
    return _page(f"{geometry.name}: live", f"polling {state_url} every {LIVE_PERIOD_MS} ms",
                 "actuator force", "live: connecting", geometry, True, geometry.force_scale,
                 {"live": {"state_url": state_url, "period_ms": LIVE_PERIOD_MS}}, cues=True)


def write_view(path: str | Path, view: ViewData) -> int:
    """Write the static page atomically; returns its size in bytes."""
    text = static_view_html(view)
    write_text(path, text)
    return len(text.encode("utf-8"))
