"""The map's figures: the lowest frequency and the weakest translational stiffness over the
grid of `modes --map`, as a slice through its first two axes (the others at their middle value),
or a line over a single axis; poses outside the stroke blank."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stewart_sim.studies.sweep.plots import colorbar_ticks

from .study import POSE, Grid, MapResult

QUANTITIES = (("lowest_hz", "lowest frequency (Hz)"),
              ("weakest", "weakest translational stiffness (N/um)"))


def _unit(name: str) -> str:
    return "rad" if name.startswith("th") else "m"


def _values(m: MapResult, which: str) -> np.ndarray:
    """The quantity at every grid pose, NaN outside."""
    out = np.full(len(m.poses), np.nan)
    if m.values is not None:
        v = m.values.lowest_hz if which == "lowest_hz" else m.values.weakest * 1e-6
        out[m.inside] = v
    return out


def map_figures(name: str, grid: Grid, m: MapResult) -> dict[str, Figure]:
    """map_lowest_hz.png and map_weakest.png: file name -> figure."""
    axes = list(grid.axes)
    shape = tuple(len(grid.axes[a]) for a in axes)
    middle = tuple(n // 2 for n in shape[2:])
    held = ", ".join(f"{a} = {grid.axes[a][k]:.4g} {_unit(a)}" for a, k in zip(axes[2:], middle))
    fixed = [p for p in POSE if p not in axes]
    base = ", ".join(f"{p} = {grid.base[POSE.index(p)]:.4g}" for p in fixed)
    figures = {}
    for which, label in QUANTITIES:
        values = _values(m, which).reshape(shape)
        fig = Figure(figsize=(7, 5.6), layout="constrained")
        ax = fig.add_subplot()
        title = f"{name}: {label} over the grid; blank: outside the stroke"
        title += f"\n{base}" + (f"; slice at {held}" if held else "")
        if len(axes) == 1:
            ax.plot(grid.axes[axes[0]], values, marker="o")
            ax.set(xlabel=f"{axes[0]} ({_unit(axes[0])})", ylabel=label)
        else:
            sl = values[(slice(None), slice(None), *middle)]
            mesh = ax.pcolormesh(grid.axes[axes[0]], grid.axes[axes[1]], np.ma.masked_invalid(sl.T),
                                 shading="auto", cmap="viridis")
            cbar = fig.colorbar(mesh, ax=ax, label=label)
            finite = sl[np.isfinite(sl)]
            if finite.size:
                colorbar_ticks(cbar, float(finite.min()), float(finite.max()), False)
            ax.set(xlabel=f"{axes[0]} ({_unit(axes[0])})", ylabel=f"{axes[1]} ({_unit(axes[1])})")
        ax.set_title(title, fontsize=9)
        figures[f"map_{which}.png"] = fig
    return figures
