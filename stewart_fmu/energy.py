"""Mechanical energy of the plant state, for the power balance of every step.

E = T + V_g + V_s: kinetic energy T = nu^T M_nu nu / 2 (platform, legs and, rigid, the drives
through [m_d] in M_nu; compliant, m_d sd^2 / 2 per motor), gravity potential V_g = -sum m g . r
over the platform and both parts of each leg, spring energy V_s = k (s - l)^2 / 2. The rack
forces F do work on the driven coordinates d (the leg lengths l, or the motor coordinates s with
a transmission): with F held over a step, dE = F . dd - D with D >= 0 the friction and damper
dissipation (sum mu_i ld_i + c (sd - ld)^2 over time).
Computed by the C core (native/src/energy.c).
"""
from __future__ import annotations

import numpy as np

from .model import Model
from .native import core

KINETIC, POTENTIAL, SPRING, DRIVEN = 0, 1, 2, 3   # layout of energy_terms' output (DRIVEN: 6)


def energy_terms(model: Model, y: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(T, V_g, V_s, d_1..d_6) of the plant state y (12 or 24 entries)."""
    return core.energy_terms(model.native, np.ascontiguousarray(y, dtype=float), out)


def total_energy(terms: np.ndarray) -> float:
    """E = T + V_g + V_s from energy_terms."""
    return float(terms[KINETIC] + terms[POTENTIAL] + terms[SPRING])
