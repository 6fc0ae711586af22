"""The files of `stewart-sim size`, written into DIR all or nothing (stewart_sim.shell.outputs):

    report.md                what the motions ask, the scene's drive against them, each
                             motion against the first mode ([stiffness]), the ranking
    motions.csv              per motion: stroke used, and per quantity its peak (value, time,
                             leg) and the worst leg's RMS, on the scene's drive
    scene_checks.csv         per motion and check: the scene's drive and motor against it
    demand.png               leg lengths, rack forces and leg speeds of every motion
    torque_speed.png         operating points against every drive's limits (when a drive is
                             known: the scene's [drive], or a catalogue)
    with --catalogue:
    candidates.csv           per catalogue drive, ranked: its values, worst ratio of each check
                             and its motion, whether it qualifies, its error if it failed
    candidate_motions.csv    per catalogue drive and motion: peaks, RMS torque and the ratios
    candidates.png           the ratios of every drive against the margin

Column names carry their unit after the last underscore-separated word (force_peak_N,
motor_speed_peak_rad_s, stroke_used_m, t_s); a ratio or a count has none.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

from stewart_fmu import io
from stewart_fmu.model import Model, per_leg
from stewart_sim.cueing.feasibility import Margin
from stewart_sim.cueing.resonance import Resonance
from stewart_sim.shell.markdown import md_text
from stewart_sim.shell.outputs import result_set
from stewart_sim.studies.sweep.result_table import csv_text

from .demand import QUANTITIES, UNITS
from .motions import Motion
from .plots import candidates_figure, demand_figure, torque_speed_figure
from .study import CANDIDATE_CHECKS, CandidateResult, CatalogueSweep, SceneSizing, meets

def verdict(ratio: float, margin: float, quantity: str | None = None) -> str:
    """A check's verdict in words (study.meets)."""
    if meets(ratio, margin, quantity):
        return "meets"
    return "within the limit, not the margin" if ratio <= 1.0 else "past the limit"


def motion_rows(motions: Sequence[Motion], scene: SceneSizing) -> tuple[list[str], list[dict]]:
    """motions.csv: columns and one row per motion."""
    rows = []
    for m, d in zip(motions, scene.demands):
        used = d.stroke_used
        leg = int(used.argmax())
        row: dict[str, Any] = {"motion": m.name, "kind": m.kind, "duration_s": m.duration,
                               "samples": m.t.size, "stroke_used_m": float(used[leg]),
                               "stroke_used_leg": leg + 1,
                               "length_min_m": float(d.lengths.min()),
                               "length_max_m": float(d.lengths.max())}
        for q, st in d.statistics().items():
            unit = UNITS[q][1]
            row.update({f"{q}_peak_{unit}": st.peak.value, f"{q}_peak_t_s": st.peak.t,
                        f"{q}_peak_leg": st.peak.leg, f"{q}_rms_{unit}": st.rms,
                        f"{q}_rms_leg": st.rms_leg})
        rows.append(row)
    columns = list(rows[0])
    return columns, rows


def check_rows(scene: SceneSizing, margin: float) -> tuple[list[str], list[dict]]:
    """scene_checks.csv: one row per motion and check."""
    rows = [{"motion": d.motion, "check": c.quantity, "ratio": c.ratio, "value": c.value,
             "limit": c.limit, "unit": c.unit, "t_s": c.t, "leg": "" if c.leg is None else c.leg,
             "verdict": verdict(c.ratio, margin, c.quantity)}
            for d, checks in zip(scene.demands, scene.checks) for c in checks]
    return ["motion", "check", "ratio", "value", "limit", "unit", "t_s", "leg", "verdict"], rows


def candidate_rows(ranked: Sequence[CandidateResult], margin: float
                   ) -> tuple[list[str], list[dict]]:
    """candidates.csv: one row per drive, ranked."""
    rows = []
    for rank, r in enumerate(ranked, start=1):
        d = r.drive
        row: dict[str, Any] = {
            "rank": rank, "name": d.name, "qualifies": r.qualifies(margin),
            "gear_ratio": d.gear_ratio, "pinion_radius_m": d.pinion_radius,
            "rotor_inertia_kg_m2": d.rotor_inertia,
            "reflected_mass_kg": d.gear_ratio**2 * d.rotor_inertia / d.pinion_radius**2,
            "peak_torque_Nm": d.peak_torque, "continuous_torque_Nm": d.continuous_torque,
            "max_speed_rad_s": d.max_speed,
            "price": "" if d.price is None else d.price,
            "mass_kg": "" if d.mass is None else d.mass,
            "worst_ratio": r.worst_ratio if r.error is None else ""}
        for check in CANDIDATE_CHECKS:
            worst = r.worst(check)
            row[f"{check}_ratio"] = "" if worst is None else worst[0].ratio
            row[f"{check}_motion"] = "" if worst is None else worst[1]
        row["error"] = r.error or ""
        rows.append(row)
    return list(rows[0]), rows


