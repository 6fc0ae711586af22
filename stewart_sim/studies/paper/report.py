"""Files of the paper rerun: CSV per trajectory and level, PNG plots in the style of the paper's
Figs. 2-5, a comparison of the three levels, and report.md with the setup and the claim figures."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

from stewart_fmu.dynamics import present_parts
from stewart_fmu.io import named_array, write_csv, write_text
from stewart_fmu.model import Model, is_per_leg
from stewart_sim.scene.describe import per_leg_text
from stewart_sim.scene.paper_moves import TRAJECTORIES, Trajectory
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.shell.plots import plot_leg_forces, save_figure
from stewart_sim.studies.paper.study import (
    FAR_LARGER,
    LEVEL_TITLES,
    LEVELS,
    NEGLIGIBLE,
    SIGNIFICANT,
    VARIANTS,
    PaperResults,
    Run,
)

FIG45_TRAJECTORIES = ("x", "thz")  # the paper does not say which two moves Figs. 4-5 show
FORCE_LABEL = "actuator force σ (N)"
LEG_WIDTHS = (3.4, 2.9, 2.4, 1.9, 1.5, 1.1)  # thick to thin, so coincident curves stay visible
PANEL = "abcdef"


def write_paper_report(results: PaperResults, out_dir: str | Path) -> list[Path]:
    """Write the CSVs, PNGs and report.md of a paper rerun into out_dir; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = write_csvs(results, out)
    paths += write_plots(results, out)
    paths.append(write_text(out / "report.md", report_markdown(results, paths)))
    return paths


def csv_name(trajectory: str, level: str) -> str:
    """File name of one run: levels are numbered 1-3 as in the paper, variants keep their name."""
    tag = f"level{LEVELS.index(level) + 1}" if level in LEVELS else level
    return f"{trajectory}_{tag}.csv"


def write_csvs(results: PaperResults, out: Path) -> list[Path]:
    """One CSV per trajectory and level (and leg variant)."""
    paths = []
    for name in TRAJECTORIES:
        tr = results.trajectories[name]
        for level in (*LEVELS, *VARIANTS):
            table = run_table(results.t, tr, results.runs[name][level], results.models[level])
            paths.append(write_csv(out / csv_name(name, level), table))
    return paths


def run_table(t: np.ndarray, tr: Trajectory, run: Run, model: Model) -> np.ndarray:
    """t, sigma1..6, then the breakdown per part (platform1..6, ...), lddot1..6 and cond."""
    cols = {"t": t}
    cols.update({f"sigma{i + 1}": run.sigma[:, i] for i in range(6)})
    for part in present_parts(model):
        cols.update({f"{part}{i + 1}": run.parts[part][:, i] for i in range(6)})
    cols.update({f"lddot{i + 1}": tr.accelerations[:, i] for i in range(6)})
    cols["cond"] = tr.cond
    return named_array(cols)


def write_plots(results: PaperResults, out: Path) -> list[Path]:
    """The PNGs: Figs. 2 and 3 style, Figs. 4-5 style and the comparison of levels."""
    figs = {
        "fig2_platform_only.png": force_grid(results, "platform", "Fig. 2 style"),
        "fig3_with_legs.png": force_grid(results, "legs", "Fig. 3 style"),
        "fig4_5_drive_inertia.png": drive_figure(results),
        "levels_comparison.png": levels_figure(results),
    }
    return [save_figure(fig, out / name) for name, fig in figs.items()]


def trajectory_label(tr: Trajectory) -> str:
    """E.g. 'x: constant 10 m/s^2' or 'thz: constant 8 rad/s^2'."""
    unit = "m/s²" if tr.axis < 3 else "rad/s²"
    return f"{tr.name}: constant {tr.acceleration:g} {unit}"


