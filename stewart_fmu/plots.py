"""Plots shared by the reports: six leg-force curves per panel, PNG written atomically."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .io import atomic_write

LEG_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Render a figure to PNG with the Agg canvas (no display needed), atomically."""
    FigureCanvasAgg(fig)
    return atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi), binary=True)


def forces_figure(table: np.ndarray, parts: Sequence[str], title: str) -> Figure:
    """sigma_i over t on top, then one panel per part of the breakdown."""
    rows = 1 + math.ceil(len(parts) / 2)
    fig = Figure(figsize=(11, 2.6 * rows + 0.6), layout="constrained")
    grid = fig.add_gridspec(rows, 2)
    t = table["t"]
    ax = fig.add_subplot(grid[0, :])
    plot_leg_forces(ax, t, _columns(table, "sigma"), "actuator force σ_i (rack force, incl. drive)")
    ax.legend([f"σ{i + 1}" for i in range(6)], ncol=6, fontsize="small", loc="best")
    for k, name in enumerate(parts):
        ax = fig.add_subplot(grid[1 + k // 2, k % 2], sharex=fig.axes[0])
        plot_leg_forces(ax, t, _columns(table, name), f"part: {name}")
    fig.suptitle(title)
    return fig


def plot_leg_forces(ax: Axes, t: np.ndarray, forces: np.ndarray, title: str,
                    ylabel: str = "force (N)", widths: Sequence[float] | None = None) -> None:
    """Six curves forces[:, i] against t on one axes, labelled with units."""
    for i in range(6):
        ax.plot(t, forces[:, i], color=LEG_COLOURS[i], lw=1.2 if widths is None else widths[i],
                label=f"σ{i + 1}")
    ax.set_title(title, fontsize=9)
    ax.set(xlabel="time t (s)", ylabel=ylabel)
    ax.grid(True, alpha=0.3)


def _columns(table: np.ndarray, prefix: str) -> np.ndarray:
    """The (N, 6) array of fields <prefix>1..6 of a structured array."""
    return np.column_stack([table[f"{prefix}{i + 1}"] for i in range(6)])