def candidate_motion_rows(ranked: Sequence[CandidateResult]) -> tuple[list[str], list[dict]]:
    """candidate_motions.csv: one row per drive and motion (drives that evaluated)."""
    rows = []
    for r in ranked:
        for m in r.motions:
            row: dict[str, Any] = {"name": r.drive.name, "motion": m.motion}
            for q in ("torque", "motor_speed", "force", "power"):
                st, unit = m.stats[q], UNITS[q][1]
                row.update({f"{q}_peak_{unit}": st.peak.value, f"{q}_peak_t_s": st.peak.t,
                            f"{q}_peak_leg": st.peak.leg})
            row["torque_rms_Nm"] = m.stats["torque"].rms
            row["torque_rms_leg"] = m.stats["torque"].rms_leg
            row.update({f"{c.quantity}_ratio": c.ratio for c in m.checks})
            rows.append(row)
    columns = list(rows[0]) if rows else ["name", "motion"]
    return columns, rows


def write_size_report(out: Path, model: Model, motions: Sequence[Motion], scene: SceneSizing,
                      sweep: CatalogueSweep | None, ranked: Sequence[CandidateResult],
                      margin: float, title: str,
                      first_mode: Sequence[Resonance | None] = (),
                      frame: str = "platform") -> list[Path]:
    """Every file of the sizing into `out`, all or nothing; returns their paths. `first_mode`:
    each motion against the scene's first mode (cueing.resonance; None: no [stiffness]);
    `frame`: the one the platform trajectories were given in (said in report.md)."""
    from stewart_sim.shell.plots import save_figure   # matplotlib: only when writing

    names = []
    with result_set(out) as stage:
        def table(name: str, columns_rows: tuple[list[str], list[dict]]) -> None:
            io.write_text(stage / name, csv_text(*columns_rows))
            names.append(name)

        def figure(name: str, fig) -> None:
            if fig is not None:
                save_figure(fig, stage / name)
                names.append(name)

        table("motions.csv", motion_rows(motions, scene))
        table("scene_checks.csv", check_rows(scene, margin))
        figure("demand.png", demand_figure(scene, model.leg_min, model.leg_max, title))
        figure("torque_speed.png", torque_speed_figure(scene, ranked, [m.name for m in motions],
                                                       margin, title))
        if sweep is not None:
            table("candidates.csv", candidate_rows(ranked, margin))
            table("candidate_motions.csv", candidate_motion_rows(ranked))
            figure("candidates.png", candidates_figure(ranked, margin, title))
        io.write_text(stage / "report.md",
                      report_markdown(model, motions, scene, sweep, ranked, margin, title, names,
                                      first_mode, frame))
        names.insert(0, "report.md")
    return [out / n for n in names]


def _g(v: float, digits: int = 4) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}g}"


def report_markdown(model: Model, motions: Sequence[Motion], scene: SceneSizing,
                    sweep: CatalogueSweep | None, ranked: Sequence[CandidateResult],
                    margin: float, title: str, files: Sequence[str],
                    first_mode: Sequence[Resonance | None] = (), frame: str = "platform") -> str:
    """report.md: the motions, the demand's peaks, the scene's checks, the first mode, the
    ranking."""
    lines = [f"# Actuator sizing: {md_text(title)}", ""]
    lines += ["## Motions", "", "| motion | kind | duration (s) | samples |", "|---|---|---|---|"]
    kinds = {"platform": f"platform trajectory ({frame} frame)",
             "vehicle": "vehicle motion, cued ([cueing] classical washout)"}
    lines += [f"| {md_text(m.name)} | {kinds[m.kind]} | {m.duration:.4g} | {m.t.size} |"
              for m in motions]
    lines += ["", *_demand_section(model, scene), "", *_scene_section(scene, margin)]
    lines += _first_mode_section(motions, first_mode)
    if sweep is not None:
        lines += ["", *_catalogue_section(sweep, ranked, margin)]
    lines += ["", "## Files", "", *(f"- `{n}`" for n in files), ""]
    return "\n".join(lines)


def _demand_section(model: Model, scene: SceneSizing) -> list[str]:
    drive = model.drive
    head = ["## What the motions ask of each leg (the scene's drive)", ""]
    if drive is not None:
        head += [f"Drive: gear ratio ζ = {drive.gear_ratio:g}, pinion radius r = "
                 f"{drive.pinion_radius:g} m, rotor inertia I = "
                 f"{float(per_leg(drive.rotor_inertia).max()):g} kg m² "
                 f"(reflected mass m_d = {drive.reflected_mass:.4g} kg per leg). Rack force σ "
                 "includes m_d l̈ (the contract's total force); torque = σ r / ζ, motor "
                 "speed = l̇ ζ / r, power = σ l̇.", ""]
    else:
        head += ["The scene has no [drive]: motor torque and speed are not computed.", ""]
    rows = ["| quantity | peak | motion | t (s) | leg | RMS, worst leg | motion |",
            "|---|---|---|---|---|---|---|"]
    used = [(float(d.stroke_used.max()), d.motion, int(d.stroke_used.argmax()) + 1)
            for d in scene.demands]
    v, motion, leg = max(used)
    rows.append(f"| stroke used (m) | {v:.4g} | {md_text(motion)} | — | {leg} | — | — |")
    for q in QUANTITIES:
        found = [(d.statistics()[q], d.motion) for d in scene.demands
                 if d.values[q] is not None]
        if not found:
            continue
        peak, pm = max(found, key=lambda s: s[0].peak.magnitude)
        rms, rm = max(found, key=lambda s: s[0].rms)
        unit = UNITS[q][0]
        rows.append(f"| {q.replace('_', ' ')} ({unit}) | {peak.peak.value:.4g} | {md_text(pm)} | "
                    f"{peak.peak.t:.4g} | {peak.peak.leg} | {rms.rms:.4g} | {md_text(rm)} |")
    return head + rows


