"""Files of `stewart-sim accuracy`: the work-precision tables (CSV), the log-log plot and
summary.md, from stewart_sim.studies.accuracy.study's results."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stewart_fmu import io
from stewart_fmu.integrators import FIXED_STEP, INTEGRATORS
from stewart_sim.shell.markdown import md_text
from stewart_sim.shell.plots import save_figure
from stewart_sim.studies.accuracy.study import (
    ATOL_RATIO,
    CLOSED_LOOP_REFERENCE,
    ORDER_FLOOR,
    PERTURBATION,
    REFERENCE,
    REFERENCE_TOLERANCE,
    SECOND,
    AccuracyResults,
    cheapest,
    closed_loop_order,
)

ACCURACY_FILES = ("open_loop.csv", "closed_loop.csv", "work_precision.png", "summary.md")
TARGETS = (1e-3, 1e-6, 1e-9)        # relative pose errors the summary names the cheapest for
MARKERS = dict(zip(INTEGRATORS, "os^vDPX*"))


def write_accuracy_report(res: AccuracyResults, out: Path) -> list[Path]:
    """Write ACCURACY_FILES (closed_loop.csv only with a closed loop) into out."""
    paths = [io.write_csv(out / "open_loop.csv", res.open_loop)]
    if res.closed_loop is not None:
        paths.append(io.write_csv(out / "closed_loop.csv", res.closed_loop))
    paths.append(save_figure(work_precision_figure(res), out / "work_precision.png"))
    paths.append(io.write_text(out / "summary.md", summary_text(res)))
    return paths


def setting(row) -> str:
    """'h = 12.5 ms' for a fixed-step row, 'rtol = 1e-07' for an adaptive one."""
    return (f"h = {row['step'] * 1e3:.4g} ms" if row["method"] in FIXED_STEP
            else f"rtol = {row['rtol']:.0e}")


def work_precision_figure(res: AccuracyResults) -> Figure:
    """Open loop: pose error against run time per integrator, fixed-step errors against the
    step with the fitted orders; closed loop: error against run time per communication step."""
    panels = 3 if res.closed_loop is not None else 2
    fig = Figure(figsize=(5.2 * panels, 4.6), layout="constrained")
    axes = fig.subplots(1, panels)
    rows = res.open_loop
    ax = axes[0]
    for method in INTEGRATORS:
        r = rows[(rows["method"] == method) & (rows["outcome"] == "ok")]  # coarse to fine
        ax.loglog(r["run_time"], np.maximum(r["pose_error"], 1e-17), marker=MARKERS[method],
                  ms=4, lw=1, label=method)
    _floor(ax, res.floor)
    ax.set(xlabel="run time (s)", ylabel="relative pose error (-)",
           title=f"open loop, {res.case.times[-1]:g} s, forces held {res.case.comm_step * 1e3:g} ms")
    ax.legend(fontsize="small", ncol=2)
    ax = axes[1]
    for order in res.orders:
        r = np.sort(rows[(rows["method"] == order.method) & (rows["outcome"] == "ok")],
                    order="step")
        ax.loglog(r["step"], np.maximum(r["pose_error"], 1e-17), marker=MARKERS[order.method],
                  label=f"{order.method}: order {order.measured:.2f} (theory {order.theory})"
                  if np.isfinite(order.measured) else f"{order.method}: order not measurable")
    _floor(ax, res.floor)
    ax.set(xlabel="internal step h (s)", ylabel="relative pose error (-)",
           title="fixed-step methods: convergence")
    ax.legend(fontsize="small")
    if res.closed_loop is not None:
        ax = axes[2]
        c = res.closed_loop[res.closed_loop["stable"] > 0]
        ax.loglog(c["run_time"], c["pose_error"], "o-", label="pose vs reference loop")
        for r in c:
            ax.annotate(f"{r['step'] * 1e3:g} ms", (r["run_time"], r["pose_error"]),
                        fontsize=8, xytext=(4, 4), textcoords="offset points")
        ax.set(xlabel="run time (s)", ylabel="relative pose error (-)",
               title=f"closed loop, {res.closed_loop_duration:g} s: communication step")
        ax.legend(fontsize="small")
    for a in axes:
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{res.scene}: error against run time")
    return fig


def _floor(ax, floor: float) -> None:
    ax.axhline(floor, color="grey", ls="--", lw=0.8)
    ax.text(ax.get_xlim()[0], floor, " reference resolved to here", fontsize=7, va="bottom",
            color="grey")


def summary_text(res: AccuracyResults) -> str:
    """summary.md: the case, the reference and its check, the tables, orders, headlines."""
    ref, case = res.reference, res.case
    pose_agree, force_agree = ref.agreement
    resolved = max(pose_agree, force_agree) <= REFERENCE_TOLERANCE
    lines = [
        f"# Accuracy against run time: {md_text(res.scene)}", "",
        "## Open loop: the integrators",
        "",
        f"From rest at home, {case.times[-1]:g} s of motion under the rack forces of the "
        f"demonstration move (inverse dynamics at the middle of each {case.comm_step * 1e3:g} ms "
        f"communication step, held over it) plus a perturbation of {100 * PERTURBATION:g} % of "
        f"their peak ({ref.force_scale:.4g} N), through the Plant's do_step. Range of the motion: "
        f"{ref.ranges[0]:.4g} m, {ref.ranges[1]:.4g} rad.",
        "",
        "Errors are the max over time: pose error relative to the motion's range (translation "
        "and rotation separately, the larger), force error over every part of the rack force's "
        "breakdown (`Plant.outputs.parts`) relative to the peak force. Run time: "
        f"time.perf_counter around the whole run, best of {res.repeats} or more (short runs "
        "repeat for 0.2 s), after one untimed warm-up run of the same setting (discarded, so "
        "one-time costs never count, also with --repeats 1). Adaptive methods: "
        f"atol = {ATOL_RATIO:g} rtol, steps up to the communication step.",
        "",
        f"Reference: {REFERENCE.method} at rtol {REFERENCE.rtol:g} (atol {REFERENCE.atol:g}), "
        f"{ref.run_time:.3g} s; checked by {SECOND.method} at rtol {SECOND.rtol:g} (atol "
        f"{SECOND.atol:g}): they agree to {pose_agree:.2g} in pose and {force_agree:.2g} in "
        f"force, " + ("within the stated tolerance" if resolved else "NOT within the stated "
                      "tolerance") + f" {REFERENCE_TOLERANCE:g}. Errors below {res.floor:.2g} "
        "are not resolved.",
    ]
    coulomb = res.case.model.friction.coulomb_legs.max() if res.case.model.friction is not None else 0.0
    if not resolved and coulomb:
        lines += ["", f"Why: Coulomb friction (up to {coulomb:g} N, "
                  "`sign(ldot)`) makes the right-hand side discontinuous wherever a leg stops or "
                  "reverses: fixed-step methods lose their order across those points, "
                  "error-controlled ones pay in rejected steps, and implicit ones (Newton "
                  "iterations across the switch) may settle on another motion; below the "
                  "agreement above, errors are consistency among methods, not checked errors."]
    lines += ["", "| method | setting | pose error | force error | run time (ms) | x real time |",
              "|---|---|---|---|---|---|"]
    span = case.times[-1]
    for r in res.open_loop:
        if r["outcome"] != "ok":   # caught by the plant's checks (stability, stroke)
            lines.append(f"| {r['method']} | {setting(r)} | {r['outcome']} | - | - | - |")
            continue
        lines.append(f"| {r['method']} | {setting(r)} | {r['pose_error']:.2e} | "
                     f"{r['force_error']:.2e} | {r['run_time'] * 1e3:.3g} | "
                     f"{span / r['run_time']:,.0f} |")
    lines += ["", "Measured convergence order of the fixed-step methods (slope of log error "
              f"against log h over the finest errors above {ORDER_FLOOR:g}x the resolved floor):",
              "", "| method | theory | measured (pose) | steps of the fit (ms) | measured (force) |",
              "|---|---|---|---|---|"]
    for o, f in zip(res.orders, res.force_orders):
        lines.append(f"| {o.method} | {o.theory} | {_order(o.measured)} | "
                     f"{', '.join(f'{h * 1e3:.4g}' for h in o.steps)} | {_order(f.measured)} |")
    lines += ["", "Cheapest setting for a relative pose error target:", "",
              "| target | integrator | setting | run time (ms) | pose error |", "|---|---|---|---|---|"]
    for target in TARGETS:
        r = cheapest(res.open_loop, target) if target >= res.floor else None
        lines.append(f"| {target:g} | " + ("not reached (or below the resolved floor) | | | |"
                     if r is None else f"{r['method']} | {setting(r)} | "
                     f"{r['run_time'] * 1e3:.3g} | {r['pose_error']:.2e} |"))
    lines += _closed_loop_lines(res)
    return "\n".join(lines) + "\n"


def _order(value: float) -> str:
    return f"{value:.3f}" if np.isfinite(value) else "not measurable (too few errors above the floor)"


def _closed_loop_lines(res: AccuracyResults) -> list[str]:
    if res.closed_loop is None:
        return ["", "## Closed loop", "", "Skipped: the scene has no [controller] table, or "
                "--no-closed-loop was given."]
    lines = [
        "", "## Closed loop: the communication step", "",
        f"`stewart-sim run`'s reference (quintic move out and back, {res.closed_loop_duration:g} s) "
        "tracked by the scene's per-axis controllers around the in-process plant "
        "(controller.cosim.run_closed_loop). The controller runs at the communication rate, so "
        "the step changes the sampled controller as well as the plant's input hold. Pose error "
        "(relative to the motion's range, at the coarse step's samples) against the reference "
        f"loop: the loop at {CLOSED_LOOP_REFERENCE * 1e6:g} us Richardson-extrapolated with the "
        "loop at twice that step (2 q(h) - q(2h): the loop converges with order one in its "
        f"step, measured {closed_loop_order(res.closed_loop):.2f} here); the same extrapolation "
        f"at half the step differs from it by {res.closed_loop_check:.2g}. Tracking error: the "
        "largest translational pose error against the reference trajectory, relative to the "
        "range. Run time: the compiled loop's wall time, best of "
        f"{res.repeats} or more, after one untimed warm-up loop at the same step.",
        "", "| step (ms) | pose error vs reference loop | tracking error | run time (ms) | "
        "x real time |", "|---|---|---|---|---|"]
    for r in res.closed_loop:
        if r["stable"] > 0:
            lines.append(f"| {r['step'] * 1e3:g} | {r['pose_error']:.2e} | "
                         f"{r['tracking_error']:.2e} | {r['run_time'] * 1e3:.3g} | "
                         f"{res.closed_loop_duration / r['run_time']:,.0f} |")
        else:
            lines.append(f"| {r['step'] * 1e3:g} | unstable: the sampled loop is refused | | | |")
    return lines
