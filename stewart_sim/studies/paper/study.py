"""Rerun of the paper's Section 3: six constant-acceleration moves at three model levels, and the
figures behind its two claims (Conclusion) and its remark on Fig. 3(a).

The six moves: stewart_sim.scene.paper_moves.

Levels (paper 3.1-3.3), all built from the scene's Model with dataclasses.replace:
  1 "platform": platform only (no legs, no drive),  2 "legs": platform and legs,
  3 "drive": platform, legs and drive inertia.
The paper ignores damping and friction in these runs ("damping and friction were ignored"), so the
scene's [friction] is removed at every level (`PaperResults.removed_friction` keeps what it was).
Two extra leg variants feed claim (a): "lower_only" (upper-leg mass and inertia zero) and
"upper_only" (lower-leg mass and inertia zero), both without drive.

Verdict thresholds (stated in the report): an effect is "negligible" below NEGLIGIBLE of the
platform-only peak force, "very significant" above SIGNIFICANT of it, and one force is "far larger"
than another at FAR_LARGER times or more; a change is "uniform" across the legs when its spread is
at most UNIFORM of its smallest value.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Mapping

import numpy as np

from stewart_fmu.dynamics import inverse_dynamics, inverse_dynamics_parts, present_parts
from stewart_fmu.errors import SceneError, TrajectoryError
from stewart_fmu.model import FrictionParams, Model, is_per_leg
from stewart_sim.scene.paper_moves import TRAJECTORIES, Trajectory, make_trajectory

LEVELS = ("platform", "legs", "drive")
LEVEL_TITLES = MappingProxyType({
    "platform": "level 1: platform only (paper 3.1, Fig. 2)",
    "legs": "level 2: platform + legs (paper 3.2, Fig. 3)",
    "drive": "level 3: platform + legs + drive inertia (paper 3.3)",
    "lower_only": "lower-leg masses only (upper-leg mass and inertia 0)",
    "upper_only": "upper-leg masses only (lower-leg mass and inertia 0)",
})
VARIANTS = ("lower_only", "upper_only")
INERTIAL_PARTS = ("platform", "lower_legs", "upper_legs")  # the non-drive inertia ("coupling")
NEGLIGIBLE = 0.05
SIGNIFICANT = 0.25
FAR_LARGER = 10.0
UNIFORM = 0.05               # spread across legs over the smallest increase, Fig. 3(c) remark
FIG3A_TRAJECTORY = "x"


@dataclass(frozen=True)
class Run:
    """Forces of one trajectory at one model level: sigma and its breakdown (present parts only)."""

    sigma: np.ndarray                  # (N, 6)
    parts: Mapping[str, np.ndarray]    # part name -> (N, 6), summing to sigma


@dataclass(frozen=True)
class LegMassFigures:
    """Claim (a) for one trajectory: effect of lower vs upper leg masses (N, max over t and legs)."""

    platform_peak: float        # max |sigma| at level 1
    lower_effect: float         # max |sigma(lower_only) - sigma(level 1)|
    upper_effect: float         # max |sigma(upper_only) - sigma(level 1)|
    legs_effect: float          # max |sigma(level 2) - sigma(level 1)|
    lower_inertia_peak: float   # max |lower_legs part| at level 2 (inertia only, no gravity)
    upper_inertia_peak: float   # max |upper_legs part| at level 2
    legs_effect_min: float      # min over t and legs of sigma(level 2) - sigma(level 1), signed
    legs_effect_max: float      # max of the same, signed
    legs_effect_spread: float   # max over t of the range across legs of that difference

    @property
    def lower_relative(self) -> float:
        """Lower-leg effect over the platform-only peak."""
        return self.lower_effect / self.platform_peak

    @property
    def upper_relative(self) -> float:
        """Upper-leg effect over the platform-only peak."""
        return self.upper_effect / self.platform_peak

    @property
    def upper_over_lower(self) -> float:
        """How many times larger the upper-leg effect is than the lower-leg effect."""
        return self.upper_effect / self.lower_effect

    @property
    def agrees(self) -> bool:
        """Lower negligible and upper very significant, by the module thresholds."""
        return self.lower_relative < NEGLIGIBLE and self.upper_relative >= SIGNIFICANT


@dataclass(frozen=True)
class DriveFigures:
    """Claim (b) for one trajectory: drive inertia force m_d lddot vs the coupling forces (N)."""

    drive_peak: float            # max |m_d lddot|
    drive_variation: float       # max over legs of the range over t of m_d lddot_i
    coupling_peak: float         # max |platform + lower_legs + upper_legs parts|
    coupling_variation: float    # max over legs of the range over t of that inertial part
    coupling_spread: float       # max over t of the range across legs of that inertial part
    level2_variation: float      # max over legs of the range over t of sigma at level 2
    gravity_peak: float          # max |gravity part| (platform and legs)

    @property
    def ratio_peak(self) -> float:
        """Drive peak over the coupling peak (the verdict's figure)."""
        return self.drive_peak / self.coupling_peak

    @property
    def ratio_spread(self) -> float:
        """Drive peak over the coupling spread across the six legs."""
        return self.drive_peak / self.coupling_spread if self.coupling_spread > 0 else np.inf

    @property
    def ratio_variation(self) -> float:
        """Drive peak over the time variation of the level-2 forces."""
        return self.drive_peak / self.level2_variation if self.level2_variation > 0 else np.inf

    @property
    def ratio_gravity(self) -> float:
        """Drive peak over the gravity peak."""
        return self.drive_peak / self.gravity_peak

    @property
    def agrees(self) -> bool:
        """Drive term at least FAR_LARGER times the peak coupling force."""
        return self.ratio_peak >= FAR_LARGER


@dataclass(frozen=True)
class Fig3aRemark:
    """Paper's Fig. 3(a) vs 2(a): with leg masses some |sigma_i| rise, some fall (x trajectory)."""

    trajectory: str
    change: np.ndarray            # (N, 6) |sigma(level 2)| - |sigma(level 1)|
    increased: tuple[int, ...]    # legs (1-based) whose magnitude rises at every sample
    decreased: tuple[int, ...]    # legs whose magnitude falls at every sample
    mixed: tuple[int, ...]        # legs that rise at some samples and fall at others
    fall_fraction: np.ndarray     # (6,) fraction of samples at which |sigma_i| falls
    first_fall: np.ndarray        # (6,) first time (s) at which |sigma_i| falls, nan if never
    contracting: tuple[int, ...]  # legs with ldot < 0 at the end of the move
    tension: tuple[int, ...]      # legs with sigma < 0 at level 1 at some sample

    @property
    def shows(self) -> bool:
        """Some legs rise throughout and some fall throughout, as the paper reports."""
        return bool(self.increased) and bool(self.decreased)


@dataclass(frozen=True)
class Verdict:
    """A plain 'agrees / does not agree' for one statement of the paper, with the reason."""

    claim: str
    agrees: bool
    reason: str


@dataclass(frozen=True)
class PaperResults:
    """Everything the paper rerun computes; `write_paper_report` turns it into files."""

    scene: str
    model: Model                                  # the scene's model as given
    models: Mapping[str, Model]                   # LEVELS and VARIANTS, friction removed
    removed_friction: FrictionParams | None
    t: np.ndarray                                 # (N,)
    trajectories: Mapping[str, Trajectory]
    runs: Mapping[str, Mapping[str, Run]]         # runs[trajectory][level or variant]
    leg_masses: Mapping[str, LegMassFigures]      # claim (a) per trajectory
    drive: Mapping[str, DriveFigures]             # claim (b) per trajectory
    fig3a: Fig3aRemark
    verdicts: tuple[Verdict, ...]                 # claims (a), (b), Figs. 3(a) and 3(c) remarks

    @property
    def drive_mass(self) -> float:
        """m_d = zeta^2 I / r^2 of the scene's drive (its largest leg's when per leg)."""
        return self.models["drive"].drive.reflected_mass

    @property
    def per_leg_drive(self) -> bool:
        """Whether the scene gives each leg its own rotor inertia."""
        return is_per_leg(self.models["drive"].drive.rotor_inertia)


def run_paper_experiments(model: Model, duration: float = 0.1, samples: int = 201) -> PaperResults:
    """Run the paper's six trajectories at the three levels and the two leg variants."""
    _check_inputs(model, duration, samples)
    models = paper_models(model)
    t = np.linspace(0.0, duration, samples)
    trajs = {name: make_trajectory(model, name, t) for name in TRAJECTORIES}
    runs = {name: {lv: _run(m, tr) for lv, m in models.items()} for name, tr in trajs.items()}
    legs = {n: leg_mass_figures(runs[n]) for n in TRAJECTORIES}
    drive = {n: drive_figures(runs[n]) for n in TRAJECTORIES}
    fig3a = fig3a_remark(t, trajs[FIG3A_TRAJECTORY], runs[FIG3A_TRAJECTORY])
    return PaperResults(
        scene=model.name, model=model, models=MappingProxyType(models),
        removed_friction=model.friction, t=t, trajectories=MappingProxyType(trajs),
        runs=MappingProxyType({k: MappingProxyType(v) for k, v in runs.items()}),
        leg_masses=MappingProxyType(legs), drive=MappingProxyType(drive), fig3a=fig3a,
        verdicts=(verdict_leg_masses(legs), verdict_drive(drive), verdict_fig3a(fig3a),
                  verdict_z_uniform(legs["z"])))


def _check_inputs(model: Model, duration: float, samples: int) -> None:
    """The rerun needs legs and a drive in the scene, a positive duration and >= 2 samples."""
    if model.legs is None:
        raise SceneError("legs", "the paper's experiments need leg masses (level 2)", model.source)
    if model.drive is None:
        raise SceneError("drive", "the paper's experiments need a drive (level 3)", model.source)
    if not (np.isfinite(duration) and duration > 0):
        raise TrajectoryError(f"duration must be a finite number > 0 s, got {duration!r}")
    if isinstance(samples, bool) or int(samples) != samples or samples < 2:
        raise TrajectoryError(f"samples must be an integer >= 2, got {samples!r}")


def paper_models(model: Model) -> dict[str, Model]:
    """The three levels and the two leg variants, all without friction."""
    base = replace(model, friction=None)
    legs = replace(base, drive=None)
    lg = model.legs
    return {
        "platform": replace(base, legs=None, drive=None),
        "legs": legs,
        "drive": base,
        "lower_only": replace(legs, legs=replace(lg, upper_mass=0.0, upper_inertia=(0.0, 0.0))),
        "upper_only": replace(legs, legs=replace(lg, lower_mass=0.0, lower_inertia=(0.0, 0.0))),
    }


def _run(model: Model, tr: Trajectory) -> Run:
    """Forces and their breakdown (only the parts this model computes)."""
    sigma = inverse_dynamics(model, tr.q, tr.qd, tr.qdd)
    parts = inverse_dynamics_parts(model, tr.q, tr.qd, tr.qdd)
    return Run(sigma, MappingProxyType({k: parts[k] for k in present_parts(model)}))


def _peak(a: np.ndarray) -> float:
    """max |a| over all samples and legs."""
    return float(np.max(np.abs(a)))


def _range_over_time(a: np.ndarray) -> float:
    """Max over legs of (max - min) over time."""
    return float(np.max(a.max(axis=0) - a.min(axis=0)))


def _range_over_legs(a: np.ndarray) -> float:
    """Max over time of (max - min) across the six legs."""
    return float(np.max(a.max(axis=1) - a.min(axis=1)))


def leg_mass_figures(runs: Mapping[str, Run]) -> LegMassFigures:
    """Claim (a) figures of one trajectory from its runs."""
    s1 = runs["platform"].sigma
    d = runs["legs"].sigma - s1
    parts = runs["legs"].parts
    return LegMassFigures(
        platform_peak=_peak(s1), lower_effect=_peak(runs["lower_only"].sigma - s1),
        upper_effect=_peak(runs["upper_only"].sigma - s1), legs_effect=_peak(d),
        lower_inertia_peak=_peak(parts["lower_legs"]), upper_inertia_peak=_peak(parts["upper_legs"]),
        legs_effect_min=float(d.min()), legs_effect_max=float(d.max()),
        legs_effect_spread=_range_over_legs(d))


def coupling_force(run: Run) -> np.ndarray:
    """The non-drive inertial part: platform + lower-leg + upper-leg inertia forces, (N, 6)."""
    return sum((run.parts[k] for k in INERTIAL_PARTS), np.zeros_like(run.sigma))


def drive_figures(runs: Mapping[str, Run]) -> DriveFigures:
    """Claim (b) figures of one trajectory from its runs."""
    full = runs["drive"]
    coupling = coupling_force(full)
    drive = full.parts["drives"]
    return DriveFigures(
        drive_peak=_peak(drive), drive_variation=_range_over_time(drive),
        coupling_peak=_peak(coupling), coupling_variation=_range_over_time(coupling),
        coupling_spread=_range_over_legs(coupling),
        level2_variation=_range_over_time(runs["legs"].sigma),
        gravity_peak=_peak(full.parts["gravity"]))


def fig3a_remark(t: np.ndarray, tr: Trajectory, runs: Mapping[str, Run]) -> Fig3aRemark:
    """Which |sigma_i| rise and which fall when leg masses are added (levels 1 -> 2)."""
    s1 = runs["platform"].sigma
    change = np.abs(runs["legs"].sigma) - np.abs(s1)
    up, down = np.all(change > 0, axis=0), np.all(change < 0, axis=0)
    falls = change < 0
    first = np.where(falls.any(axis=0), t[np.argmax(falls, axis=0)], np.nan)
    legs = lambda mask: tuple(int(i) + 1 for i in np.flatnonzero(mask))  # noqa: E731
    return Fig3aRemark(
        trajectory=tr.name, change=change, increased=legs(up), decreased=legs(down),
        mixed=legs(~up & ~down), fall_fraction=np.mean(falls, axis=0), first_fall=first,
        contracting=legs(tr.rates[-1] < 0), tension=legs(np.any(s1 < 0, axis=0)))


def _names(figs: Mapping[str, object], ok: bool) -> list[str]:
    """Trajectory names whose figures agree (ok=True) or not."""
    return [n for n, f in figs.items() if f.agrees == ok]


def verdict_leg_masses(figs: Mapping[str, LegMassFigures]) -> Verdict:
    """Claim (a): lower-leg masses negligible, upper-leg masses very significant."""
    bad = _names(figs, False)
    lo = [f.lower_relative for f in figs.values()]
    up = [f.upper_relative for f in figs.values()]
    ratio = [f.upper_over_lower for f in figs.values()]
    order = "exceeds" if min(ratio) > 1 else "does not always exceed"
    reason = (f"lower-leg effect {min(lo):.1%}-{max(lo):.1%} and upper-leg effect "
              f"{min(up):.1%}-{max(up):.1%} of the platform-only peak force; the upper-leg effect "
              f"{order} the lower-leg effect ({min(ratio):.1f}-{max(ratio):.1f}x) "
              f"(thresholds: negligible < {NEGLIGIBLE:.0%}, very significant >= {SIGNIFICANT:.0%})")
    if bad:
        reason += "; fails for " + ", ".join(_why_legs(n, figs[n]) for n in bad)
    return Verdict("(a) lower-leg masses negligible, upper-leg masses very significant",
                   not bad, reason)


def _why_legs(name: str, f: LegMassFigures) -> str:
    """Why one trajectory fails claim (a)."""
    why = []
    if f.lower_relative >= NEGLIGIBLE:
        why.append(f"lower {f.lower_relative:.1%} not negligible")
    if f.upper_relative < SIGNIFICANT:
        why.append(f"upper {f.upper_relative:.1%} not very significant")
    return f"{name} ({', '.join(why)})"


def verdict_drive(figs: Mapping[str, DriveFigures]) -> Verdict:
    """Claim (b): drive inertia forces far larger than the dynamic coupling effects."""
    bad = _names(figs, False)
    r = [f.ratio_peak for f in figs.values()]
    reason = (f"drive force m_d*lddot / peak coupling (platform + leg inertia) force = "
              f"{min(r):.3g}-{max(r):.3g} (far larger: >= {FAR_LARGER:g}x)")
    if bad:
        reason += "; fails for " + ", ".join(f"{n} ({figs[n].ratio_peak:.3g}x)" for n in bad)
    var = [f.drive_variation / f.drive_peak for f in figs.values()]
    reason += (f"; m_d*lddot varies over the move by {min(var):.0%}-{max(var):.0%} of its peak "
               "(the paper calls it constant)")
    weak = [n for n, f in figs.items() if f.ratio_gravity < FAR_LARGER]
    if weak:
        reason += ("; the drive term is not far larger than gravity for " + ", ".join(
            f"{n} ({figs[n].ratio_gravity:.3g}x)" for n in weak))
    return Verdict("(b) drive inertia forces far larger than the dynamic coupling effects",
                   not bad, reason)


def verdict_fig3a(r: Fig3aRemark) -> Verdict:
    """Fig. 3(a) remark: with leg masses some |sigma_i| increase and some decrease."""
    fmt = lambda legs: ", ".join(map(str, legs)) or "none"  # noqa: E731
    mixed = "; ".join(f"leg {i} falls at {r.fall_fraction[i - 1]:.0%} of the samples, first at "
                      f"t = {r.first_fall[i - 1]:.3g} s" for i in r.mixed)
    reason = (f"'{r.trajectory}' trajectory: |sigma| rises throughout for legs {fmt(r.increased)}, "
              f"falls throughout for legs {fmt(r.decreased)}, changes direction for legs "
              f"{fmt(r.mixed)}" + (f" ({mixed})" if mixed else "")
              + f"; contracting legs: {fmt(r.contracting)}; legs in tension at level 1: "
              f"{fmt(r.tension)} (paper: 1, 3, 4, 6 rise, 2 and 5 fall; its geometry and leg "
              "numbering are not given, so only the pattern can be compared)")
    return Verdict("Fig. 3(a): with leg masses some actuator forces increase, some decrease",
                   r.shows, reason)


def verdict_z_uniform(f: LegMassFigures) -> Verdict:
    """Figs. 2(c)/3(c) remark: along z the legs raise all six forces, and uniformly."""
    rel = f.legs_effect_spread / f.legs_effect_min if f.legs_effect_min > 0 else np.inf
    ok = f.legs_effect_min > 0 and rel <= UNIFORM
    reason = (f"'z' trajectory: sigma(level 2) - sigma(level 1) lies in "
              f"[{f.legs_effect_min:.4g}, {f.legs_effect_max:.4g}] N; its spread across the legs is "
              f"{f.legs_effect_spread:.3g} N, {rel:.2g} of the smallest increase (uniform: "
              f"<= {UNIFORM:.0%})")
    return Verdict("Fig. 3(c): leg masses increase all six forces uniformly along z", ok, reason)
