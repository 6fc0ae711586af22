"""The files of `stewart-sim cue`: the platform trajectory (the `inverse` command's input
format, so every other command takes it), forces and drives, the perception table, summary.md
and the figures, written all or nothing.

    trajectory.csv          t, x..thz, dx..dthz, ddx..ddthz of the first mode's cue
    trajectory_<mode>.csv   the same for every further mode (--compare)
    forces.csv              t, sigma1..6 (rack force incl. the drive term, N), cond,
                            current1..6 (A), voltage1..6 (V) when the scene has its drives
    perception.csv          t, per axis: vehicle, delivered, perceived vehicle, perceived
                            delivered, false cue (0/1); f in m/s^2, w in rad/s; then
                            head_x, head_y, head_z: where the delivered motion is felt (m,
                            platform frame, the scene's [cueing] head; the same every row)
    tracking.csv            the closed loop's table (as `run` writes it), with --track
    summary.md              the figures (see summary_markdown)
    cue_*.png               the figures (cueing/figures.py)

and what the terminal gets: cue_view (the 3D view), verdict (one line per mode).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu import io
from stewart_fmu.frames import table_from_platform
from stewart_fmu.model import Model
from stewart_sim.shell.markdown import md_text
from stewart_sim.shell.outputs import result_set
from stewart_sim.view.data import view_data
from stewart_sim.view.sources import run_table_view

from .feasibility import Feasibility
from .figures import FIGURES
from .study import CueRun, CueStudy
from .vestibular import AXES, ROTATION_AXES, Perception

RACK = "rack force σ (inverse dynamics of the cue, incl. drive)"


def write_cue_report(study: CueStudy, out: Path, title: str,
                     extra: Callable[[Path], list[str]] | None = None, model: Model | None = None,
                     frame: str = "platform") -> list[Path]:
    """Every file of the study into `out`, all or nothing; `extra(stage)` may add files (the
    3D view) and returns their names. The trajectories and tracking.csv's poses are written
    in `frame` of `model`'s [frames] (said in summary.md)."""
    first = study.runs[0]

    def framed(table: np.ndarray) -> np.ndarray:
        return table if frame == "platform" else table_from_platform(model, table, frame)

    with result_set(out) as stage:
        names = ["trajectory.csv", "forces.csv", "perception.csv", "summary.md"]
        io.write_csv(stage / "trajectory.csv", framed(trajectory_table(first)))
        for run in study.runs[1:]:
            name = f"trajectory_{run.mode}.csv"
            io.write_csv(stage / name, framed(trajectory_table(run)))
            names.append(name)
        io.write_csv(stage / "forces.csv", forces_table(first.feasibility))
        io.write_csv(stage / "perception.csv", perception_table(first.perception))
        if study.tracking is not None:
            io.write_csv(stage / "tracking.csv", framed(study.tracking.table))
            names.append("tracking.csv")
        from stewart_sim.shell.plots import save_figure   # matplotlib: only when plotting
        for name, make in FIGURES:
            fig = make(study, title)
            if fig is not None:
                save_figure(fig, stage / name)
                names.append(name)
        if extra is not None:
            names += extra(stage)
        io.write_text(stage / "summary.md", summary_markdown(study, title, frame))
    return [out / n for n in names]


def trajectory_table(run: CueRun) -> np.ndarray:
    """The cue in the contract's trajectory columns."""
    c = run.cue
    return io.trajectory_table(c.t, c.q, c.qd, c.qdd)


def forces_table(f: Feasibility) -> np.ndarray:
    """t, sigma1..6, cond, then current1..6 and voltage1..6 when the drives were computed."""
    cols = {"t": f.t, **{f"sigma{i + 1}": f.sigma[:, i] for i in range(6)}, "cond": f.cond}
    for name, values in (("current", f.current), ("voltage", f.voltage)):
        if values is not None:
            cols.update({f"{name}{i + 1}": values[:, i] for i in range(6)})
    return io.named_array(cols)


