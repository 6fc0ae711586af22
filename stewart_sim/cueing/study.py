"""The `cue` study: a vehicle motion -> the platform cue (classical washout, or the optimal
mode) -> what a person perceives of it and whether the mechanism can fly it.

For each cueing mode asked for, the cue (washout.Cue) goes through
- perception (vestibular.perception): the vehicle's and the delivered motion through the
  otolith and canal models, the perceived error, the false cues, the workspace used;
- feasibility (feasibility.feasibility): inverse kinematics (stroke, cond(J)), the scene's
  inverse dynamics (every declared effect) and its drives (current, voltage), every crossing
  reported with its time and leg;
- with the scene's [stiffness], the cue's content against the first mode (resonance.py).
Optionally the scene's closed loop (controller.cosim, as `run`) tracks the first mode's cue,
so the user sees what the drives deliver; the cue is then computed again at the controller's
rate from the vehicle motion interpolated linearly. The washout's linear filters are exact for
that input; the tilt-rate limiter and the Euler-angle integration work per sample, so the two
cues differ slightly at the common samples (on the shipped motions at 100 Hz against 1 kHz:
at most 2.6e-4 m and 4.9e-4 rad).

Studies return data; report.py writes the files.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from controller.cosim import ClosedLoopResult, run_closed_loop
from controller.trajectory import Trajectory
from stewart_fmu.budget import check_count
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model
from stewart_sim.scene.load import Scene

from stewart_sim.scene.cueing_config import CueingConfig
from .feasibility import Feasibility, feasibility
from .motion import VehicleMotion
from .optimal import Diagnostics, optimal_cueing
from .resonance import Resonance, resonance
from .vestibular import Perception, perception
from .washout import Cue, classical_washout

MODES = ("classical", "optimal")


@dataclass(frozen=True)
class CueRun:
    """One cueing mode's cue and what it gives."""

    mode: str
    cue: Cue
    perception: Perception
    feasibility: Feasibility
    seconds: float            # wall time to compute the cue (reported, never judged)
    solver: Diagnostics | None = None   # the optimal mode's QP record
    # what cue-live's envelope does with the motion on a simulated clock (live.preflight:
    # Interventions.as_dict()); None: not flown
    live: dict | None = None


@dataclass(frozen=True)
class CueStudy:
    """Every mode's run on one vehicle motion (runs[0]: the mode whose trajectory is written)
    and, if asked for, the closed loop tracking runs[0]'s cue."""

    model: Model
    config: CueingConfig
    motion: VehicleMotion
    runs: tuple[CueRun, ...]
    tracking: ClosedLoopResult | None = None
    tracking_note: str | None = None     # why the closed loop was not run, if asked for
    # per run: its cue against the first mode (resonance.py); None: no [stiffness]
    resonance: tuple[Resonance | None, ...] = ()


class CueError(StewartError):
    """A cueing study that cannot run as asked (an unknown mode, a cue the loop cannot track)."""


def cue_study(scene: Scene, motion: VehicleMotion, modes: tuple[str, ...] = ("classical",),
              track: bool = False,
              progress: Callable[[str, int, int], None] | None = None) -> CueStudy:
    """Cue the motion with each mode (the first is the primary) with the scene's [cueing]
    table, then perception and feasibility of each; the closed loop on the primary cue if
    `track`. `progress(stage, done, total)` follows the work (MPC steps, closed-loop samples)."""
    model, config = scene.model, scene.cueing
    runs = []
    for mode in modes:
        start = time.perf_counter()
        cue, solver = make_cue(mode, scene, config, motion, _stage(progress, f"cueing ({mode})"))
        seconds = time.perf_counter() - start
        if progress:
            progress(f"perception and feasibility ({mode})", 0, 1)
        runs.append(CueRun(mode, cue, perception(motion, cue.t, cue.q, cue.qd, cue.qdd,
                                                 model.gravity, config.head),
                           feasibility(model, cue.t, cue.q, cue.qd, cue.qdd, scene.controller),
                           seconds, solver))
    tracking, note = None, None
    if track:
        tracking, note = track_cue(scene, config, motion, runs[0], progress)
    return CueStudy(model, config, motion, tuple(runs), tracking, note, first_mode(model, runs))


