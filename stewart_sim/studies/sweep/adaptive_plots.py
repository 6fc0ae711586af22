"""The map of an adaptive sweep (`sweep --adaptive N`): the outcome at every point over the
first two refined axes (a grid refined along one axis: that axis against the target), the
grid's points and the points refinement added marked apart."""
from __future__ import annotations

from typing import Mapping

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

from stewart_sim.studies.sweep.adaptive import REFINEMENT, refinable_axes
from stewart_sim.studies.sweep.grid import FEASIBLE, GridSpec
from stewart_sim.studies.sweep.plots import axis_label

REFINEMENT_PLOT = "refinement.png"
GRID_TICKS = 12   # an axis of at most this many grid values has its ticks there
# Units of the result columns (stewart_sim/studies/sweep/evaluate.py RESULTS; the PID gains are
# controller/design.py PidGains'), for a map whose vertical axis is the target.
RESULT_UNITS = {**dict.fromkeys((*(f"sigma{i}_max" for i in range(1, 7)), "sigma_max"), "N"),
                "torque_max": "N m", "power_max": "W", "cond_max": "-", "reachable": "-",
                "kp": "V/m", "ki": "V/(m s)", "kd": "V s/m", "phase_margin": "deg",
                "crossover_hz": "Hz", "leg_err_rms": "m", "leg_err_max": "m",
                "pose_err_max_linear": "m", "pose_err_max_angular": "rad", "current_max": "A",
                "voltage_rms": "V", "saturated_time": "s", "lowest_hz": "Hz",
                "weakest_n_per_um": "N/um"}


def refinement_figure(table: Mapping[str, np.ndarray], grid: GridSpec, title: str) -> Figure:
    """Grid points as dots and added points as triangles, both coloured by the outcome
    (feasible or failed; below or at/above the threshold, or failed)."""
    keys = [grid.keys[j] for j in refinable_axes(grid)]
    target, threshold = grid.adaptive.target, grid.adaptive.threshold
    ok = table["status"] == "ok"
    added = table[REFINEMENT] > 0
    if target == FEASIBLE:
        classes = [("feasible", ok, "tab:green"), ("failed", ~ok, "tab:red")]
        what = "feasibility (status ok or error)"
    else:
        above = ok & (np.where(ok, table[target], -np.inf) >= threshold)
        classes = [(f"{target} < {threshold:g}", ok & ~above, "tab:blue"),
                   (f"{target} >= {threshold:g}", above, "tab:orange"), ("failed", ~ok, "0.6")]
        what = f"{target} against {threshold:g}"
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    ax = fig.add_subplot()
    x = keys[0]
    if len(keys) >= 2:
        y, ylabel = table[keys[1]], axis_label(keys[1])
    elif target == FEASIBLE:
        y, ylabel = ok.astype(float), "outcome (1: feasible, 0: failed)"
    else:
        y, ylabel = table[target], f"{target} ({RESULT_UNITS[target]})"
        ax.axhline(threshold, color="0.3", lw=0.8, ls="--", label=f"threshold {threshold:g}")
    for label, mask, colour in classes:
        for sel, marker, size, edge, kind in ((mask & ~added, "o", 22, "none", "grid"),
                                              (mask & added, "^", 26, "black", "added")):
            if sel.any():
                ax.scatter(table[x][sel], y[sel], s=size, marker=marker, c=colour,
                           edgecolors=edge, linewidths=0.5,
                           label=f"{label}: {int(sel.sum())} {kind}")
    for j, name in zip(refinable_axes(grid)[:2], ("x", "y")):
        if name == "y" and len(keys) < 2:
            break
        axis = getattr(ax, f"{name}axis")
        if grid.axes[j].log:
            getattr(ax, f"set_{name}scale")("log")
        values = sorted(set(grid.axes[j].grid_values()))
        if len(values) <= GRID_TICKS:   # the grid's lines, labelled (3 digits)
            axis.set_major_locator(FixedLocator(values))
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
            axis.set_minor_locator(NullLocator())
    ax.set(xlabel=axis_label(x), ylabel=ylabel)
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="best")
    rounds = int(table[REFINEMENT].max()) if len(table[REFINEMENT]) else 0
    plane = f", projected onto {keys[0]} - {keys[1]}" if len(keys) > 2 else ""
    ax.set_title(f"{title}\nrefinement of {what}: {int(added.sum())} points added in {rounds} "
                 f"rounds (triangles){plane}", fontsize=9)
    return fig
