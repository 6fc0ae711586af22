"""A candidate flying the design's motions (design.toml [motions], [drives]): its margins, named
`motion_<limit>` for the feasibility engine's limits and as `size` names its drive checks.

Along every motion (about the candidate's home, every `every`-th sample in the search, every
sample in the dense check), with the candidate's payload and drive:
- every limit of the feasibility engine (stewart_fmu.reach.Engine with rates and
  accelerations): the stroke, the joint cones, leg and obstacle clearance where the base scene
  has them, cond(J) below the requirement's limit, and the drives' bounds: with the base
  scene's drive, controller.capability's (the no-load speed, the peak acceleration of the
  constant load, the peak rack force Kf I_max, the rack force by the inverse dynamics); with a
  catalogue drive, the peak acceleration of the constant load (peak torque zeta / r over the
  constant load plus the reflected inertia, as controller.drive.AxisModel defines it);
- with a catalogue drive, `size`'s checks of the drive's ratings, the same call on the
  candidate's model (stewart_sim.studies.sizing.study.drive_result, evaluate_drive's):
  torque_peak, torque_rms, motor_speed;
- with the base scene's drive, `size`'s checks of its motor, the same call
  (stewart_sim.studies.sizing.study.size_scene): the current and the voltage the motor needs
  for the rack force (controller.drive.AxisModel.drive_for) against its current_limit and
  voltage_limit.
Every drive bound and rating keeps `margin` free (size's --margin: demand (1 + margin) <=
rating); a relative margin is what is left of the bound so derated (of the stroke, the cone,
the characteristic length, the cond(J) limit as for the workspace)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from controller.capability import capability
from controller.drive import constant_load
from stewart_fmu.errors import StewartError
from stewart_fmu.reach import DriveBounds, Engine, where_text

from .margin import FAILED, UNITS, Margin

ENGINE = ("stroke_min", "stroke_max", "base_cone", "platform_cone", "leg_clearance",
          "obstacle", "cond", "speed", "acceleration", "force")
ENGINE_UNITS = {**UNITS, "speed": "m/s", "acceleration": "m/s2", "force": "N"}
RATINGS = ("torque_peak", "torque_rms", "motor_speed")   # size's CANDIDATE_CHECKS
MOTOR = ("current", "voltage")      # size's checks of the scene's own motor

def flight_names(spec, geometric: tuple[str, ...]) -> tuple[str, ...]:
    """The motions' requirements of `spec` (none without [motions]): the engine's limits the
    workspace has (`geometric`) and the drive's, then the catalogue drive's ratings."""
    fl = spec.flight
    if fl is None:
        return ()
    drive = ("acceleration",) if fl.drives is not None else ("speed", "acceleration", "force")
    names = [f"motion_{n}" for n in ENGINE if n in geometric or n in drive]
    names += list(RATINGS if fl.drives is not None else MOTOR)
    return tuple(names)


def drive_bounds(spec, model, drive) -> DriveBounds:
    """The drives' bounds along the motions, each derated by the margin: the base scene's
    (capability) or a catalogue drive's acceleration bound."""
    fl = spec.flight
    keep = 1.0 + fl.margin
    if drive is None:
        b = capability(model, fl.controller).drive
        return DriveBounds(b.speed / keep, b.acceleration / keep, b.force / keep)
    peak_force = drive.peak_torque * drive.gear_ratio / drive.pinion_radius
    reflected = drive.gear_ratio**2 * drive.rotor_inertia / drive.pinion_radius**2
    return DriveBounds(None, peak_force / (constant_load(model) + reflected) / keep, None)


