"""The identified scene: standard parameters back into the scene's keys, written into the input
scene's text.

scene_values maps standard parameters pi (stewart_fmu.standard.NAMES) to the scene keys they
set, merging the identified entries into the prior's (the scene's own standard parameters):

- platform.mass = m; platform.inertia = the diagonal (xx, yy, zz) of the inertia tensor about
  C. The scene holds neither a first moment (its model puts the centre of mass at C) nor
  products of inertia: identified values of those are returned apart, for the report to list.
- legs.<part>_mass = m, legs.<part>_com = (m c) / m, legs.<part>_inertia = [J - (m c)^2 / m,
  axial], J the transverse moment about the part's joint (I_t + m c^2). The lower part turns
  about its base joint without translating, so its mass acts only through m c and J: it is
  not identifiable, keeps the prior mass, and the com written is (m c) / m_prior, I_t =
  J - (m c)^2 / m_prior; the written scene then has exactly the identified m c and J.
- drive.rotor_inertia = m_d r^2 / zeta^2 per leg (m_d = zeta^2 I / r^2, DriveParams.
  reflected_masses); friction.viscous and friction.coulomb per leg. Per-leg keys are written
  as lists of six.

A standard parameter not identified keeps the prior's value, so the written scene's standard
parameters are the identified ones where identified and the prior's elsewhere (platform first
moment and products of inertia: zero, as the scene's model has them). A key is written only
when one of the parameters it depends on is identified.

write_identified edits the scene's TOML text with tomlkit (every other key, comment and the
layout kept), reads the result back as any scene (it must load) and writes it atomically.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Union

import numpy as np
import tomlkit

from stewart_fmu.errors import StewartError
from stewart_fmu.io import write_text
from stewart_fmu.model import Model
from stewart_fmu.scene import parse_scene_bytes, read_scene_bytes, scene_from_dict
from stewart_fmu.standard import ENTRIES, NAMES, present, span, standard_parameters
from stewart_sim.scene.load import scene_of

Value = Union[float, list]
# The standard parameters the scene cannot hold (its model has the centre of mass at C and
# principal axes along the platform frame's).
NOT_HELD = ("platform.first_moment.x", "platform.first_moment.y", "platform.first_moment.z",
            "platform.inertia_tensor.xy", "platform.inertia_tensor.xz",
            "platform.inertia_tensor.yz")


def scene_values(model: Model, pi: np.ndarray, identified: Iterable[str]
                 ) -> tuple[dict[str, Value], dict[str, float]]:
    """(scene key -> value for the keys the identified parameters set, standard name -> value
    of the identified parameters the scene cannot hold); see the module doc. `identified`:
    names of NAMES, each one the scene can hold (stewart_fmu.standard.present)."""
    pi = np.asarray(pi, dtype=float)
    ids = set(identified)
    unknown = sorted(ids - set(NAMES))
    if unknown:
        raise ValueError(f"not standard parameters: {unknown}")
    held = present(model)
    absent = sorted(n for n in ids if not held[NAMES.index(n)])
    if absent:
        raise ValueError(f"the scene has no table for {absent}")
    mask = np.array([n in ids for n in NAMES])
    merged = np.where(mask, pi, standard_parameters(model))

    def any_of(*entries: str) -> bool:
        return any(mask[span(e)].any() for e in entries)

    values: dict[str, Value] = {}
    if any_of("PLATFORM_MASS"):
        values["platform.mass"] = float(merged[span("PLATFORM_MASS")][0])
    tensor = dict(zip(ENTRIES["PLATFORM_INERTIA"].columns, merged[span("PLATFORM_INERTIA")]))
    diagonal = [f"platform.inertia_tensor.{a}" for a in ("xx", "yy", "zz")]
    if ids & set(diagonal):
        values["platform.inertia"] = [float(tensor[k]) for k in diagonal]
    for part in ("lower", "upper"):
        name = part.upper()
        m, mc, joint, axial = (float(merged[span(f"{name}_{e}")][0])
                               for e in ("MASS", "MOMENT", "INERTIA", "AXIAL"))
        if any_of(f"{name}_MASS"):
            values[f"legs.{part}_mass"] = m
        if any_of(f"{name}_MASS", f"{name}_MOMENT"):
            values[f"legs.{part}_com"] = _ratio(mc, m, f"legs.{part}_com")
        if any_of(f"{name}_MASS", f"{name}_MOMENT", f"{name}_INERTIA", f"{name}_AXIAL"):
            values[f"legs.{part}_inertia"] = [joint - mc * _ratio(mc, m, f"legs.{part}_com"),
                                              axial]
    if any_of("DRIVE_MASS"):
        d = model.drive
        values["drive.rotor_inertia"] = (merged[span("DRIVE_MASS")] * d.pinion_radius**2
                                         / d.gear_ratio**2).tolist()
    for entry, key in (("VISCOUS", "friction.viscous"), ("COULOMB", "friction.coulomb")):
        if any_of(entry):
            values[key] = merged[span(entry)].tolist()
    not_held = {n: float(pi[NAMES.index(n)]) for n in NOT_HELD if n in ids}
    return values, not_held


def _ratio(mc: float, m: float, key: str) -> float:
    if not m > 0:
        raise StewartError(f"scene key '{key}': the identified mass {m!r} kg is not positive: "
                           f"no centre of mass to write")
    return mc / m


def write_identified(scene_path: str | Path, values: dict[str, Value], out_path: str | Path,
                     header_lines: Iterable[str]) -> Path:
    """Write the scene at scene_path with `values` (scene_values) in place of its own, each
    header line a comment at the top (the source runs), to out_path, atomically. The new text
    is read back as a scene first: values that make an invalid scene (a rule between keys) are
    a StewartError naming the key, and nothing is written."""
    return write_text(out_path, _scene_text(scene_path, values, header_lines))


def _scene_text(scene_path: str | Path, values: dict[str, Value],
                header_lines: Iterable[str]) -> str:
    """The text write_identified writes, checked by loading it (see there)."""
    source = str(scene_path)
    doc = tomlkit.parse(read_scene_bytes(scene_path).decode("utf-8"))
    for key, value in values.items():
        table, name = key.split(".")
        if table not in doc or name not in doc[table]:
            raise ValueError(f"{source}: no key '{key}' to replace")
        doc[table][name] = ([float(v) for v in value] if isinstance(value, (list, tuple))
                            else float(value))
    header = [part for line in header_lines for part in (str(line).splitlines() or [""])]
    text = "".join(f"# {line}".rstrip() + "\n" for line in header) + tomlkit.dumps(doc)
    data = parse_scene_bytes(text.encode("utf-8"), source)
    try:
        scene_of(scene_from_dict(data, source))
    except StewartError as exc:
        raise StewartError(f"{source}: the identified values make an invalid scene: "
                           f"{exc}") from None
    for key, value in values.items():    # what a reader gets back is what was identified
        table, name = key.split(".")
        if not np.array_equal(np.asarray(data[table][name], dtype=float),
                              np.asarray(value, dtype=float)):
            raise StewartError(f"{source}: scene key '{key}' could not be rewritten in place")
    return text
