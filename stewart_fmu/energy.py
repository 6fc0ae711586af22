"""Mechanical energy of the plant state, for the power balance of every step.

E = T + V_g + V_s: kinetic energy T = nu^T M_nu nu / 2 (platform, legs and, rigid, the drives
through [m_d] in M_nu; compliant, m_d sd^2 / 2 per motor), gravity potential V_g = -sum m g . r
over the platform and both parts of each leg, spring energy V_s = k (s - l)^2 / 2. The rack
forces F do work on the driven coordinates d (the leg lengths l, or the motor coordinates s with
a transmission): with F held over a step, dE = F . dd - D with D >= 0 the friction and damper
dissipation (sum mu_i ld_i + c (sd - ld)^2 over time).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from . import model as M
from .dynamics import workspace
from .kane import twist_mass_matrix
from .model import Model
from .transmission import leg_kinematics, leg_side_params

KINETIC, POTENTIAL, SPRING, DRIVEN = 0, 1, 2, 3   # layout of energy_terms' output (DRIVEN: 6)


@njit(cache=True, error_model="numpy")
def energy_terms_kernel(p, y, out) -> None:
    """out = (T, V_g, V_s, d_1..d_6) at y (see the module doc)."""
    ws, pl = workspace(), leg_side_params(p)
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = ws
    leg_kinematics(pl, y, ws)
    twist_mass_matrix(pl, R, U, Rr, leg, Mt)
    nu = (y[6], y[7], y[8], om[0], om[1], om[2])
    T = 0.0
    for a in range(6):
        for b in range(6):
            T += 0.5 * nu[a] * Mt[a, b] * nu[b]
    gx, gy, gz = p[M.P_GRAVITY], p[M.P_GRAVITY + 1], p[M.P_GRAVITY + 2]
    V = -p[M.P_MASS] * (gx * y[0] + gy * y[1] + gz * y[2])
    compliant = p[M.P_HAS_TRANSMISSION] != 0.0
    Vs = 0.0
    for i in range(6):
        l = leg[i, 0]
        if p[M.P_HAS_LEGS] != 0.0:
            a = M.P_BASE + 3 * i
            ga = gx * p[a] + gy * p[a + 1] + gz * p[a + 2]
            gu = gx * U[i, 0] + gy * U[i, 1] + gz * U[i, 2]
            mA, cA = p[M.P_LOWER], p[M.P_LOWER + 1]
            mB, cB = p[M.P_UPPER], p[M.P_UPPER + 1]
            V -= mA * (ga + cA * gu) + mB * (ga + (l - cB) * gu)
        if compliant:
            T += 0.5 * p[M.P_DRIVE_MASS] * y[18 + i] ** 2
            Vs += 0.5 * p[M.P_STIFFNESS] * (y[12 + i] - l) ** 2
            out[DRIVEN + i] = y[12 + i]
        else:
            out[DRIVEN + i] = l
    out[KINETIC], out[POTENTIAL], out[SPRING] = T, V, Vs


def energy_terms(model: Model, y: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(T, V_g, V_s, d_1..d_6) of the plant state y (12 or 24 entries), compiled."""
    out = np.empty(DRIVEN + 6) if out is None else out
    energy_terms_kernel(model.params, np.ascontiguousarray(y, dtype=float), out)
    return out


def total_energy(terms: np.ndarray) -> float:
    """E = T + V_g + V_s from energy_terms."""
    return float(terms[KINETIC] + terms[POTENTIAL] + terms[SPRING])
