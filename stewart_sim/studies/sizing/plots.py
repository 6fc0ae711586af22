"""The figures of `stewart-sim size`: each motion's leg lengths, rack forces and leg speeds
against the scene's limits; the torque-speed plane of every drive (the scene's and each
catalogue drive) with its limits and each motion's operating points; the catalogue drives'
ratios against the margin."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from stewart_sim.shell.plots import LEG_COLOURS, plot_line

from .study import CANDIDATE_CHECKS, CandidateResult, SceneSizing, operating_points

MOTION_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                  "tab:pink", "tab:gray", "tab:olive", "tab:cyan")
MAX_PANELS = 24           # torque-speed panels: the scene's drive and the first ranked drives


def motion_colour(k: int) -> str:
    return MOTION_COLOURS[k % len(MOTION_COLOURS)]


def demand_figure(scene: SceneSizing, leg_min: float | None, leg_max: float | None,
                  title: str) -> Figure:
    """Per motion (column): leg lengths with the stroke, rack forces with Kf I_max, leg speeds
    with the no-load speed, each leg in its colour."""
    n = len(scene.demands)
    fig = Figure(figsize=(4.5 * n + 1, 9), layout="constrained")
    grid = np.asarray(fig.subplots(3, n, squeeze=False, sharex="col"))
    axis = scene.axis
    force = None if axis is None else axis.peak_force
    speed = None if axis is None else axis.no_load_speed
    rows = (("lengths", "leg length l (m)", (leg_min, leg_max)),
            ("force", "rack force σ (N)", (force,)),
            ("speed", "leg speed l̇ (m/s)", (speed,)))
    for col, d in enumerate(scene.demands):
        for row, (key, label, limits) in enumerate(rows):
            ax = grid[row, col]
            values = d.lengths if key == "lengths" else d.values[key]
            for i in range(6):
                plot_line(ax, d.t, values[:, i], color=LEG_COLOURS[i], lw=0.8, label=f"leg {i + 1}")
            for k, limit in enumerate(v for v in limits if v is not None):
                marks = (limit,) if key == "lengths" else (limit, -limit)
                for v in marks:
                    ax.axhline(v, color="k", ls="--", lw=0.8,
                               label="limit" if (k == 0 and v == marks[0]) else None)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(d.motion, fontsize=9)
            if row == 2:
                ax.set_xlabel("time t (s)")
    grid[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"{title}: what each motion asks of the legs (scene's drive)")
    return fig


def torque_speed_figure(scene: SceneSizing, ranked: Sequence[CandidateResult],
                        motions: Sequence[str], margin: float, title: str) -> Figure | None:
    """One panel per drive: motor speed (x) against motor torque (y), every leg at the samples
    of study.operating_points, a colour per motion; the drive's limits as boxes (peak torque
    and speed: solid; continuous torque: dashed). The scene's drive first (its motor's
    Kt I_max and no-load speed), then the catalogue drives in ranked order. None when no
    drive has a torque (a scene without [drive] and no catalogue)."""
    panels: list[tuple[str, list, float | None, float | None, float | None]] = []
    if all(d.values["torque"] is not None for d in scene.demands):
        panels.append(("scene's drive", [operating_points(d.values["motor_speed"],
                                                          d.values["torque"])
                                         for d in scene.demands],
                       scene.peak_torque, None, scene.no_load_speed))
    for r in ranked[:MAX_PANELS - len(panels)]:
        if r.error is None:
            verdict = "qualifies" if r.qualifies(margin) else "does not qualify"
            panels.append((f"{r.drive.name}: {verdict}", list(r.points), r.drive.peak_torque,
                           r.drive.continuous_torque, r.drive.max_speed))
    if not panels:
        return None
    cols = min(4, len(panels))
    rows = max(1, math.ceil(len(panels) / cols))
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows + 0.8), layout="constrained")
    axes = np.asarray(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, (name, points, peak, continuous, top) in zip(axes, panels):
        for k, (speed, torque) in enumerate(points):
            ax.plot(speed.ravel(), torque.ravel(), ".", ms=1.5,
                    color=motion_colour(k), rasterized=True, label=motions[k])
        if peak is not None and top is not None:
            ax.add_patch(Rectangle((-top, -peak), 2 * top, 2 * peak, fill=False, color="k",
                                   lw=1.0, label="peak torque, max speed"))
        if continuous is not None and top is not None:
            ax.add_patch(Rectangle((-top, -continuous), 2 * top, 2 * continuous, fill=False,
                                   color="k", ls="--", lw=1.0, label="continuous torque"))
        ax.autoscale_view()
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("motor speed ω (rad/s)")
        ax.set_ylabel("motor torque τ (N m)")
        ax.grid(alpha=0.3)
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7, markerscale=6)
    fig.suptitle(f"{title}: operating points in the torque-speed plane (solid box: peak torque "
                 "and max speed; dashed: continuous torque)")
    return fig


def candidates_figure(ranked: Sequence[CandidateResult], margin: float, title: str) -> Figure:
    """Per catalogue drive (ranked order): the worst ratio over the motions of each check, with
    the line the margin allows and the limit."""
    good = [r for r in ranked if r.error is None]
    fig = Figure(figsize=(max(6.0, 0.9 * len(good) + 2), 4.8), layout="constrained")
    ax = fig.subplots()
    x = np.arange(len(good))
    width = 0.8 / len(CANDIDATE_CHECKS)
    labels = {"torque_peak": "peak torque / peak rating",
              "torque_rms": "RMS torque / continuous rating",
              "motor_speed": "peak speed / max speed"}
    for k, check in enumerate(CANDIDATE_CHECKS):
        ratios = [r.worst(check)[0].ratio for r in good]
        ax.bar(x + (k - 1) * width, ratios, width, label=labels[check])
    ax.axhline(1.0 / (1.0 + margin), color="k", ls="--", lw=1,
               label=f"the most a {100 * margin:g} % margin allows")
    ax.axhline(1.0, color="tab:red", lw=1, label="rating")
    ax.set_xticks(x, [r.drive.name for r in good], rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("demand / rating (1), worst motion")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title(f"{title}: catalogue drives, ranked")
    return fig