def force_grid(results: PaperResults, level: str, style: str) -> Figure:
    """2x3 grid, one panel per trajectory, six force curves each."""
    fig = Figure(figsize=(13, 7.5), layout="constrained")
    axes = fig.subplots(2, 3)
    for k, (ax, name) in enumerate(zip(axes.ravel(), TRAJECTORIES)):
        tr = results.trajectories[name]
        plot_leg_forces(ax, results.t, results.runs[name][level].sigma,
                     f"({PANEL[k]}) {trajectory_label(tr)}")
    axes[0, 0].legend(fontsize=8, ncols=2)
    fig.suptitle(f"{style}: {results.scene}, {LEVEL_TITLES[level]}, no friction")
    return fig


def drive_figure(results: PaperResults) -> Figure:
    """Figs. 4-5 style: two trajectories, without (a) and with (b) drive inertia side by side."""
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    axes = fig.subplots(2, 2)
    for row, name in enumerate(FIG45_TRAJECTORIES):
        tr = results.trajectories[name]
        for col, (level, tag) in enumerate((("legs", "(a) without"), ("drive", "(b) with"))):
            plot_leg_forces(axes[row, col], results.t, results.runs[name][level].sigma,
                         f"Fig. {4 + row}{tag} drive inertia — {trajectory_label(tr)}",
                         FORCE_LABEL, LEG_WIDTHS)
    axes[0, 0].legend(fontsize=8, ncols=2)
    fig.suptitle(f"Figs. 4-5 style: {results.scene}, m_d = {results.drive_mass:.4g} kg per leg"
                 + (" (the largest)" if results.per_leg_drive else ""))
    return fig


def levels_figure(results: PaperResults) -> Figure:
    """2x3 grid of grouped bars: peak |sigma_i| per leg at each level (log scale)."""
    fig = Figure(figsize=(13, 7.5), layout="constrained")
    axes = fig.subplots(2, 3)
    legs = np.arange(1, 7)
    width = 0.27
    for k, (ax, name) in enumerate(zip(axes.ravel(), TRAJECTORIES)):
        for j, level in enumerate(LEVELS):
            peak = np.max(np.abs(results.runs[name][level].sigma), axis=0)
            ax.bar(legs + (j - 1) * width, peak, width, label=f"level {j + 1}: {level}")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(LogFormatter())
        ax.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False, minor_thresholds=(1, 0.5)))
        ax.set_xticks(legs, [f"σ{i}" for i in legs])
        ax.set_xlabel("actuator i (leg number)")
        ax.set_ylabel("peak |σ| over the move (N)")
        ax.set_title(f"({PANEL[k]}) {trajectory_label(results.trajectories[name])}", fontsize=9)
        ax.grid(True, axis="y", alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=3)
    fig.suptitle(f"{results.scene}: platform only vs + legs vs + legs + drive inertia (log scale)")
    return fig


def report_markdown(results: PaperResults, paths: list[Path]) -> str:
    """The report: setup, peak forces, claim figures and verdicts, file list."""
    sections = (_setup(results), _peaks(results), _claim_a(results), _claim_b(results),
                _fig3a(results), _verdicts(results), _files(paths))
    return "\n\n".join(sections) + "\n"


