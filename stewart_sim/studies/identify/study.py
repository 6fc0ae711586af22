"""Identification of the dynamic parameters from runs (`identify`): the pipeline and its data.

For each run (runs.read_run): forward kinematics of the measured lengths (runs.pose_of); the
zero-phase low-passed pose and its derivatives (signal.derivatives); the regressor Y of the
filtered motion (stewart_fmu.dynamics.regressor, the core's); then the same low-pass on Y's
columns and on the measured forces (parallel filtering: sigma = Y pi stays exact, the noise
above the cut-off goes) and decimation (signal.decimated). The rows of all runs are stacked;
base.base_parameters finds what they determine, compared with the scene's structural base
(what no data could separate); estimate.estimate gives beta with standard deviations and a
physically consistent pi. Validation predicts held-out runs' forces with pi and with the prior
scene's parameters.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from stewart_fmu.dynamics import regressor
from stewart_fmu.errors import StewartError, TrajectoryError
from stewart_fmu.model import Model
from stewart_fmu.standard import N_STANDARD, NAMES, present, span, standard_parameters

from .base import BaseParameters, base_parameters, stacked, structural_base
from .estimate import Estimate, IdentificationError, estimate, scales
from .runs import Run, pose_of
from .scene_out import NOT_HELD
from .signal import Filter, choose_filter, decimated, derivatives, lowpass, white_noise_factor

ROUND_OFF = 1e-9   # an error below this times the force peak is arithmetic, not noise

# What motion excites a standard parameter (the hint of a rank-deficiency refusal).
_HINTS = (("platform.inertia_tensor.xx", "rotation about x"),
          ("platform.inertia_tensor.yy", "rotation about y"),
          ("platform.inertia_tensor.zz", "rotation about z"),
          ("platform.inertia_tensor.x", "rotation about x"),
          ("platform.inertia_tensor.y", "rotation about y"),
          ("platform.inertia_tensor", "rotation about all three axes"),
          ("platform.first_moment", "rotation with translation"),
          ("platform.mass", "vertical acceleration"),
          ("legs.", "leg rotation (tilting the legs)"),
          ("drive.reflected_mass", "leg acceleration"),
          ("friction.viscous", "leg speed"),
          ("friction.coulomb", "leg motion in both directions"))


@dataclass(frozen=True)
class Prepared:
    """One run, filtered and decimated: the rows it adds to the identification."""

    run: Run
    filter: Filter
    t: np.ndarray        # (n,) times of the decimated samples (s)
    W: np.ndarray        # (6 n, N_STANDARD) stacked regressor rows
    s: np.ndarray        # (6 n,) measured forces (filtered, decimated)


@dataclass(frozen=True)
class Prediction:
    """Forces of a run predicted from its measured motion (full rate)."""

    run: Run
    t: np.ndarray              # (N,)
    measured: np.ndarray       # (N, 6) N
    identified: np.ndarray     # (N, 6) with the identified pi
    prior: np.ndarray          # (N, 6) with the prior scene's pi
    noise_floor: np.ndarray    # (6,) the force noise of the run (N), from above the cut-off

    def rms(self, which: str) -> np.ndarray:
        return np.sqrt(np.mean((getattr(self, which) - self.measured) ** 2, axis=0))

    def peak(self, which: str) -> np.ndarray:
        return np.max(np.abs(getattr(self, which) - self.measured), axis=0)

    def rms_error(self, which: str) -> float:
        """The RMS error over all legs of the `which` model, relative to the force peak."""
        return float(np.sqrt(np.mean(self.rms(which) ** 2))) / self.force_peak

    @property
    def force_peak(self) -> float:
        return float(np.max(np.abs(self.measured)))

    def at_noise_floor(self, factor: float = 1.2) -> bool:
        """Whether the identified model's RMS error is within `factor` x the noise floor on
        every leg (or at round-off, ROUND_OFF of the peak: noise-free data)."""
        rms = self.rms("identified")
        return bool(np.all((rms <= factor * self.noise_floor)
                           | (rms <= ROUND_OFF * self.force_peak)))


@dataclass(frozen=True)
class Identification:
    """The result of `identify`."""

    model: Model                 # the prior scene's model
    prepared: tuple[Prepared, ...]
    structural: BaseParameters   # what the scene's structure allows
    base: BaseParameters         # what the runs determine
    estimate: Estimate
    prior: np.ndarray            # the prior scene's standard parameters
    scale: np.ndarray            # typical magnitude of each standard parameter
    missing: tuple[str, ...]     # structurally identifiable, not by these runs (kept at prior)
    force_delay: float = 0.0     # s: the runs' forces belong to the motion this long before

    @property
    def pi(self) -> np.ndarray:
        return self.estimate.pi

    def identified(self) -> set[str]:
        """Standard parameters the runs determined, alone or in combination."""
        return set(self.base.alone) | set(self.base.combined)

    def written(self) -> set[str]:
        """The standard parameters identified.toml takes from pi: all those the scene holds.
        pi is one physically consistent set: its parameters that the runs do not determine are
        at the prior unless the consistency constraints had to move them, and mixing them with
        the prior's could break consistency (a leg part's mass with another's moment)."""
        return {n for n, held in zip(NAMES, present(self.model)) if held} - set(NOT_HELD)

    def unheld(self) -> set[str]:
        """The standard parameters the runs determine that a scene cannot hold (NOT_HELD)."""
        return self.identified() & set(NOT_HELD)

    def base_scale(self) -> np.ndarray:
        """A base parameter's magnitude for relative errors (|K| times the scales)."""
        return np.abs(self.base.combination) @ self.scale

    def fitted(self, p: Prepared) -> np.ndarray:
        """The model's forces on the rows of a prepared run."""
        return p.W @ self.pi


