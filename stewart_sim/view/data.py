"""The frames a view shows: a run's samples decimated to a frame rate, with the leg lengths,
cond(J), stroke-limit and singularity marks of each frame (data only; html.py writes the page).

Decimation keeps source samples (no interpolation): frame k is the first sample at or after
t0 + k / fps, and the last sample is always kept. Lengths, cond(J) and the marks are those of
the frames' samples (stewart_fmu.kinematics on the frame poses), so an hour's run costs what its
frames cost, not what its samples cost.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu.budget import check_count
from stewart_fmu.errors import StewartError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_sim.view.geometry import ViewGeometry, at_stroke_limit, view_geometry

DEFAULT_FPS = 30.0   # frames per second of simulated time: smooth to the eye, 4 s -> 121 frames
FRAME_BYTES = 1024   # a frame's arrays (ViewData) and its text in the page, about


@dataclass(frozen=True, eq=False)
class ViewData:
    """A view: the geometry, the frames (one row per frame) and what they were made from."""

    geometry: ViewGeometry
    t: np.ndarray            # (F,) s
    q: np.ndarray            # (F, 6) actual pose
    q_ref: np.ndarray | None  # (F, 6) reference pose (closed-loop runs), or None
    lengths: np.ndarray      # (F, 6) m
    forces: np.ndarray       # (F, 6) N
    cond: np.ndarray         # (F,) scaled cond(J)
    at_limit: np.ndarray     # (F, 6) bool: leg within the margin of a stroke limit
    force_label: str         # what the forces are, e.g. "actuator force sigma (inverse dynamics)"
    force_peak: float        # max |force| over every source sample (N)
    title: str
    source: str              # the file or directory the frames come from
    source_samples: int
    fps: float               # the frame rate asked for (frames per second of simulated time)
    speed: float = 1.0       # the page's initial playback speed (simulated s per second)
    # specific forces at the pilot's head (m/s^2, in C; geometry.CUES), drawn as arrows: the
    # vehicle's and the delivered one of a cueing run, or None
    f_vehicle: np.ndarray | None = None     # (F, 3)
    f_delivered: np.ndarray | None = None   # (F, 3)
    # parts of the frames a person picks from the page's selector, which then plays that part
    # in a loop: (label, start time in s), start times increasing (e.g. the modes' cycles)
    chapters: tuple[tuple[str, float], ...] = ()
    # a study's own objects, as meshcat commands (meshcat_scene's dicts), drawn once after the
    # mechanism and left as they are (the design's workspace:
    # stewart_sim.studies.design.workspace_view)
    extra: tuple[dict, ...] = ()
    plate_opacity: float = 1.0   # the platform plate's (below 1: what it covers shows through)

    @property
    def frames(self) -> int:
        return int(self.t.size)


def frame_indices(t: np.ndarray, fps: float) -> np.ndarray:
    """Indices of the source samples shown at `fps` (see the module doc); t increasing."""
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        raise StewartError("view: no samples to show")
    if not (np.isfinite(fps) and fps > 0):
        raise StewartError(f"view: --fps must be a positive number, got {fps}")
    span = float(t[-1] - t[0])
    tolerance = 1e-12 * max(1.0, abs(span))
    if span * fps + 1 <= t.size:   # the frame times as a grid: no more of them than samples
        grid = t[0] + np.arange(int(np.floor(span * fps + 1e-9)) + 1) / fps
        idx = np.minimum(np.searchsorted(t, grid - tolerance), t.size - 1)
    else:
        # more frame times than samples (a long span, a high fps): the grid itself could take
        # gigabytes. Sample i is shown when a frame time falls in (t[i-1], t[i]], i.e. when
        # the frame number floor((t - t0 + tolerance) * fps) steps up at i: the same frames,
        # bounded by the samples
        with np.errstate(over="ignore", invalid="ignore"):
            number = np.floor((t - t[0] + tolerance) * fps)
        idx = np.r_[0, 1 + np.flatnonzero(np.diff(number) > 0)]
    frames = np.unique(np.r_[idx, t.size - 1])
    check_count("view frames", frames.size, FRAME_BYTES, "a lower --fps")
    return frames


def view_data(model: Model, t, q, forces, q_ref=None, *, controller: ControllerConfig | None,
              fps: float = DEFAULT_FPS,
              force_label: str = "actuator force sigma", title: str | None = None,
              source: str = "", source_samples: int | None = None,
              force_peak: float | None = None, speed: float = 1.0,
              f_vehicle=None, f_delivered=None) -> ViewData:
    """The view of samples t (N,), poses q (N, 6), forces (N, 6) and, for closed-loop runs, the
    reference poses q_ref (N, 6), decimated to `fps`. Samples already decimated (at the same
    fps) are kept as they are: give the count they came from (`source_samples`) and the peak
    force over all of them (`force_peak`; default: over the samples given). `controller`: the
    scene's [controller] (None: it has none), for the drives' peak force (view_geometry).
    f_vehicle, f_delivered (N, 3): specific forces at the head (m/s^2, platform frame) drawn as
    arrows, when given."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    forces = np.asarray(forces, dtype=float)
    n = t.size
    for name, arr in (("q", q), ("forces", forces)) + (() if q_ref is None else (("q_ref", q_ref),)):
        if np.shape(arr) != (n, 6):
            raise StewartError(f"view: {name} must be ({n}, 6), got {np.shape(arr)}")
    cues = {"f_vehicle": f_vehicle, "f_delivered": f_delivered}
    for name, arr in cues.items():
        if arr is not None and np.shape(arr) != (n, 3):
            raise StewartError(f"view: {name} must be ({n}, 3), got {np.shape(arr)}")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise StewartError(f"view: {source or 'the samples'}: times must increase")
    idx = frame_indices(t, fps)
    geometry = view_geometry(model, controller=controller)
    kin = inverse_kinematics(model, q[idx])
    finite = forces[np.isfinite(forces)]
    return ViewData(
        geometry=geometry, t=t[idx], q=q[idx],
        q_ref=None if q_ref is None else np.asarray(q_ref, dtype=float)[idx],
        lengths=kin.lengths, forces=forces[idx], cond=kin.cond,
        at_limit=at_stroke_limit(geometry, kin.lengths), force_label=force_label,
        force_peak=(force_peak if force_peak is not None
                    else float(np.max(np.abs(finite))) if finite.size else 0.0),
        title=title or model.name, source=source,
        source_samples=n if source_samples is None else int(source_samples), fps=float(fps),
        speed=float(speed),
        **{name: None if arr is None else np.asarray(arr, dtype=float)[idx]
           for name, arr in cues.items()})
