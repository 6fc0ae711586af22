"""What `stewart-sim case SCENE [--duration S]` reports (stewart_sim.commands.case): a shipped
stiff or extreme scene's [case] outcome (stewart_sim.studies.cases.outcome.run_case) against the one
it expects.

Exit status: 0 when the outcome is the expected one (also when the expected outcome is an
error, e.g. StrokeLimitError: the case shows that the error is caught), 1 when it is not (a
mismatch is a finding about the simulator, not a user input error), 2 for bad input (a scene
without a [case] table, a bad --duration) as for every command.
"""
from __future__ import annotations

import math

import numpy as np

from stewart_sim.scene.case_config import Case
from stewart_sim.studies.cases.outcome import CaseResult

MISMATCH_STATUS = 1


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

