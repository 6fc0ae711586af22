"""Which integrators cope with the stiff cases, at what cost; drift over a simulated hour.

`integrator_study` runs a stiff scene's case with each integrator and compares it with a tight
Radau reference at the same communication points; `hour_drift` integrates the hour case with
RK4 one second at a time and reports the energy and orientation drift.
"""
from __future__ import annotations

import time as wallclock
from dataclasses import dataclass

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu.energy import DRIVEN, KINETIC, energy_terms, total_energy
from stewart_fmu.errors import StewartError
from stewart_fmu.integrators import IntegratorOptions, advance
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.stability import default_options
from stewart_sim.scene.case_config import Case
from stewart_sim.studies.cases.outcome import CaseResult, hold_forces, run_case, started_plant

REFERENCE = IntegratorOptions("Radau", rtol=1e-10, atol=1e-13)


def study_methods(model: Model) -> list[tuple[str, IntegratorOptions]]:
    """(label, options) of every integrator the study compares, the default first."""
    d = default_options(model)
    rows = [(f"default (rk4, {d.max_step:.3g} s)", d)]
    rows += [(f"rk4 {h:g} s", IntegratorOptions("rk4", max_step=h)) for h in (1e-3, 2.5e-4, 1e-4)]
    rows += [(m, IntegratorOptions(m)) for m in ("dopri5", "RK45", "DOP853", "Radau", "BDF",
                                                  "LSODA")]
    return rows


@dataclass(frozen=True)
class StudyRow:
    """One integrator on one case: outcome, where it failed, error vs reference, cost."""

    label: str
    outcome: str
    time: float | None
    error: float          # max |q - q_ref| (m, rad) or |l - l_ref| (m, closed loop); NaN if failed
    wall: float           # s
    evaluations: int


def integrator_study(model: Model, case: Case, controller: ControllerConfig | None,
                     duration: float | None = None) -> list[StudyRow]:
    """Every study_methods integrator on the scene's case (and [controller], for a closed-loop
    case), against the REFERENCE run."""
    ref = run_case(model, case, controller, REFERENCE, duration)
    rows = []
    for label, options in study_methods(model):
        r = run_case(model, case, controller, options, duration)
        rows.append(StudyRow(label, r.outcome, r.time, _error(r, ref), r.wall, r.evaluations))
    return rows


def _error(r: CaseResult, ref: CaseResult) -> float:
    if r.outcome != "ok" or r.states is None:
        return float("nan")
    return float(np.max(np.abs(r.states[:, :6] - ref.states[:, :6])))


@dataclass(frozen=True)
class Drift:
    """Energy and orientation drift of a long conservative run."""

    duration: float
    step: float
    energy_drift: float        # max |I(t) - I(0)| / max T, I = E - F . d (conserved)
    orientation_drift: float   # rad: final orientation vs a run at a quarter of the step
    wall: float


def hour_drift(model: Model, case: Case, duration: float | None = None,
               step: float = 1e-3) -> Drift:
    """RK4 over the hour case (`case`, its [case] table) at `step`, the invariant sampled every
    second of simulated time."""
    duration = case.duration if duration is None else duration
    start = wallclock.perf_counter()
    q, energy = _conservative_run(model, case, duration, step)
    wall = wallclock.perf_counter() - start
    q_fine, _ = _conservative_run(model, case, duration, step / 4)
    R = (inverse_kinematics(model, q, with_cond=False).rotation.T
         @ inverse_kinematics(model, q_fine, with_cond=False).rotation)
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    angle = float(np.arctan2(np.linalg.norm(axis) / 2.0, (np.trace(R) - 1.0) / 2.0))
    drift = np.max(np.abs(energy[:, 0] - energy[0, 0])) / np.max(energy[:, 1])
    return Drift(duration, step, float(drift), angle, wall)


def _conservative_run(model: Model, case, duration: float, step: float):
    """(final q, per-second (invariant, kinetic)) of the hold under constant forces F."""
    y = started_plant(model, case, default_options(model)).get_state().y
    F = hold_forces(model, case)
    nxt = np.empty_like(y)
    chunk = min(1.0, duration)
    n = int(round(chunk / step))
    rk4 = IntegratorOptions(method="rk4", max_step=chunk / n, max_steps=n)
    out = []
    for _ in range(int(round(duration / chunk))):
        e = energy_terms(model, y)
        out.append((total_energy(e) - float(F @ e[DRIVEN:]), e[KINETIC]))
        status = advance(model.native, rk4, y, nxt, F, chunk)
        if status:
            raise StewartError(f"hour run: the plant refused a step (status {status})")
        y, nxt = nxt, y
    e = energy_terms(model, y)
    out.append((total_energy(e) - float(F @ e[DRIVEN:]), e[KINETIC]))
    return y[:6].copy(), np.array(out)
