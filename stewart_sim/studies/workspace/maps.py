"""`workspace --map`: the constant-orientation workspace (the positions a pose of fixed angles
reaches inside every geometric limit and cond(J)), its volume and two slices.

Algorithm (bisection on the margins, no geometric boundary): the positions' bounding box is
the intersection of the boxes of the spheres of radius leg_max about a_i - R p_i (every leg
within its longest length; without a leg_max, 10 characteristic lengths about home). Columns
along z on a square x-y grid of step h: each column sampled every COARSE h in one engine call
(the binding limits alone), then from each first inside sample the engine's travel along z,
down and up, marching in steps of at most h and bisecting each end to 1e-9 m (a barrier at
least h thick, such as the thin band of cond(J) above its limit about the singular pose with
the platform in the base's plane, ends a run). The workspace is the runs connected to the
start pose's (runs of neighbouring columns connect where their z intervals overlap): the
stroke alone also admits the mirror image of the machine through its base, which no motion
from home reaches. The volume is the sum of its runs' lengths times h^2 (the midpoint rule in
x and y, exact in z to 1e-9 m); runs thinner than COARSE h between two samples, and barriers
thinner than h, are missed.

The orientation workspace at a position (`tilts`): the largest tilt from the start's angles
along each of TILT_STEPS azimuths of the tilt axis in the thx-thy plane, by the engine's
travel (march, then regula falsi to 1e-9 rad).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from stewart_fmu.frames import from_platform, to_platform
from stewart_fmu.reach import LIMITS, Engine

COARSE = 4          # a column's samples are COARSE grid steps apart before the bisection
SPAN_FALLBACK = 10  # characteristic lengths about home without a leg_max
MAX_CELLS = 1e9     # grid cells (h^3) in the box searched: a bound on the work


@dataclass(frozen=True)
class WorkspaceMap:
    """The constant-orientation workspace at `angles` (in `frame`) on an x-y grid of step h:
    runs (K, 4) of x, y, z_low, z_high (m, in the frame), the volume (m^3), the box searched
    (lo, hi (3,)), the engine's evaluations and the seconds taken."""

    angles: np.ndarray
    frame: str
    h: float
    runs: np.ndarray
    volume: float
    lo: np.ndarray
    hi: np.ndarray
    seconds: float


