"""`stewart-sim case SCENE [--duration S]`: run a shipped stiff or extreme scene's [case]
(stewart_sim.cases.run_case) and report its outcome against the one the case expects.

Exit status: 0 when the outcome is the expected one (also when the expected outcome is an
error, e.g. StrokeLimitError: the case shows that the error is caught), 1 when it is not (a
mismatch is a finding about the simulator, not a user input error), 2 for bad input (a scene
without a [case] table, a bad --duration) as for every command.
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from stewart_fmu.scene import load_scene
from stewart_sim.argtypes import positive_seconds
from stewart_sim.cases import Case, CaseResult, case_of, run_case

MISMATCH_STATUS = 1


def add_parser(sub) -> None:
    """Register `case` on the CLI's subparsers."""
    p = sub.add_parser(
        "case", help="run a stiff or extreme scene's [case] and check its outcome",
        description="Run the [case] of a scene (scenes/stiff, scenes/extreme: a hold, a move or "
                    "a closed loop) and report its outcome (ok, or the typed error that ended "
                    "it, with where) against the outcome the case expects, with its figures. "
                    "Exit status 0 when they agree, 1 when they do not.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [case] table")
    p.add_argument("--duration", type=positive_seconds, default=None, metavar="S",
                   help="run this long instead of the case's duration (e.g. a short look at "
                        "the hour-long hold)")
    p.set_defaults(run=cmd)


def cmd(args: argparse.Namespace) -> int:
    """Run the case, print the report; exit status 1 (SystemExit) on a mismatch, else 0."""
    model = load_scene(args.scene)
    case = case_of(model)
    result = run_case(model, duration=args.duration)
    print(report(model.name, case, result, args.duration))
    if not agrees(case, result):
        raise SystemExit(MISMATCH_STATUS)
    return 0


def agrees(case: Case, result: CaseResult) -> bool:
    """The outcome is the one the case expects."""
    return result.outcome == case.expect


def report(name: str, case: Case, result: CaseResult, duration: float | None = None) -> str:
    """The lines printed: what ran, expected and actual outcome, the figures."""
    ran = case.duration if duration is None else duration
    lines = [f"case '{name}' ({case.kind}): {case.description}",
             f"  motion: {case.motion}, {ran:g} s"
             + (f" (of the case's {case.duration:g} s)" if duration is not None else "")
             + f", step {case.step:g} s",
             f"  expected: {case.expect}",
             f"  outcome:  {result.outcome}"]
    if result.error is not None:   # its message names the sample and time when known
        lines.append(f"  error: {str(result.error).splitlines()[0] or type(result.error).__name__}")
        if result.time is not None and "t = " not in str(result.error):
            lines.append(f"  at t = {result.time:.6g} s")
    if not math.isnan(result.cond_max):
        lines.append(f"  cond(J) max: {result.cond_max:.4g}")
    if result.forces is not None and result.forces.size:
        lines.append(f"  rack forces: |sigma| max {np.max(np.abs(result.forces)):.4g} N")
    if result.states is not None and result.states.size and case.motion == "hold":
        q = result.states[-1, :6]
        lines.append("  final pose: (" + ", ".join(f"{x:.6g}" for x in q) + ")")
        drift = np.max(np.abs(result.states[:, :3] - result.states[0, :3]))
        lines.append(f"  largest position change from the start: {drift:.3e} m")
    summary = result.extra.get("summary")
    if summary is not None:
        lines.append(f"  closed loop: {_summary_line(summary)}")
    if result.evaluations:
        lines.append(f"  right-hand-side evaluations: {result.evaluations}")
    lines.append(f"  wall time: {result.wall:.3g} s")
    lines.append(f"  verdict: {'as expected' if agrees(case, result) else 'NOT as expected'}")
    return "\n".join(lines)


def _summary_line(summary) -> str:
    """A closed-loop summary's tracking figures, whatever its shape (dataclass or dict)."""
    items = summary if isinstance(summary, dict) else getattr(summary, "__dict__", {})
    figures = [f"{k} {v:.4g}" for k, v in items.items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)][:6]
    return ", ".join(figures) or str(summary)