def _scene_section(scene: SceneSizing, margin: float) -> list[str]:
    lines = [f"## The scene's drive and motor against the motions (margin {100 * margin:g} %)", ""]
    if scene.axis is not None:
        a = scene.axis
        lines += [f"Limits: rack force Kf I_max = {a.peak_force:.4g} N (motor torque "
                  f"{scene.peak_torque:.4g} N m), current {a.motor.current_limit:g} A, voltage "
                  f"{a.motor.voltage_limit:g} V, no-load speed {a.no_load_speed:.4g} m/s "
                  f"(motor {scene.no_load_speed:.4g} rad/s).", ""]
    elif scene.note:
        lines += [f"The motor is not checked: {md_text(scene.note)}.", ""]
    lines += ["| check | worst ratio | value | limit | motion | t (s) | leg | verdict |",
              "|---|---|---|---|---|---|---|---|"]
    worst: dict[str, tuple[Margin, str]] = {}
    for d, checks in zip(scene.demands, scene.checks):
        for c in checks:
            if c.quantity not in worst or c.ratio > worst[c.quantity][0].ratio:
                worst[c.quantity] = (c, d.motion)
    for q, (c, motion) in worst.items():
        lines.append(f"| {q} ({c.unit}) | {c.ratio:.3f} | {c.value:.4g} | {c.limit:.4g} | "
                     f"{md_text(motion)} | {_g(c.t)} | {c.leg or '—'} | "
                     f"{verdict(c.ratio, margin, c.quantity)} |")
    lines += ["", "Ratio: demand / limit (limit / demand for stroke_min); a drive's check meets "
              f"the margin when ratio × {1 + margin:g} ≤ 1, the stroke and cond(J) when "
              "ratio ≤ 1. Per motion: scene_checks.csv."]
    return lines


def _first_mode_section(motions: Sequence[Motion],
                        first_mode: Sequence[Resonance | None]) -> list[str]:
    """Each motion against the scene's first mode, with its [stiffness] (else nothing)."""
    found = [(m, r) for m, r in zip(motions, first_mode) if r is not None]
    if not found:
        return []
    reached = "reached" if any(r.reaches for _, r in found) else "not reached"
    return ["", f"## First mode ([stiffness]): {reached}", "",
            *(f"- {md_text(r.line(m.name))}" for m, r in found)]


def _catalogue_section(sweep: CatalogueSweep, ranked: Sequence[CandidateResult],
                       margin: float) -> list[str]:
    good = [r for r in ranked if r.qualifies(margin)]
    failed = [r for r in ranked if r.error is not None]
    cost = "price" if ranked and ranked[0].drive.price is not None else "mass (kg)"
    lines = [f"## Catalogue: {len(ranked)} drives, {len(good)} meet every motion with a "
             f"{100 * margin:g} % margin", "",
             f"Evaluated on {sweep.workers} Dask workers, one task per drive; each drive "
             "replaces the scene's [drive] (its rotor inertia changes the rack force). Ranked "
             f"by {cost}: the qualifying drives first.", ""]
    if good:
        lines += [f"**Choice: {md_text(good[0].drive.name)}** ({cost} {good[0].drive.cost:g}).", ""]
    else:
        lines += ["**No drive of the catalogue meets every motion with the margin.**", ""]
    lines += ["| rank | drive | ζ | r (m) | I (kg m²) | " + cost + " | peak torque | RMS torque "
              "| speed | worst motion | qualifies |", "|---" * 11 + "|"]
    for rank, r in enumerate(ranked, start=1):
        d = r.drive
        if r.error is not None:
            continue
        ratios = [r.worst(c) for c in CANDIDATE_CHECKS]
        worst = max(ratios, key=lambda cm: cm[0].ratio)
        lines.append(f"| {rank} | {md_text(d.name)} | {d.gear_ratio:g} | {d.pinion_radius:g} | "
                     f"{d.rotor_inertia:g} | {d.cost:g} | "
                     + " | ".join(f"{c.ratio:.3f}" for c, _ in ratios)
                     + f" | {md_text(worst[1])} | {'yes' if r.qualifies(margin) else 'no'} |")
    lines += ["", "Ratios (worst motion): peak |torque| / peak_torque, the worst leg's RMS "
              "torque / continuous_torque, peak |motor speed| / max_speed."]
    for r in failed:
        lines.append(f"- {md_text(r.drive.name)}: not evaluated: {md_text(r.error)}")
    return lines
