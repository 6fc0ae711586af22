"""The figures of `stewart-sim cue`: vehicle against delivered motion and what is perceived of
each, leg lengths against the stroke, leg forces and drives against their limits, and the
closed loop's tracking when it ran."""
from __future__ import annotations

from typing import Callable

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from stewart_sim.shell.plots import plot_leg_forces, plot_line, tracking_figure

from .study import CueStudy
from .vestibular import AXES, ROTATION_AXES

MODE_COLOURS = ("tab:blue", "tab:orange", "tab:green")


def specific_force_figure(study: CueStudy, title: str) -> Figure:
    """Per axis: the vehicle's and the delivered specific force (left), what is perceived of
    each with the perception threshold (right)."""
    return _motion_figure(study, title, "f", AXES, "specific force", "m/s²", 1.0)


def angular_velocity_figure(study: CueStudy, title: str) -> Figure:
    """Per axis: the vehicle's and the delivered angular velocity, and their perception."""
    return _motion_figure(study, title, "w", ROTATION_AXES, "angular velocity", "deg/s",
                          float(np.degrees(1.0)))


def _motion_figure(study: CueStudy, title: str, sig: str, axes_names, what: str, unit: str,
                   scale: float) -> Figure:
    fig = Figure(figsize=(12, 8.5), layout="constrained")
    grid = fig.subplots(3, 2, sharex=True)
    p0 = study.runs[0].perception
    t = p0.t
    threshold = getattr(p0, f"threshold_{sig}") * scale
    for k, name in enumerate(axes_names):
        raw, seen = grid[k]
        plot_line(raw, t, getattr(p0, f"vehicle_{sig}")[:, k] * scale, "k", lw=1.6,
                  label="vehicle")
        plot_line(seen, t, getattr(p0, f"perceived_vehicle_{sig}")[:, k] * scale, "k", lw=1.6,
                  label="vehicle, perceived")
        for r, colour in zip(study.runs, MODE_COLOURS):
            p = r.perception
            plot_line(raw, t, getattr(p, f"delivered_{sig}")[:, k] * scale, color=colour,
                      lw=1.1, label=f"delivered ({r.mode})")
            plot_line(seen, t, getattr(p, f"perceived_delivered_{sig}")[:, k] * scale,
                      color=colour, lw=1.1, label=f"delivered, perceived ({r.mode})")
        centre = 9.81 if (sig == "f" and k == 2) else 0.0
        seen.axhspan(centre - threshold[k], centre + threshold[k], color="grey", alpha=0.15,
                     lw=0, label=f"threshold ±{threshold[k]:.2g} {unit}")
        for ax, kind in ((raw, ""), (seen, "perceived ")):
            ax.set(ylabel=f"{kind}{what} {name} ({unit})", xlabel="time t (s)")
            ax.grid(True, alpha=0.3)
        rms = getattr(study.runs[0].perception, f"rms_{sig}")[k] * scale
        seen.set_title(f"{name}: RMS perceived error {rms:.3g} {unit} ({study.runs[0].mode})",
                       fontsize=9)
    grid[0, 0].legend(fontsize="small", loc="best")
    grid[0, 1].legend(fontsize="small", loc="best")
    frame = "platform frame C at its origin" if sig == "f" else "platform frame C"
    fig.suptitle(f"{title}\n{what}: vehicle (vehicle frame) against delivered ({frame})")
    return fig


def legs_figure(study: CueStudy, title: str) -> Figure:
    """Leg lengths against the stroke, and cond(J) against its limit."""
    f = study.runs[0].feasibility
    fig = Figure(figsize=(11, 7), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1.3))
    plot_leg_forces(top, f.t, f.lengths, "leg lengths l_i", ylabel="leg length (m)")
    for limit, name in ((f.leg_min, "leg_min"), (f.leg_max, "leg_max")):
        if limit is not None:
            top.axhline(limit, color="tab:red", ls="--", lw=1.0)
            top.annotate(f"{name} {limit:g} m", (f.t[0], limit), fontsize=8, color="tab:red",
                         va="bottom")
    top.legend([f"leg {i + 1}" for i in range(6)], ncol=6, fontsize="small", loc="best")
    plot_line(bottom, f.t, f.cond, color="k", lw=1.0)
    bottom.set(ylabel="cond(J) (–)", xlabel="time t (s)")
    bottom.set_title(f"cond(J) (limit {f.cond_limit:g}, peak {float(np.max(f.cond)):.3g})",
                     fontsize=9)
    bottom.grid(True, alpha=0.3)
    fig.suptitle(f"{title}\nleg lengths against the stroke ({study.runs[0].mode} cue)")
    return fig


def forces_figure(study: CueStudy, title: str) -> Figure:
    """Rack forces, motor currents and voltages against their limits (those the scene has)."""
    f = study.runs[0].feasibility
    panels = [("rack force σ_i (incl. drive)", f.sigma, f.force_limit, "force", "N")]
    if f.current is not None:
        panels += [("motor current i_i", f.current, f.current_limit, "current", "A"),
                   ("motor voltage V_i", f.voltage, f.voltage_limit, "voltage", "V")]
    fig = Figure(figsize=(11, 2.8 * len(panels) + 0.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    for ax, (name, values, limit, what, unit) in zip(axes, panels):
        _limited(ax, f.t, values, name, limit, what, unit)
    axes[0].legend([f"leg {i + 1}" for i in range(6)], ncol=6, fontsize="small", loc="best")
    note = f" ({f.drive_note})" if f.drive_note else ""
    fig.suptitle(f"{title}\nforces and drives ({study.runs[0].mode} cue){note}")
    return fig


def _limited(ax: Axes, t, values, name: str, limit, what: str, unit: str) -> None:
    plot_leg_forces(ax, t, values, name, ylabel=f"{what} ({unit})")
    peak = float(np.max(np.abs(values)))
    if limit is not None:
        for sign in (-1, 1):
            ax.axhline(sign * limit, color="tab:red", ls="--", lw=0.9)
        ax.set_title(f"{name}: peak {peak:.4g} {unit}, limit ±{limit:g} {unit} "
                     f"({100 * peak / limit:.0f} %)", fontsize=9)
    else:
        ax.set_title(f"{name}: peak {peak:.4g} {unit}", fontsize=9)


def tracking(study: CueStudy, title: str) -> Figure | None:
    """The closed loop's pose against the cue, when it ran."""
    if study.tracking is None:
        return None
    return tracking_figure(study.tracking.table, f"{title}\nclosed loop tracking the "
                                                 f"{study.runs[0].mode} cue")


FIGURES: tuple[tuple[str, Callable[[CueStudy, str], Figure | None]], ...] = (
    ("cue_specific_force.png", specific_force_figure),
    ("cue_angular_velocity.png", angular_velocity_figure),
    ("cue_legs.png", legs_figure),
    ("cue_forces.png", forces_figure),
    ("cue_tracking.png", tracking),
)