def position_box(engine: Engine, angles: np.ndarray, frame: str) -> tuple[np.ndarray, np.ndarray]:
    """The positions' bounding box in the frame (see the module doc)."""
    model = engine.model
    q = to_platform(model, np.r_[0.0, 0.0, 0.0, angles], frame)   # C's angles of the frame's
    from stewart_fmu.reach_params import rotation
    R = rotation(q[3:]).reshape(3, 3)
    centers = np.asarray(model.base_joints) - (R @ np.asarray(model.platform_joints).T).T
    if model.leg_max is not None:
        lo = np.max(centers - model.leg_max, axis=0)
        hi = np.min(centers + model.leg_max, axis=0)
    else:
        span = SPAN_FALLBACK * model.characteristic_length
        lo, hi = np.asarray(model.home[:3]) - span, np.asarray(model.home[:3]) + span
    corners = np.array([[x, y, z, *q[3:]] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    f = from_platform(model, corners, frame)[:, :3]
    return f.min(axis=0), f.max(axis=0)


def constant_orientation(engine: Engine, start, frame: str, h: float) -> WorkspaceMap:
    """The workspace map at the angles of `start` (a pose in the frame) with x-y step h (m):
    the runs connected to the start's position."""
    t0 = time.perf_counter()
    start = np.asarray(start, dtype=float)
    angles = start[3:]
    lo, hi = position_box(engine, angles, frame)
    xs = np.arange(lo[0] + h / 2, hi[0], h)
    ys = np.arange(lo[1] + h / 2, hi[1], h)
    zs = np.arange(lo[2], hi[2] + COARSE * h, COARSE * h)
    runs, cells = [], []
    model = engine.model
    for i, x in enumerate(xs):
        grid = np.empty((len(ys), len(zs), 6))
        grid[..., 0], grid[..., 1], grid[..., 2] = x, ys[:, None], zs[None, :]
        grid[..., 3:] = angles
        inside = engine.binding(to_platform(model, grid.reshape(-1, 6), frame)) < 0
        inside = inside.reshape(len(ys), len(zs))
        for j in np.flatnonzero(inside.any(axis=1)):
            for low, high in _column_runs(engine, grid[j], inside[j], frame, h):
                runs.append((x, ys[j], low, high))
                cells.append((i, j))
    keep = _connected(runs, cells, start[:3], lo, h)
    runs_arr = np.array([runs[k] for k in keep], dtype=float).reshape(-1, 4)
    volume = float(np.sum(runs_arr[:, 3] - runs_arr[:, 2]) * h * h)
    return WorkspaceMap(angles, frame, h, runs_arr, volume, lo, hi, time.perf_counter() - t0)


def _connected(runs: list, cells: list, at: np.ndarray, lo: np.ndarray, h: float) -> list[int]:
    """The indices of the runs connected to the one holding `at` (all of them when none
    does): breadth first over the columns' 4-neighbours, runs joined where their z overlap."""
    by_cell: dict[tuple[int, int], list[int]] = {}
    for k, c in enumerate(cells):
        by_cell.setdefault(c, []).append(k)
    cell = (int((at[0] - lo[0]) // h), int((at[1] - lo[1]) // h))
    seeds = [k for k in by_cell.get(cell, []) if runs[k][2] <= at[2] <= runs[k][3]]
    if not seeds:
        return list(range(len(runs)))
    seen, queue = {seeds[0]}, [seeds[0]]
    while queue:
        k = queue.pop()
        i, j = cells[k]
        for n in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            for other in by_cell.get(n, []):
                if other not in seen and runs[other][2] <= runs[k][3] \
                        and runs[k][2] <= runs[other][3]:
                    seen.add(other)
                    queue.append(other)
    return sorted(seen)


def _column_runs(engine: Engine, column: np.ndarray, inside: np.ndarray, frame: str,
                 h: float) -> list[tuple[float, float]]:
    """The z intervals of a column inside every limit: from each first inside sample, down to
    the first limit, and up by the engine's travel in steps of at most h (any barrier between
    two inside samples, however thin, ends the run there), each end found to 1e-9 m; the next
    run starts at the next inside sample above."""
    big = column[1, 2] - column[0, 2] if len(column) > 1 else h
    up_dir, down_dir = np.array([0, 0, 1.0, 0, 0, 0]), np.array([0, 0, -1.0, 0, 0, 0])
    out, k, n = [], 0, len(column)
    while k < n:
        if not inside[k]:
            k += 1
            continue
        down = engine.travel(column[k], down_dir, frame=frame, reach=big, step=h)
        up = engine.travel(column[k], up_dir, frame=frame, reach=(n - k) * big, step=h)
        top = column[k, 2] + up.step
        out.append((column[k, 2] - down.step, top))
        k = max(k + 1, int(np.floor((top - column[0, 2]) / big)) + 1)
    return out


def _in_runs(m: WorkspaceMap, points: np.ndarray) -> np.ndarray:
    """Whether each position lies in a run of the map (its x-y cell's)."""
    cells: dict[tuple[int, int], list[tuple[float, float]]] = {}
    for x, y, low, high in m.runs:
        cell = (int((x - m.lo[0]) // m.h), int((y - m.lo[1]) // m.h))
        cells.setdefault(cell, []).append((low, high))
    out = np.zeros(len(points), dtype=bool)
    for k, (x, y, z) in enumerate(points):
        runs = cells.get((int((x - m.lo[0]) // m.h), int((y - m.lo[1]) // m.h)), ())
        out[k] = any(low <= z <= high for low, high in runs)
    return out


def slices(engine: Engine, m: WorkspaceMap, center: np.ndarray, path) -> None:
    """Two slices through `center` (a position in the frame) as PNG: x-y and x-z, each grid
    point coloured by the limit that binds there; white where it is inside every limit and
    reached from the start (a run of the map), light grey inside but not reached."""
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    h, lo, hi = m.h, m.lo, m.hi
    xs, ys, zs = (np.arange(lo[k] + h / 2, hi[k], h) for k in range(3))
    fig = Figure(figsize=(11, 5))
    colours = ["white", "tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple",
               "tab:brown", "tab:gray", "tab:olive", "tab:cyan", "tab:pink", "gainsboro"]
    cmap = ListedColormap(colours[:len(LIMITS) + 2])
    for k, (name, axis, values) in enumerate((("x-y at z", 1, ys), ("x-z at y", 2, zs))):
        grid = np.tile(np.r_[center, m.angles], (len(values), len(xs), 1))
        grid[..., 0] = xs[None, :]
        grid[..., axis] = values[:, None]
        binding = engine.binding(to_platform(engine.model, grid.reshape(-1, 6), m.frame))
        code = (binding.astype(int) + 1).reshape(len(values), len(xs))
        mapped = _in_runs(m, grid.reshape(-1, 6)[:, :3]).reshape(code.shape)
        code[(code == 0) & ~mapped] = len(LIMITS) + 1   # inside, not reached from the start
        ax = fig.add_subplot(1, 2, k + 1)
        ax.imshow(code, origin="lower", cmap=cmap, vmin=0, vmax=len(LIMITS) + 1, aspect="equal",
                  extent=(lo[0] * 1e3, hi[0] * 1e3, lo[axis] * 1e3, hi[axis] * 1e3),
                  interpolation="nearest")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel(f"{'yz'[axis - 1]} (mm)")
        at = center[3 - axis]
        ax.set_title(f"{name} = {at * 1e3:.1f} mm")
        seen = sorted(set(np.unique(code)) - {0})
        for c in seen:
            ax.plot([], [], "s", color=colours[c],
                    label=LIMITS[c - 1].name if c <= len(LIMITS) else "inside, not reached")
        if seen:
            ax.legend(loc="upper right", fontsize=7)
    fig.suptitle(f"constant-orientation workspace ({m.frame} frame, angles "
                 f"{', '.join(f'{a:.3g}' for a in m.angles)} rad): {m.volume * 1e3:.4g} l; "
                 "white: reached from the start, colour: the binding limit")
    save_figure(fig, path)


TILT_STEPS = 72   # azimuths of the orientation workspace's tilt directions (5 deg apart)


@dataclass(frozen=True)
class TiltMap:
    """The orientation workspace at a position: per azimuth phi of the tilt axis (cos phi,
    sin phi, 0) in the thx-thy plane of the frame's angles, the largest tilt (rad) from the
    start's angles, and the limit that ends it."""

    azimuth: np.ndarray    # rad
    tilt: np.ndarray       # rad
    limit: tuple[str, ...]
    where: tuple[str, ...]


def tilts(engine: Engine, start, frame: str, steps: int = TILT_STEPS) -> TiltMap:
    """The largest tilt along each of `steps` azimuths from the pose `start` (in the frame),
    its position and thz held: the engine's travel along (0, 0, 0, cos phi, sin phi, 0)."""
    start = np.asarray(start, dtype=float)
    phis = np.arange(steps) * (2 * np.pi / steps)
    out = [engine.travel(start, np.array([0, 0, 0, np.cos(p), np.sin(p), 0.0]), frame=frame)
           for p in phis]
    return TiltMap(phis, np.array([t.step for t in out]), tuple(t.limit or "" for t in out),
                   tuple(t.where for t in out))


def tilt_figure(m: TiltMap, path) -> None:
    """The largest tilt per azimuth as a polar plot (deg), PNG."""
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    fig = Figure(figsize=(5.5, 5.5))
    ax = fig.add_subplot(1, 1, 1, projection="polar")
    ax.plot(np.r_[m.azimuth, m.azimuth[:1]], np.degrees(np.r_[m.tilt, m.tilt[:1]]), "-o", ms=2)
    ax.set_title("largest tilt (deg) per tilt axis azimuth (thx-thy plane)", fontsize=9)
    save_figure(fig, path)