def perception_table(p: Perception) -> np.ndarray:
    """t, then for f (x, y, z) and w (roll, pitch, yaw): vehicle, delivered, the two perceived
    signals and the false-cue flag; then the head (m, platform frame) the delivered motion is
    felt at, in every row (a CSV has no other place for it)."""
    cols = {"t": p.t}
    for prefix, axes, sig in (("f", AXES, "f"), ("w", ROTATION_AXES, "w")):
        for k, axis in enumerate(axes):
            base = f"{prefix}{axis}"
            cols[f"{base}_vehicle"] = getattr(p, f"vehicle_{sig}")[:, k]
            cols[f"{base}_delivered"] = getattr(p, f"delivered_{sig}")[:, k]
            cols[f"{base}_perceived_vehicle"] = getattr(p, f"perceived_vehicle_{sig}")[:, k]
            cols[f"{base}_perceived_delivered"] = getattr(p, f"perceived_delivered_{sig}")[:, k]
            cols[f"{base}_false_cue"] = getattr(p, f"false_cue_{sig}")[:, k].astype(float)
    for k, axis in enumerate(AXES):
        cols[f"head_{axis}"] = np.full(p.t.size, p.head[k])
    return io.named_array(cols)


# --- summary.md --------------------------------------------------------------------------------

def summary_markdown(study: CueStudy, title: str, frame: str = "platform") -> str:
    """Perception error per axis and mode, false-cue time, workspace, limit margins, every
    violation with its time and leg, the closed loop's tracking if run; the frame of the
    written trajectories."""
    m = study.motion
    lines = [f"# {md_text(title)}", "",
             f"Vehicle motion: {m.t.size} samples over {m.t[-1] - m.t[0]:g} s "
             f"({(m.t.size - 1) / (m.t[-1] - m.t[0]):g} Hz). Cue modes: "
             + ", ".join(f"{r.mode} ({r.seconds:.3f} s to compute)" for r in study.runs)
             + f"; the written trajectory is the {study.runs[0].mode} cue's, in the {frame} "
             "frame (the workspace and margins below: C's pose).", ""]
    lines += _solver_lines(study.runs)
    lines += _first_mode_lines(study)
    lines += _perception_section(study.runs)
    lines += _workspace_section(study.runs)
    lines += _margins_section(study.runs)
    for run in study.runs:
        lines += _violations_section(run)
        lines += _live_section(run)
    lines += _tracking_section(study)
    return "\n".join(lines) + "\n"


def _solver_lines(runs: tuple[CueRun, ...]) -> list[str]:
    """The optimal mode's QP record: how many steps were solved, polished, its time."""
    lines = []
    for r in runs:
        d = r.solver
        if d is None:
            continue
        solved = sum(s == "solved" for s in d.status)
        lines.append(f"Optimal cueing: {len(d.status)} MPC steps ({d.variables} variables, "
                     f"{d.constraints} constraints, limits {', '.join(d.limits)}): {solved} "
                     f"solved, {int(np.sum(d.polished))} polished; OSQP "
                     f"{float(np.sum(d.solve_time)):.2f} s of {d.wall_time:.2f} s; stroke slack "
                     f"up to {1e3 * float(np.max(d.slack)):.2f} mm.")
    return lines + ([""] if lines else [])


def first_mode_warnings(study: CueStudy) -> list[str]:
    """The line of each run whose cue reaches the scene's first mode (resonance.py)."""
    return [r.line(f"the {run.mode} cue") for run, r in zip(study.runs, study.resonance)
            if r is not None and r.reaches]


def _first_mode_lines(study: CueStudy) -> list[str]:
    """Each run's cue against the first mode, with the scene's [stiffness] (else nothing)."""
    found = [(run, r) for run, r in zip(study.runs, study.resonance) if r is not None]
    if not found:
        return []
    reached = "reached" if any(r.reaches for _, r in found) else "not reached"
    return ([f"## First mode ([stiffness]): {reached}", ""]
            + [f"- {md_text(r.line(f'the {run.mode} cue'))}" for run, r in found] + [""])


