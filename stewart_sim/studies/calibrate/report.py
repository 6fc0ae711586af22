"""The files of `calibrate`, written all or nothing into DIR (stewart_sim.shell.outputs.result_set):

- calibrated.toml: the input scene's text with [geometry] base_joints and platform_joints
  replaced by the estimates (every other key and comment kept); it is read back and checked as
  any scene before it is written.
- offsets.csv: leg, offset, std (m): the leg-length offsets delta_i of the measurement model
  l_i = |x + R p_i - a_i| + delta_i. The scene format has no place for them (an unknown key is
  refused): a controller or the encoder's zero subtracts delta_i from the reported length.
- calibration.csv: parameter, nominal, estimate, std (m), observable (1/0), the 42 parameters.
- residuals.png: per-leg residuals (um) against the pose's row in the poses file.
- report.md: observability (scaled singular values, weakest and unobservable directions), the
  estimates with their standard deviations, residual RMS per leg, the pose selection.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stewart_fmu.errors import StewartError
from stewart_fmu.io import atomic_write, write_text
from stewart_fmu.scene import parse_scene_bytes, scene_from_dict
from stewart_sim.scene.load import scene_of
from stewart_sim.shell.markdown import md_text
from stewart_sim.shell.outputs import result_set, written_in
from stewart_sim.shell.plots import LEG_COLOURS, save_figure
from stewart_sim.studies.calibrate.study import OBSERVABLE_RTOL, Calibration, CalibrationError

FILES = ("calibrated.toml", "offsets.csv", "calibration.csv", "residuals.png", "report.md")
UM = 1e6   # m -> um in the report and the figure


def write_calibration(cal: Calibration, scene_path: str | Path, poses_path: str | Path,
                      out: str | Path) -> list[Path]:
    """Write FILES into `out` (all or nothing); returns their paths."""
    scene_path = Path(scene_path)
    text = calibrated_scene_text(scene_path.read_text(encoding="utf-8"), cal, str(scene_path))
    with result_set(out, FILES) as stage:
        paths = [write_text(stage / "calibrated.toml", text),
                 _write_rows(stage / "offsets.csv", ("leg", "offset", "std"),
                             [(i + 1, float(cal.offsets[i]), float(cal.offsets_std[i]))
                              for i in range(6)]),
                 _write_rows(stage / "calibration.csv",
                             ("parameter", "nominal", "estimate", "std", "observable"),
                             [(n, float(a), float(b), float(s), int(o)) for n, a, b, s, o in
                              zip(cal.names, cal.nominal, cal.estimate, cal.std,
                                  cal.observable)]),
                 save_figure(residuals_figure(cal, Path(poses_path).name),
                             stage / "residuals.png"),
                 write_text(stage / "report.md", report_text(cal, scene_path, poses_path))]
        return written_in(stage, Path(out), paths)


def calibrated_scene_text(text: str, cal: Calibration, source: str) -> str:
    """The scene's text with the two joint arrays replaced, checked by reading it back."""
    for key, joints in (("base_joints", cal.base_joints), ("platform_joints",
                                                           cal.platform_joints)):
        text = _replace_array(text, key, joints, source)
    data = parse_scene_bytes(text.encode("utf-8"), source)
    geometry = data.get("geometry", {})
    if not (np.array_equal(geometry.get("base_joints"), cal.base_joints)
            and np.array_equal(geometry.get("platform_joints"), cal.platform_joints)):
        raise CalibrationError(f"{source}: the joint arrays could not be rewritten in place")
    try:
        scene_of(scene_from_dict(data, source))
    except StewartError as exc:   # a rule the new joints break (home outside the stroke ...)
        raise CalibrationError(f"{source}: the calibrated joints make an invalid scene: "
                               f"{exc}") from None
    return text


def _replace_array(text: str, key: str, joints: np.ndarray, source: str) -> str:
    """Replace `key = [...]` (a line of its own, the array over any number of lines) with the
    joints written repr-exact."""
    starts = [m.end() - 1 for m in re.finditer(rf"^[ \t]*{key}[ \t]*=[ \t]*\[", text, re.M)]
    if len(starts) != 1:
        raise CalibrationError(f"{source}: cannot rewrite '{key}' in place: expected one line "
                               f"'{key} = [' in [geometry], found {len(starts)}")
    start, depth, k = starts[0], 0, starts[0]
    while k < len(text):
        c = text[k]
        if c == "#":                                 # a comment runs to the end of its line
            k = text.find("\n", k)
            k = len(text) if k < 0 else k
            continue
        depth += (c == "[") - (c == "]")
        if depth == 0:
            break
        k += 1
    rows = "".join(f"    [{', '.join(repr(float(v)) for v in row)}],\n" for row in joints)
    return text[:start] + "[\n" + rows + "]" + text[k + 1:]


