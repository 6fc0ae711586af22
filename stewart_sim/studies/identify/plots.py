"""The figures of `identify`: measured against predicted rack forces per leg, and their residual
(the identification runs), and a held-out run's forces under the identified and the prior
model (validation). Long runs are drawn decimated (stewart_sim.shell.plots.MAX_POINTS); the reports
save them with stewart_sim.shell.plots.save_figure."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stewart_sim.shell.plots import plot_line


def residual_figure(t: np.ndarray, measured: np.ndarray, predicted: np.ndarray,
                    title: str) -> Figure:
    """Per leg (a column each): measured and predicted rack force over t on top, their
    residual (measured - predicted) below, with its RMS in the panel's title."""
    measured, predicted = np.asarray(measured, float), np.asarray(predicted, float)
    fig = Figure(figsize=(15, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 6, height_ratios=(2, 1))
    for i in range(6):
        top = fig.add_subplot(grid[0, i])
        plot_line(top, t, measured[:, i], color="0.35", lw=1.0, label="measured")
        plot_line(top, t, predicted[:, i], color="tab:blue", lw=0.9, label="predicted")
        top.set(title=f"leg {i + 1}", xlabel="time t (s)", ylabel=f"rack force σ{i + 1} (N)")
        top.grid(True, alpha=0.3)
        bottom = fig.add_subplot(grid[1, i], sharex=top)
        r = measured[:, i] - predicted[:, i]
        plot_line(bottom, t, r, color="tab:red", lw=0.8)
        bottom.set(title=f"residual, RMS {_rms(r):.3g} N", xlabel="time t (s)",
                   ylabel="measured - predicted (N)")
        bottom.grid(True, alpha=0.3)
    fig.axes[0].legend(fontsize="small", loc="best")
    fig.suptitle(title)
    return fig


def validation_figure(t: np.ndarray, measured: np.ndarray, identified: np.ndarray,
                      prior: np.ndarray, title: str) -> Figure:
    """A held-out run, per leg: the measured rack force and the forces the identified and the
    prior model predict (top), both models' errors (bottom, RMS in the legend)."""
    measured = np.asarray(measured, float)
    fig = Figure(figsize=(15, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 6, height_ratios=(2, 1))
    for i in range(6):
        top = fig.add_subplot(grid[0, i])
        plot_line(top, t, measured[:, i], color="0.35", lw=1.0, label="measured")
        plot_line(top, t, np.asarray(identified)[:, i], color="tab:blue", lw=0.9,
                  label="identified model")
        plot_line(top, t, np.asarray(prior)[:, i], color="tab:orange", lw=0.9, ls="--",
                  label="prior scene")
        top.set(title=f"leg {i + 1}", xlabel="time t (s)", ylabel=f"rack force σ{i + 1} (N)")
        top.grid(True, alpha=0.3)
        top.legend(fontsize="x-small", loc="best")
        bottom = fig.add_subplot(grid[1, i], sharex=top)
        for model, colour, name in ((identified, "tab:blue", "identified"),
                                    (prior, "tab:orange", "prior")):
            e = np.asarray(model)[:, i] - measured[:, i]
            plot_line(bottom, t, e, color=colour, lw=0.8, label=f"{name}, RMS {_rms(e):.3g} N")
        bottom.set(title="model - measured", xlabel="time t (s)", ylabel="force error (N)")
        bottom.grid(True, alpha=0.3)
        bottom.legend(fontsize="x-small", loc="best")
    fig.suptitle(title)
    return fig


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))