def _perception_section(runs: tuple[CueRun, ...]) -> list[str]:
    p0 = runs[0].perception
    head = ("| mode | " + " | ".join(f"f{a} (m/s²)" for a in AXES) + " | "
            + " | ".join(f"ω {a} (deg/s)" for a in ROTATION_AXES) + " |")
    lines = ["## Perceived-motion error (RMS of perceived delivered - perceived vehicle)", "",
             _where_line(p0), "", head, "|" + "---|" * 7]
    for r in runs:
        p = r.perception
        lines.append(f"| {r.mode} | " + " | ".join(f"{v:.3f}" for v in p.rms_f) + " | "
                     + " | ".join(f"{np.degrees(v):.3f}" for v in p.rms_w) + " |")
    lines += ["", "False cues (time the delivered motion is perceived above threshold with the "
              "wrong sign; thresholds "
              + ", ".join(f"f{a} {v:g} m/s²" for a, v in zip(AXES, p0.threshold_f)) + ", "
              + ", ".join(f"{a} {np.degrees(v):.2g} deg/s"
                          for a, v in zip(ROTATION_AXES, p0.threshold_w)) + "):", "",
              "| mode | " + " | ".join(f"f{a} (s)" for a in AXES) + " | "
              + " | ".join(f"ω {a} (s)" for a in ROTATION_AXES) + " |", "|" + "---|" * 7]
    for r in runs:
        p = r.perception
        lines.append(f"| {r.mode} | " + " | ".join(f"{v:.2f}" for v in p.false_cue_time_f)
                     + " | " + " | ".join(f"{v:.2f}" for v in p.false_cue_time_w) + " |")
    return lines + [""]


def _where_line(p: Perception) -> str:
    """Where the delivered motion is felt: the platform's origin or the head."""
    if not np.any(p.head):
        return ("Perceived at the platform's origin ([cueing] head = [0, 0, 0]): the delivered "
                "specific force is that of the platform frame's origin.")
    return ("Perceived at the head, [" + ", ".join(f"{v:g}" for v in p.head) + "] m from the "
            "platform's origin in the platform frame ([cueing] head): the delivered specific "
            "force includes the rotation's tangential and centripetal accelerations there.")


def _workspace_section(runs: tuple[CueRun, ...]) -> list[str]:
    names = ("x (m)", "y (m)", "z (m)", "θx (deg)", "θy (deg)", "θz (deg)")
    scale = np.array([1, 1, 1, *(np.degrees(1.0),) * 3])
    lines = ["## Workspace used (cue pose, min .. max)", "",
             "| mode | " + " | ".join(names) + " |", "|" + "---|" * 7]
    for r in runs:
        p = r.perception
        lo, hi = p.workspace_min * scale, p.workspace_max * scale
        lines.append(f"| {r.mode} | " + " | ".join(f"{a:.3f} .. {b:.3f}" for a, b in zip(lo, hi))
                     + " |")
    return lines + [""]


def _margins_section(runs: tuple[CueRun, ...]) -> list[str]:
    lines = ["## Limits (worst sample of the cue)", "",
             "ratio: value / limit (for stroke_min, limit / value); 100 % or more is past the "
             "limit.", "",
             "| mode | quantity | worst | limit | ratio | at t (s) | leg |", "|" + "---|" * 7]
    for r in runs:
        for mg in r.feasibility.margins:
            leg = "-" if mg.leg is None else str(mg.leg)
            lines.append(f"| {r.mode} | {mg.quantity} | {_quantity(mg.value, mg.unit)} | "
                         f"{_quantity(mg.limit, mg.unit)} | {100 * mg.ratio:.0f} % | {mg.t:.3f} "
                         f"| {leg} |")
        if r.feasibility.drive_note:
            lines.append(f"| {r.mode} | current, voltage | - | - | - | - | "
                         f"{r.feasibility.drive_note} |")
    return lines + [""]


def _quantity(value: float, unit: str) -> str:
    """A value with its unit; dimensionless (cond) without one."""
    return f"{value:.4g}" if unit in ("", "1", "-") else f"{value:.4g} {unit}"


def _violations_section(run: CueRun) -> list[str]:
    v = run.feasibility.violations
    if not v:
        return [f"## Violations ({run.mode}): none", ""]
    lines = [f"## Violations ({run.mode}): {len(v)} (first sample of each crossing)", "",
             "| t (s) | sample | leg | quantity | value | limit | lasted (s) |", "|" + "---|" * 7]
    for x in v:
        leg = "-" if x.leg is None else str(x.leg)
        lines.append(f"| {x.t:.3f} | {x.sample} | {leg} | {x.quantity} | "
                     f"{_quantity(x.value, x.unit)} | {_quantity(x.limit, x.unit)} | "
                     f"{x.duration:.3f} |")
    return lines + [""]