def flight_margins(spec, model, values: dict[str, float], names: tuple[str, ...],
                   every: int) -> dict[str, Margin]:
    """Each of the motions' requirements among `names` over every motion: the least margin and
    where (`model`: the candidate's, its catalogue drive in place)."""
    names = tuple(n for n in names if n.startswith("motion_") or n in RATINGS + MOTOR)
    fl = spec.flight
    drive = spec.drive(values)
    home = np.asarray(model.home, dtype=float)
    motions = [_thinned(m, home, every) for m in fl.motions]
    out: dict[str, Margin] = {}
    try:
        bounds = drive_bounds(spec, model, drive)
        engine = Engine(model, bounds, spec.requirements.cond_limit)
        scale = _scales(spec, model, values, bounds)
        for m in motions:
            res = engine.check(m.q, m.qd, m.qdd)
            for lim in engine.present(True, True):
                name = f"motion_{lim.name}"
                if name not in names:
                    continue
                k = int(np.argmin(res[lim.name]))
                value = float(res[lim.name][k])
                at = where_text(lim.index, int(res[f"{lim.name}_at"][k]))
                where = f"{m.name} t={m.t[k]:.4g} s {at}"
                _keep(out, Margin(name, value, ENGINE_UNITS[lim.name], value / scale[lim.name],
                                  where.rstrip()))
        if drive is not None:
            _ratings(out, model, drive, motions, fl.margin)
        else:
            _motor(out, model, fl.controller, motions, fl.margin)
    except StewartError as exc:      # a pose the dynamics refuse, a drive the scene refuses
        why = str(exc)[:80]
        return {n: Margin(n, float("nan"), "", FAILED, why) for n in names}
    return {n: out.get(n, Margin(n, float("nan"), "", FAILED, "not computed")) for n in names}


def _ratings(out: dict, model, drive, motions, margin: float) -> None:
    """size's checks of a catalogue drive's ratings (evaluate_drive's, on the candidate's model
    that has the drive's [drive] table), relative to the rating derated by the margin."""
    from stewart_sim.studies.sizing.study import drive_result

    r = drive_result(model, drive, motions)
    if r.error is not None:
        raise StewartError(r.error)
    keep = 1.0 + margin
    for cm in r.motions:
        for c in cm.checks:
            at = "" if not np.isfinite(c.t) else f" t={c.t:.4g} s"
            leg = f" leg {c.leg}" if c.leg else ""
            _keep(out, Margin(c.quantity, c.limit / keep - abs(c.value), c.unit,
                              1.0 - c.ratio * keep, f"{cm.motion}{at}{leg}"))


def _motor(out: dict, model, controller, motions, margin: float) -> None:
    """size's checks of the scene's own motor (size_scene), relative to the limit derated by
    the margin."""
    from stewart_sim.studies.sizing.study import size_scene

    sizing = size_scene(model, controller, motions)
    keep = 1.0 + margin
    for m, checks in zip(motions, sizing.checks):
        for c in checks:
            if c.quantity in MOTOR:
                _keep(out, Margin(c.quantity, c.limit / keep - abs(c.value), c.unit,
                                  1.0 - c.ratio * keep, f"{m.name} t={c.t:.4g} s leg {c.leg}"))


def _scales(spec, model, values: dict, bounds: DriveBounds) -> dict[str, float]:
    r = spec.requirements
    return {"stroke_min": values["stroke"], "stroke_max": values["stroke"],
            "base_cone": r.base_cone, "platform_cone": r.platform_cone,
            "leg_clearance": model.characteristic_length,
            "obstacle": model.characteristic_length, "cond": r.cond_limit,
            "speed": bounds.speed, "acceleration": bounds.acceleration, "force": bounds.force}


def _keep(out: dict, m: Margin) -> None:
    """The least relative margin of a requirement over the motions."""
    if m.name not in out or m.relative < out[m.name].relative:
        out[m.name] = m


def _thinned(m, home: np.ndarray, every: int):
    """The motion about `home`, every `every`-th sample (the last always kept)."""
    rows = np.unique(np.r_[np.arange(0, len(m.t), every), len(m.t) - 1])
    return replace(m, t=m.t[rows], q=m.q[rows] + home, qd=m.qd[rows], qdd=m.qdd[rows])
