"""Compliant transmission: each drive's inertia on its own coordinate, sprung to its leg.

A scene's [transmission] table (stiffness k in N/m, damping c in N s/m, both reflected to the
leg axis) gives every leg a motor-side coordinate s_i (the rack position on the leg axis) that
carries the reflected drive inertia m_d = zeta^2 I / r^2. The rack force F_i (the plant's input)
acts on the motor side; the leg gets the spring-damper force

    f_i = k (s_i - l_i) + c (sd_i - ld_i),       m_d sdd_i = F_i - f_i,

and the platform and legs move under f as under sigma of a drive-less model (Kane's equations
without [m_d]). The plant's state grows from y = (q, qd) to y = (q, qd, s, sd). As k -> inf,
s -> l and the rigid drive of Eq. 12 is recovered (tested). inverse_dynamics and
forward_dynamics keep the rigid drive: they are that limit. The derivative itself is the C
core's (native/src/transmission.c); this module holds its Python face.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .kane_terms import mass_matrix
from .model import Model
from .native import core


def spring_forces(model: Model, y: np.ndarray) -> np.ndarray:
    """The transmission forces f_i on the legs (N) at the 24-state y."""
    forces, _ = core.spring_forces(model.native, np.ascontiguousarray(y, dtype=float))
    return forces


def initial_state(model: Model, q: np.ndarray, qd: np.ndarray,
                  rack_force: np.ndarray | None = None) -> np.ndarray:
    """The plant state at pose q and rates qd: (q, qd), and with a transmission the motor side
    moving with the legs (sd = ld) and preloaded to carry `rack_force` (s = l + F / k)."""
    def vector(a):
        return np.ascontiguousarray(a, dtype=float)

    return core.initial_state(model.native, vector(q), vector(qd),
                              None if rack_force is None else vector(rack_force))


def natural_frequencies(model: Model, q: np.ndarray) -> np.ndarray:
    """Linearised transmission modes at pose q (rad/s, ascending): the springs k between the
    drive inertias m_d,i and the leg side's leg-space mass [m], omega^2 = eig(k ([m_d]^-1 +
    [m]^-1)); gravity's geometric stiffness and the damping left out."""
    m = mass_matrix(replace(model, drive=None, transmission=None), q)
    k, md = model.transmission.stiffness, model.drive.reflected_masses
    w2 = np.linalg.eigvals(k * (np.diag(1.0 / md) + np.linalg.inv(m)))
    return np.sqrt(np.sort(w2.real))
