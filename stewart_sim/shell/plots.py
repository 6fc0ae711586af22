"""Plots shared by the reports: six leg-force curves per panel, PNG written atomically."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from stewart_fmu.io import atomic_write
from stewart_sim.shell.terminal import printable

LEG_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")

# Drawing long runs: a line of more than MAX_POINTS samples is drawn as its min/max envelope,
# the samples split into MAX_POINTS // 2 equal runs of consecutive samples and each run drawn
# as its smallest and largest sample in time order (peaks kept, at most MAX_POINTS points a
# line). The CSV files keep every sample; only the drawing is decimated.
MAX_POINTS = 5000


def decimation_indices(y: np.ndarray, max_points: int = MAX_POINTS) -> np.ndarray:
    """Sorted indices of the min/max envelope of y (all indices when len(y) <= max_points)."""
    y = np.asarray(y, float)
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    size = -(-n // (max_points // 2))            # samples per run: ceil(n / (max_points / 2))
    m = n // size
    blocks = y[:m * size].reshape(m, size)
    start = np.arange(m) * size
    idx = [start + np.argmin(blocks, axis=1), start + np.argmax(blocks, axis=1)]
    if m * size < n:                             # the last, shorter run
        tail = y[m * size:]
        idx.append(np.array([m * size + np.argmin(tail), m * size + np.argmax(tail)]))
    return np.unique(np.concatenate(idx))


def decimate(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS
             ) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) reduced to their min/max envelope of at most max_points points (see MAX_POINTS)."""
    k = decimation_indices(y, max_points)
    return np.asarray(t)[k], np.asarray(y)[k]


