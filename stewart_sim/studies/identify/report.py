"""The files of `identify`, written all or nothing into DIR (stewart_sim.shell.outputs.result_set):

- identified.toml: the input scene's text with the identified values (scene_out), every other
  key and comment kept; what the runs could not identify keeps its prior value and is listed in
  the report.
- base_parameters.csv: name (the base parameter as a combination of standard ones), estimate,
  std, wls (the unconstrained estimate), prior (the prior scene's value), unit.
- standard_parameters.csv: name, identified (the physically consistent pi), prior, status
  (alone / combined / not identifiable / missing from the runs), unit.
- residuals.png: measured and fitted forces of the first run (filtered, decimated) and the
  residual, per leg.
- validation.png (with --validate): each held-out run's measured forces against the identified
  and the prior model's.
- report.md: the filter, the base parameters with their standard deviations, what is
  identifiable alone, in combination and not at all, the noise level, the residuals, the
  validation (RMS and peak error per leg, identified against prior, and whether at the noise
  floor).
"""
from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.io import atomic_write, write_text
from stewart_fmu.standard import NAMES, UNITS
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.shell.outputs import result_set, written_in
from stewart_sim.shell.plots import save_figure

from .plots import residual_figure, validation_figure
from .scene_out import scene_values, write_identified
from .estimate import IdentificationError
from .refine import Refinement
from .study import Identification, Prediction

FILES = ("identified.toml", "base_parameters.csv", "standard_parameters.csv", "residuals.png",
         "validation.png", "report.md")


def write_identification(ident: Identification, scene_path: str | Path,
                         validation: list[Prediction], out: str | Path,
                         refined: Refinement | None = None) -> list[Path]:
    """Write the files (module docstring) into `out`, all or nothing; their paths. With
    `refined`, identified.toml holds the refined parameters."""
    scene_path = Path(scene_path)
    check_results(ident, validation, refined)
    pi = refined.pi if refined is not None else ident.pi
    values, unheld = scene_values(ident.model, pi, ident.written() | ident.unheld())
    runs = ", ".join(p.run.path.name for p in ident.prepared)
    with result_set(out, FILES) as stage:
        try:
            scene = write_identified(scene_path, values, stage / "identified.toml",
                                     [f"identified by stewart-sim identify from {runs}",
                                      f"prior: {scene_path.name}"])
        except StewartError as exc:     # checked before it is written: name the runs too
            raise StewartError(f"{', '.join(str(p.run.path) for p in ident.prepared)}: "
                               f"{exc}") from None
        paths = [scene,
                 _rows(stage / "base_parameters.csv",
                       ("name", "estimate", "std", "wls", "prior", "unit"), _base_rows(ident)),
                 _rows(stage / "standard_parameters.csv",
                       ("name", "identified", "prior", "status", "unit"), standard_rows(ident)),
                 save_figure(_residuals(ident), stage / "residuals.png")]
        if validation:
            paths.append(save_figure(validation_figure(
                validation[0].t, validation[0].measured, validation[0].identified,
                validation[0].prior, f"held-out run {validation[0].run.path.name}"),
                stage / "validation.png"))
        paths.append(write_text(stage / "report.md",
                                report_text(ident, scene_path, validation, unheld, refined)))
        return written_in(stage, Path(out), paths)


def check_results(ident: Identification, validation: list[Prediction],
                  refined: Refinement | None = None) -> None:
    """Every figure the files and the summary state is finite (and each held-out run has a
    force to compare with), or an IdentificationError naming the runs it came from; called
    before the first file is written."""
    with np.errstate(over="ignore", invalid="ignore"):    # refused below, in one line
        for source, what, arrays in _figures(ident, validation, refined):
            if not all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays):
                raise IdentificationError(f"{source}: {what} is not finite (the inputs' forces "
                                          "or times are beyond what float64 holds): nothing "
                                          "written")


def _figures(ident: Identification, validation: list[Prediction], refined: Refinement | None):
    """(input, what, arrays) of every figure written or printed (check_results)."""
    runs = ", ".join(str(p.run.path) for p in ident.prepared)
    e = ident.estimate
    yield runs, "the estimate", (e.beta, e.std, e.beta_wls, e.pi, e.noise, e.residual_rms)
    if refined is not None:
        yield runs, "the refinement", (refined.beta, refined.pi, refined.bias,
                                       [refined.delay, refined.rms_before, refined.rms_after])
    for v in validation:
        if not v.force_peak > 0.0:
            raise IdentificationError(f"{v.run.path}: every force of the held-out run is zero "
                                      "(after the edges are trimmed): no error relative to its "
                                      "peak")
        yield str(v.run.path), "the validation", (
            v.identified, v.prior, v.noise_floor, v.rms("identified"), v.rms("prior"),
            [v.force_peak])


def _residuals(ident: Identification):
    p = ident.prepared[0]
    fit = ident.fitted(p).reshape(-1, 6)
    return residual_figure(p.t, p.s.reshape(-1, 6), fit,
                           f"{ident.model.name}: run {p.run.path.name} (filtered, decimated)")