def live_text(live: dict) -> str:
    """The live envelope's interventions in words: samples limited, per limit."""
    hits = ", ".join(f"{k} {v}" for k, v in live["per_limit"].items() if v)
    return f"{live['limited']} of {live['samples']} samples limited ({hits})"


def _live_section(run: CueRun) -> list[str]:
    """What cue-live's envelope does with the motion on a simulated clock (live.preflight):
    the same limits, less the same margins (controller.capability)."""
    if run.live is None:
        return []
    words = ("every sample passed unchanged" if not run.live["limited"]
             else live_text(run.live))
    return [f"## cue-live ({run.mode}, simulated clock): {words}", ""]


def _tracking_section(study: CueStudy) -> list[str]:
    if study.tracking is None:
        return ([f"## Closed loop: not run ({study.tracking_note})", ""]
                if study.tracking_note else [])
    s = study.tracking.summary
    c = study.tracking.config
    return ["## Closed loop tracking the cue (the scene's [controller], as `run`)", "",
            f"At {c.rate:g} Hz, feedforward {c.feedforward}: pose RMS error "
            + ", ".join(f"{n} {v:.3g}" for n, v in zip(("x", "y", "z"), s.pose_rms[:3])) + " m, "
            + ", ".join(f"{n} {np.degrees(v):.3g}" for n, v in zip(("θx", "θy", "θz"),
                                                                   s.pose_rms[3:]))
            + " deg; leg RMS error up to " + f"{1e3 * float(np.max(s.leg_rms)):.3g} mm "
            f"(max {1e3 * float(np.max(s.leg_max)):.3g} mm); peak current "
            f"{float(np.max(s.current_max)):.3g} A of {c.motor.current_limit:g} A; RMS voltage up "
            f"to {float(np.max(s.voltage_rms)):.3g} V of {c.motor.voltage_limit:g} V; an axis "
            f"saturated for {s.saturated_time:.3g} s.", ""]


def cue_view(study: CueStudy, title: str, controller: ControllerConfig | None):
    """The 3D view: the closed loop with the cue as its ghost when it ran, else the cue with
    the rack forces of its inverse dynamics and the vehicle's and the delivered specific force
    at the head as arrows (`controller`: the scene's parsed [controller]). The closed loop's
    view has no arrows: its samples are the controller's, not the motion's."""
    if study.tracking is not None:
        return run_table_view(study.model, study.tracking.table, controller=controller,
                              title=f"{title}, closed loop", source="tracking.csv")
    run = study.runs[0]
    return view_data(study.model, run.cue.t, run.cue.q, run.feasibility.sigma,
                     controller=controller, force_label=RACK, title=title, source="trajectory.csv",
                     f_vehicle=run.perception.vehicle_f, f_delivered=run.perception.delivered_f)


def verdict(study: CueStudy) -> str:
    """One line per mode: feasible (inside the mechanism's limits and, when preflown, passed
    unchanged by cue-live's envelope) or its first violations and the envelope's
    interventions; the RMS perceived error."""
    lines = []
    for r in study.runs:
        p = r.perception
        rms = (f"RMS perceived error f {', '.join(f'{v:.3g}' for v in p.rms_f)} m/s², "
               f"ω {', '.join(f'{math.degrees(v):.3g}' for v in p.rms_w)} deg/s")
        v = r.feasibility.violations
        live = "" if r.live is None or not r.live["limited"] else \
            f"cue-live's envelope: {live_text(r.live)}; "
        if not v and not live:
            lines.append(f"{r.mode}: inside every limit; {rms}")
        elif not v:
            lines.append(f"{r.mode}: inside the mechanism's limits, not the live margins: "
                         f"{live}{rms}")
        else:
            first = ", ".join(f"{x.quantity} leg {x.leg} at t = {x.t:.3f} s" if x.leg else
                              f"{x.quantity} at t = {x.t:.3f} s" for x in v[:3])
            lines.append(f"{r.mode}: {len(v)} limit crossings (first: {first}); {live}{rms}")
    return "\n".join(lines)
