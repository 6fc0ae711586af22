"""The standard parameters of the identification model: sigma = Y(q, qd, qdd) pi.

pi holds the inertial and friction parameters on which the inverse dynamics depends linearly
(the STEWART_STANDARD table of native/include/stewart_table.h, read here from the core as
table.py reads the packed layout): the platform's mass, first moment and inertia tensor about C;
each leg part's mass, first moment and transverse moment about its joint and its axial moment;
the drives' reflected masses and the joints' viscous and Coulomb friction, per leg.
dynamics.regressor gives Y; `standard_parameters` a Model's pi;
stewart_sim.studies.identify.scene_out turns a pi back into the scene's keys (for an identified
scene).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Model
from .native.core import ffi, lib

N_STANDARD: int = lib.STEWART_N_STANDARD
_AXES = ("x", "y", "z")
_TENSOR = ("xx", "xy", "xz", "yy", "yz", "zz")


@dataclass(frozen=True)
class Standard:
    """One entry of the standard parameters: `count` columns of Y from `column`."""

    name: str           # STEWART_S_<name>
    key: str            # dotted name ("platform.first_moment")
    column: int
    count: int
    unit: str
    description: str

    @property
    def columns(self) -> tuple[str, ...]:
        """The names of its columns: the key, or key.x/.y/.z, key.xx.., key.1..6 per leg."""
        if self.count == 1:
            return (self.key,)
        suffix = {3: _AXES, 6: _TENSOR if self.name == "PLATFORM_INERTIA" else
                  tuple(str(i) for i in range(1, 7))}[self.count]
        return tuple(f"{self.key}.{s}" for s in suffix)


def _read() -> tuple[Standard, ...]:
    text = lambda p: ffi.string(p).decode()  # noqa: E731
    rows = (lib.stewart_standard_table[k] for k in range(lib.stewart_standard_table_size))
    return tuple(Standard(text(r.name), text(r.key), r.column, r.count, text(r.unit),
                          text(r.description)) for r in rows)


STANDARD: tuple[Standard, ...] = _read()
ENTRIES: dict[str, Standard] = {s.name: s for s in STANDARD}
NAMES: tuple[str, ...] = tuple(c for s in STANDARD for c in s.columns)
UNITS: tuple[str, ...] = tuple(s.unit for s in STANDARD for _ in range(s.count))


def span(name: str) -> slice:
    """The columns of STEWART_S_<name> in pi and Y."""
    s = ENTRIES[name]
    return slice(s.column, s.column + s.count)


def standard_parameters(model: Model) -> np.ndarray:
    """pi of a model: the values of its scene in the standard parameters (zero for the effects
    it lacks; the platform's first moment and products of inertia are zero but for a
    [payload], which joins the platform: its mass, its first moment m c and its inertia moved
    to C, I_c + m (|c|^2 I - c c^T))."""
    pi = np.zeros(N_STANDARD)
    pi[span("PLATFORM_MASS")] = model.platform_mass
    tensor = np.diag(model.platform_inertia)
    if model.payload is not None:
        m, c = model.payload.mass, np.asarray(model.payload.com)
        pi[span("PLATFORM_MASS")] += m
        pi[span("PLATFORM_MOMENT")] = m * c
        tensor = tensor + model.payload.inertia_tensor + m * ((c @ c) * np.eye(3) - np.outer(c, c))
    pi[span("PLATFORM_INERTIA")] = tensor[np.triu_indices(3)]
    if model.legs is not None:
        lg = model.legs
        for part, m, c, (it, ia) in (("LOWER", lg.lower_mass, lg.lower_com, lg.lower_inertia),
                                     ("UPPER", lg.upper_mass, lg.upper_com, lg.upper_inertia)):
            pi[span(f"{part}_MASS")] = m
            pi[span(f"{part}_MOMENT")] = m * c
            pi[span(f"{part}_INERTIA")] = it + m * c * c
            pi[span(f"{part}_AXIAL")] = ia
    if model.drive is not None:
        pi[span("DRIVE_MASS")] = model.drive.reflected_masses
    if model.friction is not None:
        pi[span("VISCOUS")] = model.friction.viscous_legs
        pi[span("COULOMB")] = model.friction.coulomb_legs
    return pi


def present(model: Model) -> np.ndarray:
    """Which standard parameters a model's scene can hold (bool per column): the platform's
    always, the legs', drives' and friction's when it has those tables."""
    has = np.zeros(N_STANDARD, dtype=bool)
    has[:span("PLATFORM_INERTIA").stop] = True
    for name, table in (("LOWER", model.legs), ("UPPER", model.legs), ("DRIVE", model.drive)):
        if table is not None:
            for s in STANDARD:
                if s.name.startswith(name):
                    has[span(s.name)] = True
    if model.friction is not None:
        has[span("VISCOUS")] = has[span("COULOMB")] = True
    return has