def prepare(model: Model, run: Run, cutoff: float | None = None,
            decimate: int | None = None, force_delay: float = 0.0) -> Prepared:
    """The identification rows of one run (module docstring); `force_delay` (s): the run's
    forces belong to the motion that long before their time stamp (the regressor is then taken
    of the pose shifted back by it: the forces and their noise stay as measured)."""
    q = pose_of(model, run)
    filt = choose_filter(run.t, q, cutoff, decimate)
    Y = _regressor(model, run, q, filt, force_delay)
    Yd = decimated(lowpass(Y, filt), filt)
    sd = decimated(lowpass(run.sigma, filt), filt)
    return Prepared(run, filt, decimated(run.t, filt), stacked(Yd), sd.reshape(-1))


def _regressor(model: Model, run: Run, q: np.ndarray, filt: Filter,
               force_delay: float) -> np.ndarray:
    """Y of the run's filtered motion (poses q), the forces `force_delay` late. Derivatives that
    overflow (a time step far too short for the motion: the time column in the wrong unit) and
    the regressor's refusals are a TrajectoryError naming the run."""
    with np.errstate(over="ignore", invalid="ignore"):   # refused below, in one line
        qf, qd, qdd = derivatives(q, filt, -force_delay)
    for name, x in (("rates", qd), ("accelerations", qdd)):
        if not np.all(np.isfinite(x)):
            raise TrajectoryError(
                f"{run.path}: the pose's {name} overflow float64 at the run's sampling period "
                f"of {1.0 / filt.rate:.3g} s: is the time column in seconds?")
    try:
        return regressor(model, qf, qd, qdd)
    except StewartError as exc:
        raise TrajectoryError(f"{run.path}: the filtered motion: {exc}",
                              index=getattr(exc, "index", None)) from None


def identify(model: Model, runs: list[Run], cutoff: float | None = None, partial: bool = False,
             force_delay: float = 0.0) -> Identification:
    """Identify the scene's standard parameters from `runs`. Raises IdentificationError when the
    runs determine fewer base parameters than the scene's structure allows (unless `partial`:
    then the others keep the prior)."""
    prepared = tuple(prepare(model, r, cutoff, force_delay=force_delay) for r in runs)
    W = np.vstack([p.W for p in prepared])
    s = np.concatenate([p.s for p in prepared])
    legs = np.tile(np.arange(6), len(s) // 6)
    structural = structural_base(model)
    base = base_parameters(W, np.flatnonzero(present(model)))
    missing = _missing(structural, base)
    if missing and not partial:
        raise IdentificationError(
            f"{', '.join(str(r.path) for r in runs)}: regressor rank {base.rank} of "
            f"{structural.rank} (the scene's base parameters): "
            f"{', '.join(missing)} not identifiable from these runs; add {_hint(missing)} "
            f"(or --partial to keep their prior values)")
    prior = standard_parameters(model)
    scale = scales(model, prior)
    try:
        est = estimate(W, s, legs, base, prior, scale, model.characteristic_length,
                       np.isin(np.array(NAMES), NOT_HELD))
    except IdentificationError as exc:
        raise IdentificationError(f"{', '.join(str(r.path) for r in runs)}: {exc}") from None
    # the decimated noise is coloured by the window: least squares' covariance is low by this
    # factor (signal.white_noise_factor; the largest of the runs' filters, to stay honest)
    factor = max(white_noise_factor(p.filter) for p in prepared)
    est = dataclasses.replace(est, std=est.std * np.sqrt(factor))
    return Identification(model, prepared, structural, base, est, prior, scale, missing,
                          force_delay)


def _missing(structural: BaseParameters, base: BaseParameters) -> tuple[str, ...]:
    """Standard parameters the structure lets the data determine that these runs do not."""
    if base.rank >= structural.rank:
        return ()
    have = set(structural.alone) | set(structural.combined)
    got = set(base.alone) | set(base.combined)
    lost = [n for n in NAMES if n in have and n not in got]
    return tuple(lost) if lost else tuple(n for n in NAMES if n in base.combined
                                          and n in structural.alone)


def _hint(missing: tuple[str, ...]) -> str:
    said = []
    for name in missing:
        for prefix, words in _HINTS:
            if name.startswith(prefix):
                if words not in said:
                    said.append(words)
                break
    return ", ".join(said) or "richer motion (stewart-sim excite)"


def predict(ident: Identification, run: Run, pi: np.ndarray | None = None) -> Prediction:
    """Forces of `run` predicted from its measured motion with the identified (or `pi`) and
    the prior parameters (full rate, the cut-off of the identification's first run; edges trimmed as
    decimation trims them), and its noise floor: the RMS of the identified model's residual
    above the cut-off (where the motion has no content: what is left there is the sensor's
    noise, and the force's own content there, a Coulomb force's switching, is in the model),
    scaled to the full band as white noise."""
    q = pose_of(ident.model, run)
    filt = choose_filter(run.t, q, ident.prepared[0].filter.cutoff, 1)
    Y = _regressor(ident.model, run, q, filt, ident.force_delay)
    keep = decimated(np.arange(len(run.t)), filt)
    identified = Y @ (ident.pi if pi is None else pi)
    residual = run.sigma - identified
    high = residual - lowpass(residual, filt)
    nyquist = filt.rate / 2
    floor = np.sqrt(np.mean(high[keep] ** 2, axis=0) * nyquist / max(nyquist - filt.cutoff,
                                                                     1e-12))
    return Prediction(run, run.t[keep], run.sigma[keep], identified[keep],
                      (Y @ ident.prior)[keep], floor)


__all__ = ["IdentificationError", "Identification", "Prediction", "Prepared", "identify",
           "predict", "prepare", "N_STANDARD"]