def _table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table."""
    cell = lambda c: c.replace("|", "\\|")  # noqa: E731  (|σ| must not split a cell)
    lines = ["| " + " | ".join(map(cell, header)) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(map(cell, r)) + " |" for r in rows])


def _vec(a) -> str:
    """A short vector in brackets."""
    return "[" + ", ".join(f"{v:.6g}" for v in np.ravel(a)) + "]"


def _setup(r: PaperResults) -> str:
    """Scene, geometry, masses, drive, what was removed, the trajectories."""
    m, lg, dr = r.model, r.model.legs, r.model.drive
    fr = r.removed_friction
    joints = _table(["leg", "base joint a_i in N (m)", "platform joint p_i in C (m)"],
                    [[str(i + 1), _vec(m.base_joints[i]), _vec(m.platform_joints[i])]
                     for i in range(6)])
    cond = ", ".join(f"{n} {tr.cond.min():.3g}-{tr.cond.max():.3g}"
                     for n, tr in r.trajectories.items())
    return "\n".join([
        f"# Paper rerun (Section 3): {md_text(r.scene)}", "",
        f"Scene {md_code(m.source or r.scene)}; gravity {_vec(m.gravity)} m/s².", "",
        joints, "",
        f"- home pose {_vec(m.home)} (m, rad); stroke [{m.leg_min}, {m.leg_max}] m",
        f"- platform: mass {m.platform_mass:g} kg, principal inertia {_vec(m.platform_inertia)} kg m²",
        f"- legs: lower part {lg.lower_mass:g} kg, CoM {lg.lower_com:g} m from the base joint, "
        f"inertia [transverse, axial] {_vec(lg.lower_inertia)} kg m²; upper part "
        f"{lg.upper_mass:g} kg, CoM {lg.upper_com:g} m from the platform joint, inertia "
        f"{_vec(lg.upper_inertia)} kg m²",
        f"- drive: gear ratio ζ = {dr.gear_ratio:g}, rotor inertia I = {per_leg_text(dr.rotor_inertia)} "
        f"kg m², pinion radius r = {dr.pinion_radius:g} m, so m_d = ζ² I / r² = "
        f"{per_leg_text(tuple(dr.reflected_masses)) if is_per_leg(dr.rotor_inertia) else f'{dr.reflected_mass:.6g}'} kg",
        "- friction: removed at every level, as in the paper (\"damping and friction were "
        "ignored\")" + (f"; the scene has viscous {per_leg_text(fr.viscous)} N s/m, Coulomb "
                        f"{per_leg_text(fr.coulomb)} N"
                        if fr else "; the scene has none"),
        f"- moves: from rest at home, constant acceleration on one pose coordinate for "
        f"{r.t[-1]:g} s ({r.t.size} samples): 10 m/s² along x, y, z and 8 rad/s² on the Euler "
        "angles thx, thy, thz (Euler-angle accelerations, as the conventions define them)",
        f"- cond(J) along the moves: {cond}",
        "- levels: " + "; ".join(LEVEL_TITLES[k] for k in (*LEVELS, *VARIANTS)),
    ])


def _peaks(r: PaperResults) -> str:
    """Peak |sigma| over time and legs per trajectory and level."""
    cols = (*LEVELS, *VARIANTS)
    rows = [[n] + [f"{np.max(np.abs(r.runs[n][c].sigma)):.4g}" for c in cols] for n in TRAJECTORIES]
    header = ["trajectory", "level 1 (N)", "level 2 (N)", "level 3 (N)", "lower only (N)",
              "upper only (N)"]
    return "## Peak actuator force max over t and legs of |σ_i|\n\n" + _table(header, rows)


def _claim_a(r: PaperResults) -> str:
    """Claim (a) table: lower vs upper leg masses."""
    rows = [[n, f"{f.platform_peak:.4g}", f"{f.lower_effect:.4g}", f"{f.lower_relative:.1%}",
             f"{f.upper_effect:.4g}", f"{f.upper_relative:.1%}", f"{f.upper_over_lower:.3g}",
             f"{f.lower_inertia_peak:.3g}", f"{f.upper_inertia_peak:.3g}",
             f"{f.legs_effect_min:.3g} to {f.legs_effect_max:.3g}", f"{f.legs_effect_spread:.3g}",
             "agrees" if f.agrees else "does not agree"] for n, f in r.leg_masses.items()]
    header = ["trajectory", "platform-only peak (N)", "lower effect (N)", "rel.",
              "upper effect (N)", "rel.", "upper/lower", "lower_legs part peak (N)",
              "upper_legs part peak (N)", "level 2 − level 1 range (N)",
              "spread across legs (N)", "verdict"]
    return "\n".join([
        "## Claim (a): \"lower leg masses have negligible effects ... whereas the effects of upper "
        "leg masses are very significant\"", "",
        "Effect = max over t and legs of |σ(variant) − σ(platform only)|, including the legs' "
        "weight; rel. = over the platform-only peak. The `*_legs part` columns are the leg "
        "inertia alone (breakdown at level 2, no gravity). The last two columns compare the paper's "
        "Fig. 3 with Fig. 2 (all legs vs none); the paper says the change is uniform across the legs "
        "for z.", "",
        f"Thresholds: negligible < {NEGLIGIBLE:.0%}, very significant >= {SIGNIFICANT:.0%} of the "
        "platform-only peak.", "",
        _table(header, rows)])


def _claim_b(r: PaperResults) -> str:
    """Claim (b) table: drive inertia vs coupling forces."""
    rows = [[n, f"{f.drive_peak:.4g}", f"{f.drive_variation / f.drive_peak:.0%}",
             f"{f.coupling_peak:.4g}", f"{f.coupling_variation:.3g}", f"{f.coupling_spread:.3g}",
             f"{f.level2_variation:.3g}", f"{f.gravity_peak:.4g}", f"{f.ratio_peak:.3g}",
             f"{f.ratio_spread:.3g}", f"{f.ratio_variation:.3g}", f"{f.ratio_gravity:.3g}",
             "agrees" if f.agrees else "does not agree"] for n, f in r.drive.items()]
    header = ["trajectory", "drive m_d·l̈ peak (N)", "its variation / peak",
              "coupling peak (N)", "coupling variation in t (N)", "coupling spread over legs (N)",
              "level-2 σ variation in t (N)", "gravity peak (N)", "drive / coupling peak",
              "drive / spread", "drive / level-2 variation", "drive / gravity", "verdict"]
    return "\n".join([
        "## Claim (b): \"the dynamic coupling effects of the platform and the supporting legs are "
        "very small compared to the inertia forces of the drive systems\"", "",
        "Drive = the breakdown's `drives` part, m_d·l̈_i. Coupling = the non-drive inertial part "
        "(platform + lower-leg + upper-leg inertia, no gravity). Variation in t = max over legs of "
        "(max − min) over the move; spread over legs = max over t of (max − min) across the six "
        "legs. The verdict uses drive / coupling peak, the strictest of the ratios.", "",
        f"Threshold: far larger = at least {FAR_LARGER:g}×.", "",
        _table(header, rows)])


def _fig3a(r: PaperResults) -> str:
    """The Fig. 3(a) remark: per-leg change of |sigma| from level 1 to level 2 (x move)."""
    f = r.fig3a
    ch = f.change
    rows = [[str(i + 1), f"{ch[0, i]:+.3g}", f"{ch[-1, i]:+.3g}", f"{f.fall_fraction[i]:.0%}",
             "—" if np.isnan(f.first_fall[i]) else f"{f.first_fall[i]:.3g}",
             f"{r.trajectories[f.trajectory].rates[-1, i]:+.3g}"] for i in range(6)]
    header = ["leg", "Δ|σ| at t = 0 (N)", "Δ|σ| at the end (N)", "samples where |σ| falls",
              "first fall at t (s)", "l̇ at the end (m/s)"]
    return "\n".join([
        f"## Fig. 3(a) remark: with leg masses some forces increase, some decrease ({f.trajectory} move)",
        "", "Δ|σ| = |σ(level 2)| − |σ(level 1)|.", "", _table(header, rows)])


def _verdicts(r: PaperResults) -> str:
    """Plain agrees / does not agree per claim, with the reason."""
    lines = ["## Verdicts", ""]
    for v in r.verdicts:
        lines.append(f"- **{v.claim}: {'agrees' if v.agrees else 'does not agree'}.** {v.reason}.")
    return "\n".join(lines)


def _files(paths: list[Path]) -> str:
    """The files written next to this report."""
    csvs = sum(p.suffix == ".csv" for p in paths)
    pngs = [p.name for p in paths if p.suffix == ".png"]
    return "\n".join([
        "## Files", "",
        f"- {csvs} CSV files `<trajectory>_level<1|2|3>.csv` and `<trajectory>_<lower_only|"
        "upper_only>.csv`: columns t, sigma1..sigma6, then the breakdown per part present at that "
        "level (platform, lower_legs, upper_legs, drives, gravity; 1..6 per leg), lddot1..6 "
        "(m/s²) and cond (scaled cond(J))",
        *[f"- `{p}`" for p in pngs]])
