"""The modes' 3D view (DIR/view.html): the platform at the pose, then each mode shape played
as one cycle of a sampled sequence of poses, one second of the page's time per mode (the
page's selector plays one mode in a loop, its frequency in the label; the title lists them).

Pose k of mode j: the pose displaced along the mode's twist chi_j = (v, omega) (N, about C's
origin) by a sin(2 pi k / CYCLE_FRAMES): x = x0 + a s v, R = exp(a s [omega]x) R0, so every
frame lies on the mode's line through the pose. `a` is chosen visible: the largest
displacement of a platform joint, |v| + r |omega| to first order, is AMPLITUDE of the view's
characteristic length (ViewGeometry.size)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from stewart_fmu.stiffness import static_forces
from stewart_sim.view.data import ViewData, view_data
from stewart_sim.view.geometry import view_geometry

from .study import ModesResult

CYCLE_FRAMES = 48     # samples of one cycle; one cycle per second of the page's time
AMPLITUDE = 0.05      # of the view's characteristic length: the largest joint displacement
EULER = "xyz"         # scipy's extrinsic x, y, z: R = Rz(thz) Ry(thy) Rx(thx) (the contract's)


def mode_amplitude(shape: np.ndarray, platform_radius: float, size: float) -> float:
    """The scale a of a mode's twist whose largest platform-joint displacement is
    AMPLITUDE * size (first order)."""
    reach = float(np.linalg.norm(shape[:3]) + platform_radius * np.linalg.norm(shape[3:]))
    return AMPLITUDE * size / reach


def displaced(q0: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """The pose q0 moved by the finite twist (dx, dtheta) (N, about C's origin)."""
    R = Rotation.from_rotvec(twist[3:]) * Rotation.from_euler(EULER, q0[3:])
    return np.r_[q0[:3] + twist[:3], R.as_euler(EULER)]


def mode_poses(result: ModesResult, size: float, platform_radius: float) -> np.ndarray:
    """(count, CYCLE_FRAMES, 6): each mode's cycle of poses."""
    q0 = np.asarray(result.modes.pose, dtype=float)
    phase = np.sin(2.0 * np.pi * np.arange(CYCLE_FRAMES) / CYCLE_FRAMES)
    out = np.empty((result.count, CYCLE_FRAMES, 6))
    for j in range(result.count):
        shape = np.asarray(result.modes.shapes[j], dtype=float)
        a = mode_amplitude(shape, platform_radius, size)
        out[j] = [displaced(q0, a * s * shape) for s in phase]
    return out


def modes_view(result: ModesResult, source: str = "") -> ViewData:
    """The view: every mode's cycle one after the other (mode j from t = j - 1 s to j s)."""
    model = result.model
    g = view_geometry(model, controller=None)
    q = mode_poses(result, g.size, g.platform_radius).reshape(-1, 6)
    t = np.arange(q.shape[0]) / CYCLE_FRAMES
    forces = np.array([static_forces(model, p) for p in q])
    hz = result.modes.frequency_hz[:result.count]
    names = ", ".join(f"mode {j + 1} {f:.4g} Hz ({j}-{j + 1} s)" for j, f in enumerate(hz))
    view = view_data(model, t, q, forces, controller=None, fps=float(CYCLE_FRAMES),
                     force_label="static leg force (holding each frame's pose)",
                     title=f"{model.name}: modes, one cycle per second: {names}", source=source)
    return replace(view, chapters=tuple((f"mode {j + 1}: {f:.4g} Hz", float(j))
                                        for j, f in enumerate(hz)))
