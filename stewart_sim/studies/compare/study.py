"""Does the paper's constant-load assumption hold? A drive-inertia sweep of the closed loop.

The paper (Section 3.3 and the Conclusion) finds the drive inertia m_d = zeta^2 I / r^2 far larger
than the dynamic coupling of platform and legs, and so designs each of the six drives as if it
moved a constant load. This report tests that claim in closed loop: for one scene it sweeps the
gear ratio zeta (motor, rotor inertia and pinion kept) so that m_d runs from RATIO_RANGE[0] to
RATIO_RANGE[1] times the constant load m_load (drive.constant_load), re-tunes the per-axis PID to
the scene's bandwidth and phase margin at every point, and tracks one reference (a quintic
six-axis move, then a hold) with

  "none"           pure per-axis feedback, designed for the constant load (the paper's scheme),
  "constant_load"  the same plus feedforward of the constant-load model (m_load + m_d) lddot + c ldot,
  "kane"           the same plus Kane computed-torque feedforward (the full inverse dynamics).

Per point it records the tracking (max and RMS leg error, max pose error), the effort (peak
current, saturation time) and what the constant-load design leaves out:

  coupling      max over the move of ||[m](q) - m_load 1||_2 / (m_load + m_d): the true leg-space
                inertia [m](q) + m_d 1 against the assumed (m_load + m_d) 1, [m] from
                stewart_fmu.kane_terms.mass_matrix on SUBSAMPLE poses of the move;
  modal PM      frozen at a pose, the six loops (same controller on every leg, m_d and viscous
                friction the same on every leg) decouple exactly along the eigenvectors of [m](q),
                into loops with load masses lambda_k: the phase margin and crossover at the
                smallest and largest lambda along the move are what the design really gets
                (NaN: that loop, continuous or sampled at the controller rate, is unstable);
  predicted     the leg error the constant-load design predicts for "none" (the linear loop
                S = 1 / (1 + C P) driven by each leg's reference), to hold against the measured.

Points whose design is infeasible (DesignError) or whose run fails (UnstableLoopError,
PlantStepError, any StewartError) are reported with their message; nothing here raises for them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import control as ct
import numpy as np

from controller.config import FEEDFORWARD, ControllerConfig, scene_axis
from controller.cosim import run_closed_loop
from controller.design import PidGains, design_axis, loop, sampled_spectral_radius
from controller.drive import AxisModel
from controller.moves import move_and_hold
from controller.trajectory import Trajectory, leg_references
from stewart_fmu.errors import StewartError
from stewart_fmu.kane_terms import mass_matrix
from stewart_fmu.model import Model, per_leg

RATIO_RANGE = (0.1, 100.0)   # m_d / m_load at the ends of the sweep
N_POINTS = 8                 # log-spaced sweep points (the scene's own gear ratio is added)
MOVE_PERIODS = 5.0           # quintic move time in periods of the crossover (5 / bandwidth)
HOLD_PERIODS = 5.0           # hold after the move, same unit
SUBSAMPLE = 40               # poses of the move on which [m](q) is evaluated
HOLDS = 0.1                  # the assumption holds: coupling at most this fraction of m_load + m_d


def comparison_reference(model: Model, config: ControllerConfig) -> tuple[Trajectory, float]:
    """The sweep's reference for a scene: a move of MOVE_PERIODS / bandwidth, then a hold of
    HOLD_PERIODS / bandwidth; returns it and the move time."""
    move = MOVE_PERIODS / config.bandwidth
    return move_and_hold(model, config.rate, move, HOLD_PERIODS / config.bandwidth), move


# --- the sweep -------------------------------------------------------------------------------

def with_gear_ratio(model: Model, gear_ratio: float) -> Model:
    """The model with another gear ratio (motor, rotor inertia and pinion kept)."""
    return replace(model, drive=replace(model.drive, gear_ratio=float(gear_ratio)))


def gear_ratio_for(model: Model, mass_ratio: float, load_mass: float) -> float:
    """zeta with m_d = zeta^2 I / r^2 = mass_ratio * load_mass, for the largest rotor inertia
    when the legs differ (the axis model's: controller.drive.axis_model); a gear ratio scales
    all six legs' m_d alike."""
    d = model.drive
    return float(d.pinion_radius * np.sqrt(mass_ratio * load_mass / np.max(per_leg(d.rotor_inertia))))


@dataclass(frozen=True)
class ModeRun:
    """One closed-loop run (one feedforward mode at one sweep point)."""

    mode: str
    status: str                      # "ok" | "failed" (the run raised; see message)
    message: str = ""
    leg_max: float = np.nan          # m, max |e| over legs and samples
    leg_rms: float = np.nan          # m, RMS over legs and samples
    pose_max_linear: float = np.nan  # m, max |x - x_ref| over x, y, z
    pose_max_angular: float = np.nan  # rad, over thx, thy, thz
    current_max: float = np.nan      # A
    voltage_rms: float = np.nan      # V, largest leg
    saturated_time: float = np.nan   # s, any axis at a limit
    wall_time: float = np.nan        # s


@dataclass(frozen=True)
class SweepPoint:
    """One gear ratio: the design, what it leaves out, and a run per feedforward mode."""

    gear_ratio: float
    reflected_mass: float            # m_d, kg
    load_mass: float                 # m_load, kg
    nominal: bool                    # the scene's own gear ratio
    coupling: float                  # max ||[m](q) - m_load 1||_2 / (m_load + m_d)
    status: str                      # "ok" | "infeasible" (design refused; see message)
    message: str = ""
    gains: PidGains | None = None
    phase_margin: float = np.nan     # deg, the design (constant load)
    crossover_hz: float = np.nan
    gain_margin_db: float = np.nan
    modal_pm: tuple[float, float] = (np.nan, np.nan)        # deg at lambda_min, lambda_max
    modal_crossover: tuple[float, float] = (np.nan, np.nan)  # Hz at lambda_min, lambda_max
    predicted_leg_max: float = np.nan  # m, constant-load prediction for "none"
    peak_emf: float = np.nan         # V, back-EMF Ke zeta / r at the reference's peak leg rate
    runs: dict[str, ModeRun] = field(default_factory=dict)

    @property
    def mass_ratio(self) -> float:
        return self.reflected_mass / self.load_mass


@dataclass(frozen=True)
class Comparison:
    """The sweep of one scene."""

    scene: str
    source: str | None
    config: ControllerConfig
    modes: tuple[str, ...]
    load_mass: float
    nominal_gear_ratio: float
    mass_eigen_range: tuple[float, float]  # smallest and largest eigenvalue of [m](q), kg
    coupling_mass: float             # max ||[m](q) - m_load 1||_2 over the move, kg
    move_time: float                 # s
    duration: float                  # s, move and hold
    goal: np.ndarray                 # (6,) the pose the move ends at
    leg_excursion: float             # m, largest |l_ref - l_ref(0)| of the move
    points: tuple[SweepPoint, ...]
    # the scene's own gear ratio again with the Coulomb friction removed (a diagnostic: the
    # feedforward's Coulomb term switches with the reference's sign; empty without Coulomb)
    without_coulomb: dict[str, ModeRun] = field(default_factory=dict)
    coulomb: float = 0.0             # N, the scene's Coulomb friction (its largest leg's)

    def rows(self) -> list[dict[str, object]]:
        """One flat row per point and mode (the CSV's rows)."""
        rows = []
        for p in self.points:
            for mode in self.modes:
                r = p.runs.get(mode, ModeRun(mode, "not run", p.message))
                kp, ki, kd = (p.gains.kp, p.gains.ki, p.gains.kd) if p.gains else (np.nan,) * 3
                rows.append({
                    "scene": self.scene, "gear_ratio": p.gear_ratio, "m_d": p.reflected_mass,
                    "m_load": p.load_mass, "md_over_mload": p.mass_ratio,
                    "nominal": int(p.nominal), "coupling": p.coupling,
                    "design": p.status, "kp": kp, "ki": ki, "kd": kd,
                    "phase_margin": p.phase_margin, "crossover_hz": p.crossover_hz,
                    "modal_pm_min_lambda": p.modal_pm[0], "modal_pm_max_lambda": p.modal_pm[1],
                    "modal_fc_min_lambda": p.modal_crossover[0],
                    "modal_fc_max_lambda": p.modal_crossover[1],
                    "predicted_leg_max_none": p.predicted_leg_max, "peak_emf": p.peak_emf,
                    "regime": regime(p), "cl_over_kane": feedforward_ratio(p),
                    "captured": captured(p), "mode": mode, "status": r.status if p.status == "ok" else p.status,
                    "leg_err_max": r.leg_max, "leg_err_rms": r.leg_rms,
                    "leg_err_max_rel": r.leg_max / self.leg_excursion,
                    "pose_err_max_linear": r.pose_max_linear,
                    "pose_err_max_angular": r.pose_max_angular, "current_max": r.current_max,
                    "voltage_rms": r.voltage_rms, "saturated_time": r.saturated_time,
                    "message": r.message or p.message,
                })
        return rows

    def nominal(self) -> SweepPoint | None:
        """The point at the scene's own gear ratio (None when the sweep left it out)."""
        return next((p for p in self.points if p.nominal), None)


def compare_drive_inertia(model: Model, config: ControllerConfig, n_points: int = N_POINTS,
                          ratio_range: tuple[float, float] = RATIO_RANGE,
                          modes: Sequence[str] = FEEDFORWARD, include_nominal: bool = True,
                          progress: Callable[[int, int], None] | None = None) -> Comparison:
    """The sweep of one scene (see the module doc); `progress(done, total)` in simulated
    samples after each gear ratio."""
    if model.drive is None:
        raise StewartError(f"scene '{model.name}': the sweep varies the [drive]; the scene has none")
    unknown = [m for m in modes if m not in FEEDFORWARD]
    if unknown or n_points < 1:
        raise StewartError(f"modes must be among {FEEDFORWARD} (got {unknown}) and n_points >= 1")
    load = scene_axis(model, config).load_mass
    traj, move_time = comparison_reference(model, config)
    refs = leg_references(model, traj)
    n_move = int(round(move_time * config.rate)) + 1
    poses = traj.q[np.unique(np.linspace(0, n_move - 1, SUBSAMPLE).round().astype(int))]
    masses = np.array([mass_matrix(model, q) for q in poses])
    eig = np.linalg.eigvalsh(masses)
    coupling_mass = float(np.max(np.linalg.norm(masses - load * np.eye(6), ord=2, axis=(1, 2))))
    ratios = list(np.geomspace(*ratio_range, n_points)) if n_points > 1 else [ratio_range[0]]
    zetas = [(gear_ratio_for(model, r, load), False) for r in ratios]
    if include_nominal:
        zetas.append((model.drive.gear_ratio, True))
    zetas.sort()
    total, done = len(zetas) * len(modes) * len(traj.t), 0
    points = []
    for zeta, nominal in zetas:
        m = with_gear_ratio(model, zeta)
        point = _point(m, config, traj, refs, modes, load, nominal, coupling_mass,
                       (float(eig.min()), float(eig.max())))
        points.append(point)
        done += len(modes) * len(traj.t)
        if progress is not None:
            progress(done, total)
    excursion = float(np.max(np.abs(refs.l - refs.l[0])))
    without_coulomb = {}
    nominal = next((p for p in points if p.nominal and p.status == "ok"), None)
    if nominal is not None and model.friction is not None and np.any(model.friction.coulomb_legs > 0):
        smooth = replace(model, friction=replace(model.friction, coulomb=0.0))
        without_coulomb = {mode: run_mode(smooth, config, traj, nominal.gains, mode)
                           for mode in modes}
    return Comparison(model.name, model.source, config, tuple(modes), load,
                      model.drive.gear_ratio, (float(eig.min()), float(eig.max())), coupling_mass,
                      move_time, float(traj.t[-1]), traj.q[n_move - 1].copy(), excursion,
                      tuple(points), without_coulomb,
                      float(np.max(model.friction.coulomb_legs)) if model.friction is not None else 0.0)


def _point(model: Model, config: ControllerConfig, traj: Trajectory, refs, modes, load: float,
           nominal: bool, coupling_mass: float, eig: tuple[float, float]) -> SweepPoint:
    """Design, modal check, prediction and the runs at one gear ratio."""
    md = model.drive.reflected_mass
    base = dict(gear_ratio=model.drive.gear_ratio, reflected_mass=md, load_mass=load,
                nominal=nominal, coupling=coupling_mass / (load + md),
                peak_emf=(config.motor.back_emf * model.drive.gear_ratio
                          / model.drive.pinion_radius * float(np.max(np.abs(refs.ldot)))))
    try:
        axis, gains, analysis = design_axis(model, config)
    except StewartError as exc:  # DesignError, UnstableLoopError
        return SweepPoint(status="infeasible", message=f"{type(exc).__name__}: {exc}", **base)
    pm, fc = zip(*(_margins(replace(axis, load_mass=lam), gains, config.dt, config.delay)
                   for lam in eig))
    runs = {mode: run_mode(model, config, traj, gains, mode) for mode in modes}
    return SweepPoint(status="ok", gains=gains, phase_margin=analysis.phase_margin_deg,
                      crossover_hz=analysis.crossover_hz, gain_margin_db=analysis.gain_margin_db,
                      modal_pm=tuple(pm), modal_crossover=tuple(fc),
                      predicted_leg_max=_predicted_error(axis, gains, refs), runs=runs, **base)


def run_mode(model: Model, config: ControllerConfig, traj: Trajectory, gains: PidGains,
             mode: str) -> ModeRun:
    """One closed-loop run with feedforward `mode` and the given gains, as figures."""
    try:
        res = run_closed_loop(model, replace(config, feedforward=mode), traj, gains=gains)
    except StewartError as exc:  # UnstableLoopError (diverged), PlantStepError
        return ModeRun(mode, "failed", f"{type(exc).__name__}: {exc}")
    s = res.summary
    return ModeRun(mode, "ok", "", float(s.leg_max.max()), float(np.sqrt(np.mean(s.leg_rms**2))),
                   float(s.pose_max[:3].max()), float(s.pose_max[3:].max()),
                   float(s.current_max.max()), float(s.voltage_rms.max()), s.saturated_time,
                   s.wall_time)


def _margins(axis: AxisModel, gains: PidGains, dt: float, delay: int) -> tuple[float, float]:
    """Phase margin (deg; NaN when the loop, continuous or sampled at dt with `delay` periods
    of actuation delay, is unstable) and crossover (Hz) of the loop."""
    L = loop(axis, gains)
    _, pm, _, wc = ct.margin(L)
    stable = (bool(np.all(np.real(ct.poles(ct.feedback(L, 1))) < 0))
              and sampled_spectral_radius(axis, gains, dt, delay) < 1.0)
    return (float(pm) if stable else np.nan), float(wc / (2 * np.pi))


def _predicted_error(axis: AxisModel, gains: PidGains, refs) -> float:
    """Max leg error of the constant-load loop without feedforward: e = S (l_ref - l_ref(0))."""
    S = ct.feedback(1, loop(axis, gains))
    worst = 0.0
    for i in range(6):
        e = ct.forced_response(S, refs.t, refs.l[:, i] - refs.l[0, i]).outputs
        worst = max(worst, float(np.max(np.abs(e))))
    return worst


# --- verdicts --------------------------------------------------------------------------------

def feedforward_ratio(point: SweepPoint) -> float:
    """Max leg error with constant-load feedforward over that with Kane feedforward: how much
    tracking the constant-load model loses against the full model (NaN without both runs)."""
    r = point.runs
    if not all(m in r and r[m].status == "ok" for m in ("constant_load", "kane")):
        return np.nan
    return r["constant_load"].leg_max / r["kane"].leg_max


def captured(point: SweepPoint) -> float:
    """Share of Kane feedforward's error reduction that the constant-load feedforward achieves:
    (e_none - e_cl) / (e_none - e_kane), max leg errors; NaN without the three runs."""
    r = point.runs
    if not all(m in r and r[m].status == "ok" for m in ("none", "constant_load", "kane")):
        return np.nan
    gain = r["none"].leg_max - r["kane"].leg_max
    return float((r["none"].leg_max - r["constant_load"].leg_max) / gain) if gain > 0 else np.nan


def saturates(point: SweepPoint) -> bool:
    """Every run of the point reaches a voltage or current limit: the drive, not the model,
    limits the tracking (the linear constant-load design no longer describes the loop)."""
    ok = [r for r in point.runs.values() if r.status == "ok"]
    return bool(ok) and all(r.saturated_time > 0 for r in ok)


def regime(point: SweepPoint) -> str:
    """"holds" (coupling <= HOLDS, no saturation), "coupling" (coupling > HOLDS), "saturation"
    (every run saturates), "coupling+saturation", or "infeasible" / "failed"."""
    if point.status != "ok":
        return point.status
    if any(r.status != "ok" for r in point.runs.values()):
        return "failed"
    tags = [t for t, on in (("coupling", point.coupling > HOLDS), ("saturation", saturates(point)))
            if on]
    return "+".join(tags) or "holds"