def plot_line(ax: Axes, t: np.ndarray, y: np.ndarray, *args, **kwargs):
    """ax.plot of one line, decimated for drawing (see MAX_POINTS)."""
    return ax.plot(*decimate(t, y), *args, **kwargs)


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Render a figure to PNG with the Agg canvas (no display needed), atomically. Control
    characters in its texts (a scene's name in a title) are drawn escaped, as printed, and a
    tab as a space."""
    for text in fig.findobj(Text):
        text.set_text(printable(text.get_text()).replace("\t", " "))   # no glyph for a tab
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
    """Six curves forces[:, i] against t on one axes, labelled with units (each line decimated
    for drawing, see MAX_POINTS)."""
    for i in range(6):
        plot_line(ax, t, forces[:, i], color=LEG_COLOURS[i],
                  lw=1.2 if widths is None else widths[i], label=f"σ{i + 1}")
    ax.set_title(title, fontsize=9)
    ax.set(xlabel="time t (s)", ylabel=ylabel)
    ax.grid(True, alpha=0.3)


def _columns(table: np.ndarray, prefix: str) -> np.ndarray:
    """The (N, 6) array of fields <prefix>1..6 of a structured array."""
    return np.column_stack([table[f"{prefix}{i + 1}"] for i in range(6)])


# --- closed-loop runs (controller.cosim result tables) ----------------------------------------

POSE_LABELS = (("x", "m"), ("y", "m"), ("z", "m"), ("θx", "rad"), ("θy", "rad"), ("θz", "rad"))
POSE_FIELDS = ("x", "y", "z", "thx", "thy", "thz")


def tracking_figure(table: np.ndarray, title: str) -> Figure:
    """One panel per pose coordinate: reference (dashed) and actual, the error on a right axis."""
    fig = Figure(figsize=(12, 8.5), layout="constrained")
    axes = fig.subplots(3, 2, sharex=True).T.ravel()  # x, y, z down the left; angles right
    t = table["time"]
    twins = []
    for ax, field, (label, unit) in zip(axes, POSE_FIELDS, POSE_LABELS):
        plot_line(ax, t, table[f"{field}_ref"], "k--", lw=1.6, label="reference")
        plot_line(ax, t, table[field], color="tab:blue", lw=1.1, label="actual")
        ax.set(ylabel=f"{label} ({unit})", xlabel="time t (s)")
        ax.grid(True, alpha=0.3)
        err = ax.twinx()
        twins.append(err)
        plot_line(err, t, table[field] - table[f"{field}_ref"], color="tab:red", lw=0.8,
                  alpha=0.7, label="error (right axis)")
        err.set_ylabel(f"error ({unit})", color="tab:red", fontsize=8)
        err.tick_params(axis="y", labelcolor="tab:red", labelsize=7)
        peak = float(np.max(np.abs(table[field] - table[f"{field}_ref"])))
        ax.set_title(f"{label}: max |error| {peak:.3g} {unit}", fontsize=9)
    lines = axes[0].get_lines() + twins[0].get_lines()   # reference, actual; the error
    axes[0].legend(lines, [ln.get_label() for ln in lines], fontsize="small", loc="best")
    fig.suptitle(title)
    return fig


def leg_errors_figure(table: np.ndarray, title: str) -> Figure:
    """Leg-length errors e_i = l_ref,i - l_i, then the pose errors (translation, rotation)."""
    fig = Figure(figsize=(11, 8.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    t = table["time"]
    plot_leg_forces(axes[0], t, _columns(table, "e"), "leg errors e_i = l_ref,i − l_i",
                    ylabel="leg error (m)")
    axes[0].legend([f"leg {i + 1}" for i in range(6)], ncol=6, fontsize="small", loc="best")
    for ax, fields, unit in ((axes[1], POSE_FIELDS[:3], "m"), (axes[2], POSE_FIELDS[3:], "rad")):
        for k, (f, (label, _)) in enumerate(zip(fields, POSE_LABELS[:3] if unit == "m"
                                                 else POSE_LABELS[3:])):
            plot_line(ax, t, table[f] - table[f"{f}_ref"], color=LEG_COLOURS[k], lw=1.1,
                      label=f"{label} − {label}_ref")
        ax.set(ylabel=f"pose error ({unit})", xlabel="time t (s)")
        ax.set_title(f"pose errors ({'translation' if unit == 'm' else 'rotation'})", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=3, fontsize="small", loc="best")
    fig.suptitle(title)
    return fig


def drive_figure(table: np.ndarray, voltage_limit: float, current_limit: float,
                 title: str) -> Figure:
    """Motor voltages (with the feedforward part dotted), currents and torques per leg; the
    limits dashed and the samples where any axis saturates shaded."""
    fig = Figure(figsize=(11, 8.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    t = table["time"]
    sat = np.any(_columns(table, "saturated") > 0, axis=1)
    panels = (("voltage", "motor voltage V_i", "voltage (V)", voltage_limit, "V"),
              ("current", "motor current i_i", "current (A)", current_limit, "A"),
              ("torque", "motor torque τ_i (mean over each step)", "torque (N m)", None, "N m"))
    for ax, (field, name, ylabel, limit, unit) in zip(axes, panels):
        plot_leg_forces(ax, t, _columns(table, field), name, ylabel=ylabel)
        if field == "voltage":
            ff = _columns(table, "v_ff")
            for i in range(6):
                plot_line(ax, t, ff[:, i], ":", color=LEG_COLOURS[i], lw=1.0)
        if limit is not None:
            peak = float(np.max(np.abs(_columns(table, field))))
            if peak > 0.3 * limit:  # else the limit lines would flatten the curves
                for sign in (-1, 1):
                    ax.axhline(sign * limit, color="grey", ls="--", lw=0.8)
            ax.set_title(f"{name} ({field} limit ±{limit:g} {unit}, peak {peak:.3g} {unit})",
                         fontsize=9)
        if np.any(sat):
            k = decimation_indices(sat.astype(float))   # keeps every run's saturated sample
            ax.fill_between(t[k], 0, 1, where=sat[k], transform=ax.get_xaxis_transform(),
                            color="tab:red", alpha=0.12, lw=0, step="mid")
    axes[0].legend([f"leg {i + 1}" for i in range(6)], ncol=6, fontsize="small", loc="best")
    v_peak = float(np.max(np.abs(_columns(table, "voltage"))))
    notes = [f"voltage limit ±{voltage_limit:g} V, peak {v_peak:.3g} V", "dotted: feedforward part"]
    if np.any(sat):
        notes.append(f"shaded: an axis saturated ({np.count_nonzero(sat)} samples)")
    axes[0].set_title("motor voltage V_i (" + "; ".join(notes) + ")", fontsize=9)
    fig.suptitle(title)
    return fig
