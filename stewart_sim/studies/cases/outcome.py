"""The stiff and extreme cases shipped in scenes/stiff and scenes/extreme, and their outcomes.

A case scene carries a [case] table (stewart_sim.scene.case_config: its keys, read once with
the scene).

Motions: "hold" simulates the plant forward (plant.Plant) under constant rack forces;
"accelerate" and "ramp" check every pose and compute the inverse dynamics (an error stops at
the first bad sample, naming its index and time); "closed_loop" runs the scene's controllers
on the `stewart-sim run` reference. Each run returns a CaseResult: "ok" with the figures
(cond(J), forces, final state), or the typed error that ended it.
"""
from __future__ import annotations

import time as wallclock
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from controller.config import ControllerConfig
from controller.cosim import run_closed_loop
from controller.moves import run_reference
from controller.plants import InProcessPlant, PlantStepError
from controller.trajectory import Trajectory, constant_acceleration, quintic
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import IntegrationError, KinematicsError, StewartError
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.kinematics import check_poses
from stewart_fmu.model import Model
from stewart_fmu.plant import Plant, StepRejected
from stewart_sim.scene.case_config import Case


@dataclass
class CaseResult:
    """How a case ended: outcome "ok", "unstable" (IntegrationError), or the error's class
    name; where (time, sample index), the worst cond(J) seen and the figures of the run."""

    outcome: str
    error: StewartError | None = None
    time: float | None = None
    index: int | None = None
    cond_max: float = float("nan")
    forces: np.ndarray | None = None      # inverse-dynamics motions: (N, 6) rack forces
    states: np.ndarray | None = None      # hold: (steps + 1, len(y)) plant states
    evaluations: int = 0                  # right-hand-side evaluations (hold, closed loop)
    wall: float = 0.0                     # s
    extra: dict[str, Any] = field(default_factory=dict)


def case_trajectory(model: Model, case: Case, duration: float | None = None) -> Trajectory:
    """The sampled motion of an "accelerate" or "ramp" case (rate 1 / step)."""
    duration = case.duration if duration is None else duration
    if case.motion == "accelerate":
        return constant_acceleration(model.home, case.acceleration, duration, 1.0 / case.step)
    return quintic(model.home, case.target, 1.0 / case.step, duration)


def run_case(model: Model, case: Case, controller: ControllerConfig | None,
             options: IntegratorOptions | None = None,
             duration: float | None = None) -> CaseResult:
    """Run the scene's case (its [case] table: `case`; its [controller] table: `controller`,
    needed by a closed-loop case), optionally shorter and with given plant integrator options."""
    start = wallclock.perf_counter()
    if case.motion == "hold":
        result = simulate_hold(model, case, options, duration)
    elif case.motion == "closed_loop":
        result = _closed_loop(model, case, controller, options, duration)
    else:
        result = _inverse(model, case, duration)
    result.wall = wallclock.perf_counter() - start
    return result


def hold_forces(model: Model, case: Case) -> np.ndarray:
    """force_scale x the rack forces that hold the platform at rest at home."""
    return case.force_scale * inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))


def started_plant(model: Model, case: Case, options: IntegratorOptions | None) -> Plant:
    """A Plant at home with the case's start rates, holding its rack forces from the start."""
    plant = Plant(model, options)
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    plant.set_initial(model.home, case.start_rates)
    plant.set_force(hold_forces(model, case))
    plant.exit_initialization_mode()
    return plant


def simulate_hold(model: Model, case: Case, options: IntegratorOptions | None = None,
                  duration: float | None = None) -> CaseResult:
    """Step the plant under the held forces; record every state, stop at the first error."""
    plant = started_plant(model, case, options)
    steps = int(round((case.duration if duration is None else duration) / case.step))
    states = np.empty((steps + 1, model.state_size))
    states[0] = plant.get_state().y
    for k in range(steps):
        try:
            plant.do_step(plant.time, case.step)
        except (IntegrationError, StepRejected) as exc:
            outcome = "unstable" if isinstance(exc, IntegrationError) else type(exc).__name__
            return CaseResult(outcome, exc, plant.time, k, states=states[:k + 1],
                              evaluations=plant.evaluations)
        states[k + 1] = plant.get_state().y
    return CaseResult("ok", states=states, evaluations=plant.evaluations,
                      cond_max=float(plant.outputs.cond))


def _inverse(model: Model, case: Case, duration: float | None) -> CaseResult:
    """Check every pose, then the rack forces; a bad sample ends the case with its place."""
    traj = case_trajectory(model, case, duration)
    try:
        kin = check_poses(model, traj.q, traj.t)
    except KinematicsError as exc:
        return CaseResult(type(exc).__name__, exc, exc.time, exc.index)
    forces = inverse_dynamics(model, traj.q, traj.qd, traj.qdd)
    return CaseResult("ok", cond_max=float(np.max(kin.cond)), forces=forces,
                      extra={"trajectory": traj})


def _closed_loop(model: Model, case: Case, config: ControllerConfig | None,
                 options: IntegratorOptions | None, duration: float | None) -> CaseResult:
    """The scene's controllers on the `run` reference, through the in-process plant."""
    if config is None:
        raise StewartError("case: motion 'closed_loop' needs the scene's [controller] table")
    traj = run_reference(model, config, case.duration if duration is None else duration)
    port = InProcessPlant(model, options)
    try:
        result = run_closed_loop(model, config, traj, plant=port)
    except IntegrationError as exc:
        return CaseResult("unstable", exc, exc.time, evaluations=port.plant.evaluations)
    except PlantStepError as exc:
        return CaseResult("PlantStepError", exc, evaluations=port.plant.evaluations)
    table = result.table
    legs = np.column_stack([table[f"l{i}"] for i in range(1, 7)])
    return CaseResult("ok", states=legs, evaluations=port.plant.evaluations,
                      extra={"summary": result.summary, "gains": result.gains})
