"""`workspace --load`: where the rack force limit binds over the constant-orientation
workspace with a payload and an acceleration envelope (as a load-limit calculation about the
pivot does).

The envelope is the 12 signed axis corners of a 6-D box: +-ax, +-ay, +-az (m/s^2, C's linear
acceleration) and +-alx, +-aly, +-alz (rad/s^2, the second derivatives of the angles thx, thy,
thz: the angular acceleration at zero angles), each applied alone, at rest (zero velocity, so
no Coriolis, centripetal or viscous friction terms). At each position of the map's grid (the
x-y columns of the map, z at the grid's heights inside each run) and each corner, the engine's force margin
(the drive's force bound - |sigma_i|, sigma the rack forces of the inverse dynamics with the
model's payload) is taken; a position's margin is the least over the corners and legs, with the
leg and the corner where it is least. The rack force binds where that margin is negative.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.frames import to_platform
from stewart_fmu.reach import Engine

from .maps import WorkspaceMap

AXES = ("ax", "ay", "az", "alx", "aly", "alz")
MAX_POINTS = 2_000_000   # grid positions of one load map: a bound on the work
CHUNK = 10_000           # positions per engine call


@dataclass(frozen=True)
class LoadMap:
    """Per grid position (K, 3: x, y, z in the frame, m): the least force margin over the
    envelope's corners (N), the leg (1..6) and the corner ('+az', '-alx', ...) where it is
    least."""

    points: np.ndarray
    margin: np.ndarray
    leg: np.ndarray
    corner: np.ndarray

    @property
    def binding_fraction(self) -> float:
        """The fraction of the positions (each an h^3 cell of the reachable volume) where the
        rack force binds (margin < 0)."""
        return float(np.mean(self.margin < 0)) if len(self.margin) else 0.0


def corners(accel: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """The 12 signed axis corners (12, 6) of the box `accel` (6,) and their names."""
    accel = np.asarray(accel, dtype=float)
    rows, names = [], []
    for k, axis in enumerate(AXES):
        for sign in (1.0, -1.0):
            row = np.zeros(6)
            row[k] = sign * accel[k]
            rows.append(row)
            names.append(f"{'+' if sign > 0 else '-'}{axis}")
    return np.array(rows), tuple(names)


def grid_points(m: WorkspaceMap) -> np.ndarray:
    """The map's grid positions (K, 3): each run's column at the heights lo_z + h/2 + k h (the
    cell centres of the box searched) inside the run, so that each position stands for one h^3
    cell of the reachable volume and the slices meet the same heights in every column."""
    out = []
    z0 = m.lo[2] + m.h / 2
    for x, y, low, high in m.runs:
        first, last = np.ceil((low - z0) / m.h), np.floor((high - z0) / m.h)
        zs = z0 + m.h * np.arange(first, last + 1)
        out.append(np.column_stack([np.full(len(zs), x), np.full(len(zs), y), zs]))
    return np.concatenate(out) if out else np.empty((0, 3))


def load_map(engine: Engine, m: WorkspaceMap, accel: np.ndarray) -> LoadMap:
    """The least rack-force margin over the envelope `accel` at each grid position of the map
    `m` (its angles held), at rest; StewartError when the engine has no force bound."""
    if not any(lim.name == "force" for lim in engine.present(True, True)):
        raise StewartError("--load: the scene's drives have no force bound (it needs [drive] "
                           "and [controller.motor])")
    points = grid_points(m)
    if len(points) > MAX_POINTS:
        raise StewartError(f"--load: {len(points)} grid positions, more than {MAX_POINTS}: "
                           "give a coarser --resolution")
    acc, names = corners(accel)
    poses = np.column_stack([points, np.tile(m.angles, (len(points), 1))])
    q = to_platform(engine.model, poses, m.frame) if len(points) else poses
    n = len(q)
    margin, leg = np.empty(n), np.empty(n, dtype=int)
    worst = np.empty(n, dtype=int)
    for s in range(0, n, CHUNK):   # bounded memory: CHUNK positions x 12 corners per call
        part = q[s:s + CHUNK]
        Q = np.repeat(part, len(acc), axis=0)
        res = engine.check(Q, np.zeros_like(Q), np.tile(acc, (len(part), 1)))
        mg = res["force"].reshape(len(part), len(acc))
        at = res["force_at"].reshape(len(part), len(acc))
        k = np.argmin(mg, axis=1)
        rows = np.arange(len(part))
        margin[s:s + CHUNK], leg[s:s + CHUNK] = mg[rows, k], at[rows, k].astype(int) + 1
        worst[s:s + CHUNK] = k
    return LoadMap(points, margin, leg, np.array(names, dtype=object)[worst])


def load_table(lm: LoadMap) -> np.ndarray:
    """The CSV table: x, y, z (m), margin_n (N), leg (1..6), corner."""
    out = np.empty(len(lm.margin), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"),
                                          ("margin_n", "f8"), ("leg", "i8"), ("corner", object)])
    out["x"], out["y"], out["z"] = lm.points[:, 0], lm.points[:, 1], lm.points[:, 2]
    out["margin_n"], out["leg"], out["corner"] = lm.margin, lm.leg, lm.corner
    return out


def load_figure(lm: LoadMap, m: WorkspaceMap, center: np.ndarray, path, title: str) -> None:
    """Two slices of the margins (N, colour; x where the force binds) through the grid
    positions nearest `center` (x, y, z in the frame, m): x-y and x-z, PNG."""
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    fig = Figure(figsize=(12, 5.5))
    # the colours span +-(the largest margin): deeper overloads are clipped to full red
    lim = max(float(np.max(np.abs(lm.margin.max()))), 1e-9) if len(lm.margin) else 1.0
    for k, axis in enumerate((2, 1)):          # x-y at z, x-z at y
        ax = fig.add_subplot(1, 2, k + 1)
        other = 3 - axis
        ax.set_xlabel("x (mm)")
        ax.set_ylabel(f"{'xyz'[other]} (mm)")
        ax.set_aspect("equal")
        if not len(lm.margin):
            continue
        at = lm.points[np.argmin(np.abs(lm.points[:, axis] - center[axis])), axis]
        sel = np.abs(lm.points[:, axis] - at) <= m.h / 4
        p, v = lm.points[sel], lm.margin[sel]
        sc = ax.scatter(p[:, 0] * 1e3, p[:, other] * 1e3, c=v, cmap="RdBu", vmin=-lim,
                        vmax=lim, marker="s", s=10)
        bound = v < 0
        if bound.any():
            ax.scatter(p[bound, 0] * 1e3, p[bound, other] * 1e3, marker="x", s=6, c="k",
                       linewidths=0.5, label="rack force binds")
            ax.legend(loc="upper right", fontsize=7)
        ax.set_title(f"x-{'xyz'[other]} at {'xyz'[axis]} = {at * 1e3:.2f} mm", fontsize=9)
        if k == 1:
            fig.colorbar(sc, ax=ax, label="least rack-force margin (N)")
    fig.suptitle(title, fontsize=9)
    save_figure(fig, path)