def first_mode(model: Model, runs: list[CueRun]) -> tuple[Resonance | None, ...]:
    """Each run's cue against the scene's first mode (resonance.resonance)."""
    return tuple(resonance(model, r.cue.t, r.cue.q, r.cue.qd, r.cue.qdd) for r in runs)


def _stage(progress: Callable[[str, int, int], None] | None,
           stage: str) -> Callable[[int, int], None] | None:
    """progress(done, total) of one named stage."""
    if progress is None:
        return None
    return lambda done, total: progress(stage, done, total)


def make_cue(mode: str, scene: Scene, config: CueingConfig, motion: VehicleMotion,
             progress: Callable[[int, int], None] | None = None
             ) -> tuple[Cue, Diagnostics | None]:
    """The cue of one mode with the washout `config`, and the optimal mode's solver record
    (None for classical); the optimal mode runs with the scene's [cueing.optimal] options and
    its drives' limits. `progress(done, total)` follows the optimal mode's MPC steps."""
    model = scene.model
    home = np.asarray(model.home, dtype=float)
    gravity = np.asarray(model.gravity, dtype=float)
    if mode == "classical":
        return classical_washout(config, motion, home, gravity), None
    if mode == "optimal":
        result = optimal_cueing(model, config, motion, home, gravity, controller=scene.controller,
                                options=scene.optimal, progress=progress)
        return result.cue, result.diagnostics
    raise CueError(f"cue: mode {mode!r} unknown: one of {', '.join(MODES)}")


def track_cue(scene: Scene, config: CueingConfig, motion: VehicleMotion, run: CueRun,
              progress: Callable[[str, int, int], None] | None = None
              ) -> tuple[ClosedLoopResult | None, str | None]:
    """The scene's closed loop ([controller] table) on the run's cue recomputed at the
    controller's rate; (None, why) when the cue leaves the stroke (the loop would refuse it
    before its first step) or the scene has no controller."""
    model, controller = scene.model, scene.controller
    if controller is None:
        return None, "the scene has no [controller] table: nothing to track the cue with"
    stroke = [v for v in run.feasibility.violations if v.quantity.startswith("stroke")]
    if stroke:
        v = stroke[0]
        return None, (f"the cue leaves the stroke (leg {v.leg} at t = {v.t:g} s): the closed "
                      "loop refuses such a reference before its first step")
    fine = resample(motion, controller.rate)
    cue, _ = make_cue(run.mode, scene, config, fine,
                      _stage(progress, f"cueing ({run.mode}) at {controller.rate:g} Hz"))
    return run_closed_loop(model, controller, Trajectory(cue.t, cue.q, cue.qd, cue.qdd),
                           progress=_stage(progress, "closed loop")), None


def resample(motion: VehicleMotion, rate: float) -> VehicleMotion:
    """The motion interpolated linearly at `rate` (Hz) from its first to its last sample (the
    washout's filters take their input as linear between samples, so both rates see the same
    input). CueError when the rate gives fewer than two samples."""
    t0, t1 = float(motion.t[0]), float(motion.t[-1])
    steps = (t1 - t0) * rate + 1e-9
    if not steps >= 1.0:
        raise CueError(f"vehicle motion of {t1 - t0:g} s at {rate:g} Hz: fewer than 2 samples "
                       f"(at least {1.0 / (t1 - t0):.4g} Hz)")
    # t, the specific force and the angular velocity, and the cue built from them (19 columns)
    check_count(f"vehicle motion of {t1 - t0:g} s at {rate:g} Hz: samples", steps + 1,
                2 * 26 * 8, "a shorter motion")
    t = t0 + np.arange(int(np.floor(steps)) + 1) / rate
    def interp(a: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, motion.t, a[:, i]) for i in range(a.shape[1])])
    return VehicleMotion(t, interp(motion.specific_force), interp(motion.angular_velocity))