def _rows(path: Path, header: tuple[str, ...], rows) -> Path:
    def write(fh):
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)
    return atomic_write(path, write)


def _base_rows(ident: Identification):
    e, prior_beta = ident.estimate, ident.base.beta(ident.prior)
    names = ident.base.names()
    for k in np.argsort(ident.base.independent, kind="stable"):
        name = names[k]
        yield (name, repr(float(e.beta[k])), repr(float(e.std[k])), repr(float(e.beta_wls[k])),
               repr(float(prior_beta[k])), UNITS[ident.base.independent[k]])


def status_of(ident: Identification, name: str) -> str:
    """alone / combined / not identifiable / not excited / absent, for a standard parameter;
    one the runs do not determine that the consistency constraints moved says so."""
    moved = " (moved by the consistency constraints)" if name in ident.estimate.moved else ""
    if name in ident.missing:
        return "not excited by these runs" + moved
    if name in ident.base.alone:
        return "alone"
    if name in ident.base.combined:
        return "in combination"
    if name in ident.base.unidentifiable:
        return "not identifiable" + moved
    return "absent from the scene"


def standard_rows(ident: Identification) -> Iterator[tuple[str, str, str, str, str]]:
    """standard_parameters.csv's rows: each standard parameter's name, identified and prior
    values, status (status_of: alone, in combination, not identifiable, ...) and unit."""
    for k, name in enumerate(NAMES):
        yield (name, repr(float(ident.pi[k])), repr(float(ident.prior[k])),
               status_of(ident, name), UNITS[k])


def report_text(ident: Identification, scene_path: Path, validation: list[Prediction],
                unheld: dict[str, float], refined: Refinement | None = None) -> str:
    """report.md (module docstring)."""
    e, b, f = ident.estimate, ident.base, ident.prepared[0].filter
    rel = e.std / np.maximum(np.abs(e.beta), 1e-300)
    lines = [f"# Identification of {md_text(ident.model.name)}", "",
             f"Prior scene: {md_code(scene_path)}. Runs: "
             + ", ".join(f"{md_code(p.run.path.name)} ({len(p.run.t)} samples, forces from "
                         f"{md_text(p.run.source)})" for p in ident.prepared) + ".", "",
             "## Data", "",
             f"- Filter: zero-phase low-pass at {f.cutoff:.4g} Hz on the pose (its derivatives "
             f"taken with it), the same on the regressor's columns and the measured forces "
             f"(parallel filtering); sampled at {f.rate:.6g} Hz, decimated by {f.decimate}.",
             f"- Rows: {e.samples} (samples x legs) for {b.rank} base parameters; the scene's "
             f"structure allows {ident.structural.rank} of its {len(b.columns)} standard "
             "parameters' combinations.",
             "- Noise level per leg (from the residuals, filtered band), N: "
             + ", ".join(f"{x:.4g}" for x in e.noise),
             "- Residual RMS per leg, N: " + ", ".join(f"{x:.4g}" for x in e.residual_rms), ""]
    if ident.missing:
        lines += [f"Not excited by these runs (kept at their prior values): "
                  f"{', '.join(ident.missing)}.", ""]
    lines += ["## Base parameters", "",
              "Weighted least squares; std from its covariance. "
              + ("The WLS estimate was not physically consistent: the estimate below is the "
                 "constrained fit (semidefinite program, cvxpy + Clarabel); `wls` is the "
                 "unconstrained one." if e.constrained else
                 "The WLS estimate is physically consistent (a consistent set of standard "
                 "parameters reproduces it exactly)."), "",
              "| base parameter | estimate | std | std / estimate | prior | unit |",
              "|---|---|---|---|---|---|"]
    prior_beta = b.beta(ident.prior)
    names = b.names()
    for k in np.argsort(b.independent, kind="stable"):   # in the standard parameters' order
        name = names[k]
        lines.append(f"| {name} | {e.beta[k]:.6g} | {e.std[k]:.3g} | {rel[k]:.2%} | "
                     f"{prior_beta[k]:.6g} | {UNITS[b.independent[k]]} |")
    lines += ["", "## What the runs determine", "",
              f"- Alone ({len(b.alone)}): {', '.join(b.alone) or 'none'}",
              f"- Only in combination ({len(b.combined)}): {', '.join(b.combined) or 'none'} "
              "(identified.toml holds the consistent split nearest the prior)",
              f"- Not at all ({len(b.unidentifiable)}): {', '.join(b.unidentifiable) or 'none'} "
              "(kept at the prior" + (", except as below" if e.moved else "") + ")", ""]
    if e.moved:
        lines += _moved_lines(ident)
    if unheld:
        lines += _unheld_lines(ident, unheld)
    if refined is not None:
        lines += _refinement_lines(ident, refined)
    if validation:
        lines += ["## Validation on held-out runs", "",
                  "Forces predicted from each run's measured motion (full rate) against the "
                  "measured ones. Noise floor: the RMS of the identified model's residual "
                  "above the cut-off, scaled to the full band.", ""]
        for v in validation:
            lines += _validation_lines(v)
    return "\n".join(lines) + "\n"


