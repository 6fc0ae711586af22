"""The files of `excite`, written together or not at all (stewart_sim.shell.outputs.file_set):

- T.csv: the trajectory in the contract's columns (stewart_fmu.io TRAJECTORY_COLUMNS), in the
  format `inverse` reads and `trajectory` writes;
- the report beside it (the same name, .md): the condition number, the base parameters, every
  limit and its margin, the series' coefficients;
- the figure beside it (.png): one period of the pose (mm, mrad) and of the leg lengths against
  the stroke and its margin (mm).

`summary` gives the lines `excite` prints.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stewart_fmu import io
from stewart_fmu.errors import StewartError
from stewart_fmu.frames import table_from_platform
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.shell.outputs import file_set
from stewart_sim.shell.plots import LEG_COLOURS, plot_line, save_figure
from stewart_sim.studies.excite.bounds import Kept, Peaks
from stewart_sim.studies.excite.design import GRID_PER_HARMONIC, Excitation

MM = 1e3
SIDE = (".md", ".png")      # the report and the figure beside T.csv


def side_paths(out: str | Path) -> tuple[Path, Path, Path]:
    """T.csv and the report and figure beside it (the same name, .md and .png)."""
    out = Path(out)
    if out.suffix.lower() in SIDE:
        raise StewartError(f"excite: --out {out}: the trajectory cannot be a {out.suffix} file "
                           "(the report and the figure are written beside it as T.md, T.png)")
    return out, out.with_suffix(".md"), out.with_suffix(".png")


def write_excitation(model: Model, e: Excitation, scene: str, out: str | Path,
                     frame: str = "platform") -> list[Path]:
    """T.csv (its motion in `frame` of the scene's [frames]), its report and its figure, all or
    nothing; returns their paths."""
    paths = side_paths(out)
    traj = e.trajectory
    table = io.trajectory_table(traj.t, traj.q, traj.qd, traj.qdd)
    with file_set(*paths) as (csv, md, png):
        io.write_csv(csv, table_from_platform(model, table, frame))
        io.write_text(md, report_text(e, scene, paths[0], frame))
        save_figure(figure(model, e), png)
    return list(paths)


def margins(lim: Kept, p: Peaks) -> list[tuple[str, str, str, str]]:
    """(limit, reached, bound kept, limit itself) per quantity, as text with units."""
    rows = [("stroke, shortest leg", f"{np.min(p.stroke_min) * MM:.2f} mm",
             f">= {lim.bound('stroke_min') * MM:.2f} mm", f"{lim.leg_min * MM:.2f} mm"),
            ("stroke, longest leg", f"{np.max(p.stroke_max) * MM:.2f} mm",
             f"<= {lim.bound('stroke_max') * MM:.2f} mm", f"{lim.leg_max * MM:.2f} mm")]
    for quantity, label, unit, fmt in (("speed", "leg speed", "m/s", ".3g"),
                                       ("acceleration", "leg acceleration", "m/s^2", ".3g"),
                                       ("force", "rack force", "N", ".4g"),
                                       ("voltage", "motor voltage", "V", ".3g")):
        limit, value = getattr(lim, quantity), getattr(p, quantity)
        reached = "-" if value is None else f"{np.max(value):{fmt}} {unit}"
        rows.append((label, reached, "not limited", "-") if limit is None else
                    (label, reached, f"<= {lim.bound(quantity):{fmt}} {unit}",
                     f"{limit:{fmt}} {unit}"))
    rows.append(("cond(J), worst pose", f"{p.cond:.3g}", f"<= {lim.bound('cond'):.3g}",
                 f"{lim.cond:.3g}"))
    return rows


def summary(e: Excitation) -> list[str]:
    """The lines `excite` prints: the condition number, the base parameters, the margins."""
    d, p, lim = e.design, e.peaks, e.design.limits
    lines = [f"scaled condition number of the stacked base regressor: {e.cond:.4g} "
             f"(columns of unit norm; {d.base.rank} base parameters, {e.trajectory.t.size} "
             f"samples x 6 legs; "
             f"optimised on a grid of {GRID_PER_HARMONIC * d.series.harmonics} samples a "
             f"period: {d.cond:.4g})",
             f"stroke: shortest leg {np.min(p.stroke_min) * MM:.2f} mm, "
             f"{(np.min(p.stroke_min) - lim.leg_min) * MM:.2f} mm from leg_min; longest "
             f"{np.max(p.stroke_max) * MM:.2f} mm, {(lim.leg_max - np.max(p.stroke_max)) * MM:.2f}"
             f" mm from leg_max (margin kept {lim.margin * MM:.2f} mm)"]
    for quantity, label, unit in (("speed", "leg speed", "m/s"),
                                  ("acceleration", "leg acceleration", "m/s^2"),
                                  ("force", "rack force", "N"), ("voltage", "motor voltage", "V")):
        limit, value = getattr(lim, quantity), getattr(p, quantity)
        if limit is None:
            continue
        peak = float(np.max(value))
        lines.append(f"{label}: peak {peak:.4g} {unit} of {limit:.4g} {unit} "
                     f"({peak / limit:.0%}; kept <= {lim.fraction:.0%})")
    lines.append(f"cond(J): worst {p.cond:.3g} of {lim.cond:.3g} ({p.cond / lim.cond:.0%}; "
                 f"kept <= {lim.fraction:.0%})")
    if lim.note:
        lines.append(lim.note)
    return lines


def report_text(e: Excitation, scene: str, out: Path, frame: str = "platform") -> str:
    """The report (.md): what the trajectory is (the frame its file is written in), its
    condition number and its margins."""
    d, s = e.design, e.design.series
    q0, a, b = s.coefficients(e.shrunk * d.x)
    duration = e.trajectory.t[-1] - e.trajectory.t[0]
    lines = [f"# Excitation trajectory {md_text(out.name)}", "",
             f"Scene {md_code(scene)}. A finite Fourier series per pose axis (Swevers' form), "
             f"{s.harmonics} harmonics of f_f = {1 / s.period:g} Hz (period {s.period:g} s, "
             f"up to {s.harmonics / s.period:g} Hz), at rest at home at both ends; "
             f"{e.periods} periods = {duration:g} s at {e.rate:g} Hz "
             f"({e.trajectory.t.size} samples). The file holds the motion of the {frame} "
             "frame (the series and the figure: C's pose).", "",
             "## Condition number", "",
             f"Scaled condition number (columns of unit norm: the units of the parameters do "
             f"not enter it) of the base regressor stacked over every sample and leg: "
             f"**{e.cond:.4g}**, over {d.base.rank} base parameters (the scene's structural "
             f"base). On the optimiser's grid ({GRID_PER_HARMONIC * s.harmonics} samples a "
             f"period): {d.cond:.4g}, polished from the best of the starts, which reached "
             + ", ".join(f"{c:.4g}" for c in d.starts) + f"; {d.evaluations} regressor "
             f"evaluations." + (f" The optimum was scaled by {e.shrunk:.3g} to keep every "
                                f"limit between the grid's samples." if e.shrunk < 1.0 else ""),
             "", "## Limits", "",
             "| limit | reached | kept within | the limit |", "|---|---|---|---|"]
    lines += [f"| {' | '.join(row)} |" for row in margins(d.limits, e.peaks)]
    if d.limits.note:
        lines += ["", d.limits.note + "."]
    lines += ["", "## Coefficients", "",
              "q_j(t) = q0_j + sum_k a_jk/(k w_f) sin(k w_f t) - b_jk/(k w_f) cos(k w_f t) "
              "(m, rad; a, b in m/s, rad/s).", "",
              "| axis | q0 | " + " | ".join(f"a{k}" for k in range(1, s.harmonics + 1)) + " | "
              + " | ".join(f"b{k}" for k in range(1, s.harmonics + 1)) + " |",
              "|---" * (2 + 2 * s.harmonics) + "|"]
    for j, name in enumerate(io.POSE):
        lines.append(f"| {name} | {q0[j]:.6g} | " + " | ".join(f"{v:.6g}" for v in a[j]) + " | "
                     + " | ".join(f"{v:.6g}" for v in b[j]) + " |")
    return "\n".join(lines) + "\n"


def figure(model: Model, e: Excitation) -> Figure:
    """One period of the pose and of the leg lengths, with the stroke and its margin."""
    traj, lim = e.trajectory, e.design.limits
    n = int(np.searchsorted(traj.t, traj.t[0] + e.design.series.period, side="right"))
    t, q = traj.t[:n], traj.q[:n]
    lengths = inverse_kinematics(model, q, with_cond=False).lengths
    fig = Figure(figsize=(9, 9), layout="constrained")
    axes = fig.subplots(3, 1)
    for j, name in enumerate(io.POSE[:3]):
        plot_line(axes[0], t, (q[:, j] - model.home[j]) * MM, label=name)
    axes[0].set(ylabel="translation from home (mm)",
                title=f"one period of {e.periods} (scaled cond {e.cond:.3g})")
    for j, name in enumerate(io.POSE[3:], start=3):
        plot_line(axes[1], t, (q[:, j] - model.home[j]) * MM, label=name)
    axes[1].set(ylabel="rotation from home (mrad)")
    for i in range(6):
        plot_line(axes[2], t, lengths[:, i] * MM, color=LEG_COLOURS[i], label=f"leg {i + 1}")
    for value, style in ((lim.leg_min, "-"), (lim.leg_max, "-"), (lim.bound("stroke_min"), ":"),
                         (lim.bound("stroke_max"), ":")):
        axes[2].axhline(value * MM, color="k", linestyle=style, linewidth=0.8)
    axes[2].set(ylabel="leg length (mm)",
                title="leg lengths; stroke (solid) and the margin kept (dotted)")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=3)
    return fig