def _write_rows(path: Path, header: tuple[str, ...], rows: list[tuple]) -> Path:
    """A small CSV, floats repr-exact, atomically."""
    def write(fh) -> None:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows([[repr(v) if isinstance(v, float) else v for v in row] for row in rows])
    return atomic_write(path, write)


def residuals_figure(cal: Calibration, poses_name: str) -> Figure:
    """Per-leg residuals (um) against the pose's row in the poses file (1 = first)."""
    fig = Figure(figsize=(8, 4.5))
    ax = fig.add_subplot()
    rows = cal.used + 1
    for i in range(6):
        ax.plot(rows, cal.residuals[:, i] * UM, "o-", ms=3, lw=0.8, color=LEG_COLOURS[i],
                label=f"leg {i + 1} (RMS {cal.rms[i] * UM:.3g} um)")
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlabel(f"pose (row of {poses_name}, 1 = first)")
    ax.set_ylabel("residual measured - model (um)")
    ax.set_title(f"Leg-length residuals after calibration, {len(rows)} poses")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def report_text(cal: Calibration, scene_path: Path, poses_path: str | Path) -> str:
    """report.md."""
    sv = cal.singular_values
    lines = [f"# Kinematic calibration of {md_text(scene_path.name)}", "",
             f"Poses: {md_text(poses_path)}, {len(cal.used)} used"
             + (" (chosen by greedy D-optimal selection from the candidates)" if cal.selected
                else "") + ".",
             "Model: l_i = |x + R p_i - a_i| + delta_i (delta_i: the leg-length offset, what "
             "the encoder reads beyond the joint-to-joint distance); Levenberg-Marquardt per "
             "leg from the scene's joints and zero offsets.", "",
             "## Observability", "",
             f"Scaled condition number of the identification Jacobian: {cal.cond:.4g} "
             "(columns scaled to unit norm).", "",
             "| leg | scaled singular values (largest to smallest) | weakest direction |",
             "|---|---|---|"]
    lines += [f"| {i + 1} | {' '.join(f'{v:.3g}' for v in sv[i])} | {cal.weakest[i]} |"
              for i in range(6)]
    lines += ["", ("Not observable (scaled singular value below "
                   f"{OBSERVABLE_RTOL:g} of the largest): " + "; ".join(cal.unobservable))
              if cal.unobservable else
              f"All 42 parameters are observable from these poses (smallest scaled singular "
              f"value {sv.min():.3g}, {sv.min() / sv.max():.3g} of the largest)."]
    lines += ["", "## Estimates", "",
              "| parameter | nominal (m) | estimate (m) | change (um) | std (um) |",
              "|---|---|---|---|---|"]
    for n, a, b, s, o in zip(cal.names, cal.nominal, cal.estimate, cal.std, cal.observable):
        std = f"{s * UM:.3g}" if o else "not observable"
        lines.append(f"| {n} | {a:.6g} | {b:.9g} | {(b - a) * UM:+.3f} | {std} |")
    lines += ["", "## Residuals", "",
              "| leg | RMS nominal (um) | RMS calibrated (um) |"
              + (" RMS on the poses not used (um) |" if cal.held_out_rms is not None else ""),
              "|---|---|---|" + ("---|" if cal.held_out_rms is not None else "")]
    for i in range(6):
        held = (f" {cal.held_out_rms[i] * UM:.3g} |" if cal.held_out_rms is not None else "")
        lines.append(f"| {i + 1} | {cal.nominal_rms[i] * UM:.4g} | {cal.rms[i] * UM:.3g} |"
                     + held)
    lines += ["", "Files: calibrated.toml (the scene with the estimated joints), offsets.csv "
              "(delta_i: subtract from the encoder's length), calibration.csv, residuals.png.",
              ""]
    return "\n".join(lines)