def percent(x: float) -> str:
    """x as a percentage: three decimals, or four significant digits from 1000 % and below
    0.001 % (a round-off figure is not shown as zero)."""
    return f"{x:.3%}" if 1e-5 <= abs(x) < 10.0 or x == 0.0 else f"{100.0 * x:.4g}%"


def _unheld_lines(ident: Identification, unheld: dict[str, float]) -> list[str]:
    """The identified values the scene cannot hold, and what writing them as zero costs: the
    largest change of the model's forces on the identification's rows."""
    pi = np.array([unheld.get(n, 0.0) for n in NAMES])
    W = np.vstack([p.W for p in ident.prepared])
    s = np.concatenate([p.s for p in ident.prepared])
    change = float(np.max(np.abs(W @ pi)))
    peak = float(np.max(np.abs(s)))
    return ["Identified but not representable in a scene (the scene's model holds the "
            "platform's centre of mass at C and its principal axes along the platform frame); "
            "identified.toml has them at zero: "
            + ", ".join(f"{k} = {v:.4g} {UNITS[NAMES.index(k)]}" for k, v in unheld.items())
            + f". Zeroing them changes the model's forces on the identification runs by "
              f"{change:.3g} N at most ({percent(change / peak)} of the force peak).", ""]


def body_of(name: str) -> str:
    """The body a standard parameter belongs to: platform, legs.lower_, legs.upper_, or the
    name itself (a drive or a friction, one leg's)."""
    for prefix in ("platform.", "legs.lower_", "legs.upper_"):
        if name.startswith(prefix):
            return prefix
    return name


def _moved_lines(ident: Identification) -> list[str]:
    """Which parameters the runs do not determine moved off the prior, and which identified
    combinations made them (those of the same body)."""
    b, e = ident.base, ident.estimate
    names = b.names()
    out = ["Moved off the prior although the runs do not determine them: no physically "
           "consistent set of standard parameters reproduces the identified base parameters "
           "with their prior values (the body's pseudo-inertia would not be positive "
           "semidefinite), so they take the least change, in the prior's scale, that makes one:",
           ""]
    for name in e.moved:
        k = NAMES.index(name)
        body = body_of(name)
        why = [names[i] for i in range(b.rank) if any(
            b.combination[i, j] != 0.0 and body_of(NAMES[j]) == body
            for j in range(len(NAMES)))]
        out.append(f"- {name}: prior {ident.prior[k]:.6g}, written {e.pi[k]:.6g} "
                   f"{UNITS[k]}; held by the identified {'; '.join(why) or 'base parameters'}")
    return out + [""]


def _validation_lines(v: Prediction) -> list[str]:
    peak = v.force_peak
    out = [f"### {md_code(v.run.path.name)} (force peak {peak:.4g} N)", "",
           "| leg | RMS identified (N) | RMS prior (N) | peak identified (N) | peak prior (N) "
           "| noise floor (N) | RMS / floor |", "|---|---|---|---|---|---|---|"]
    ri, rp, pi, pp = v.rms("identified"), v.rms("prior"), v.peak("identified"), v.peak("prior")
    for j in range(6):
        out.append(f"| {j + 1} | {ri[j]:.4g} | {rp[j]:.4g} | {pi[j]:.4g} | {pp[j]:.4g} | "
                   f"{v.noise_floor[j]:.4g} | {ri[j] / max(v.noise_floor[j], 1e-300):.3g} |")
    out += ["", f"RMS error over all legs: identified {percent(v.rms_error('identified'))} of "
            f"the peak, prior {percent(v.rms_error('prior'))}. "
            + ("The residual is at the noise floor (within 1.2x on every leg)."
               if v.at_noise_floor() else
               "The residual is above the noise floor (more than 1.2x on some leg): the model "
               "misses something the data hold, or the runs excite it too little."), ""]
    return out


def _refinement_lines(ident: Identification, r: Refinement) -> list[str]:
    names, e = ident.base.names(), ident.estimate
    out = ["## Output-error refinement", "",
           f"{r.segments} segments simulated from the measured state with the measured forces "
           f"({r.evaluations} evaluations of scipy's least_squares). Leg length RMS residual "
           f"{r.rms_before * 1e6:.4g} um at the least-squares estimate, {r.rms_after * 1e6:.4g} "
           f"um refined. identified.toml holds the refined values. Standard deviations from the "
           "Jacobian at the solution.", "",
           f"- Force delay: {r.delay * 1e3:.4g} ms +- {r.delay_std * 1e3:.2g} ms (the force "
           "measured at t was applied at t - delay)",
           "- Force bias per leg (measured - applied), N: "
           + ", ".join(f"{b:.4g} +- {s:.2g}" for b, s in zip(r.bias, r.bias_std)), "",
           "| base parameter | least squares | refined | std (refined) |", "|---|---|---|---|"]
    for j, k in enumerate(r.refined):
        out.append(f"| {names[k]} | {e.beta[k]:.6g} | {r.beta[k]:.6g} | {r.std[j]:.3g} |")
    return out + [""]
