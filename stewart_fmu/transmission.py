"""Compliant transmission: each drive's inertia on its own coordinate, sprung to its leg.

A scene's [transmission] table (stiffness k in N/m, damping c in N s/m, both reflected to the
leg axis) gives every leg a motor-side coordinate s_i (the rack position on the leg axis) that
carries the reflected drive inertia m_d = zeta^2 I / r^2. The rack force F_i (the plant's input)
acts on the motor side; the leg gets the spring-damper force

    f_i = k (s_i - l_i) + c (sd_i - ld_i),       m_d sdd_i = F_i - f_i,

and the platform and legs move under f as under sigma of a drive-less model (Kane's equations
without [m_d]). The plant's state grows from y = (q, qd) to y = (q, qd, s, sd). As k -> inf,
s -> l and the rigid drive of Eq. 12 is recovered (tested). inverse_dynamics and
forward_dynamics keep the rigid drive: they are that limit.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from numba import njit

from stewart_fmu.kane_terms import mass_matrix

from . import model as M
from .dynamics import forward_sample, leg_state, workspace
from .kane import twist_forces
from .model import Model
from .rotations import orientation

_ZERO = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def leg_side_params(p):
    """A copy of the packed parameters for the leg side: without a transmission the model as
    it is; with one, the drive inertia removed (it moves on the motor coordinate instead)."""
    pl = p.copy()
    if p[M.P_HAS_TRANSMISSION] != 0.0:
        pl[M.P_HAS_DRIVE] = 0.0
    return pl


@njit(cache=True, error_model="numpy", inline="always")
def _spring(p, y, leg, i) -> float:
    """f_i = k (s_i - l_i) + c (sd_i - ld_i), positive extends the leg."""
    return (p[M.P_STIFFNESS] * (y[12 + i] - leg[i, 0])
            + p[M.P_DAMPING] * (y[18 + i] - leg[i, 1]))


@njit(cache=True, error_model="numpy", inline="always")
def leg_kinematics(pl, y, ws) -> int:
    """Fill ws's R, omega, unit vectors, lever arms and leg rows (l, ld) at y's pose and rates."""
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = ws
    q = (y[0], y[1], y[2], y[3], y[4], y[5])
    qd = (y[6], y[7], y[8], y[9], y[10], y[11])
    orientation(q, qd, _ZERO, R, om, al)
    return twist_forces(pl, q, R, qd, om, _ZERO, al, U, Rr, leg, JT, order, gen)


@njit(cache=True, error_model="numpy", inline="always")
def compliant_derivative(p, pl, y, F, ws, dy) -> int:
    """dy = (qd, qdd, sd, sdd) of the 24-state plant; the forward kernel's status."""
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = ws
    leg_kinematics(pl, y, ws)
    f = (_spring(p, y, leg, 0), _spring(p, y, leg, 1), _spring(p, y, leg, 2),
         _spring(p, y, leg, 3), _spring(p, y, leg, 4), _spring(p, y, leg, 5))
    q = (y[0], y[1], y[2], y[3], y[4], y[5])
    qd = (y[6], y[7], y[8], y[9], y[10], y[11])
    out = dy[6:12].reshape((1, 6))
    status = forward_sample(pl, q, qd, f, R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt, out, 0)
    md = p[M.P_DRIVE_MASS]
    for i in range(6):
        dy[i] = y[6 + i]
        dy[12 + i] = y[18 + i]
        dy[18 + i] = (F[i] - f[i]) / md
    return status


@njit(cache=True, error_model="numpy")
def _spring_forces(p, y):
    ws = workspace()
    pl = leg_side_params(p)
    leg_kinematics(pl, y, ws)
    out = np.empty(6)
    for i in range(6):
        out[i] = _spring(p, y, ws[5], i)
    return out


def spring_forces(model: Model, y: np.ndarray) -> np.ndarray:
    """The transmission forces f_i on the legs (N) at the 24-state y."""
    return _spring_forces(model.params, np.ascontiguousarray(y, dtype=float))


def initial_state(model: Model, q: np.ndarray, qd: np.ndarray,
                  rack_force: np.ndarray | None = None) -> np.ndarray:
    """The plant state at pose q and rates qd: (q, qd), and with a transmission the motor side
    moving with the legs (sd = ld) and preloaded to carry `rack_force` (s = l + F / k)."""
    y = np.r_[np.asarray(q, dtype=float), np.asarray(qd, dtype=float)]
    if model.transmission is None:
        return y
    lengths, rates, _ = leg_state(model, y[:6], y[6:])
    preload = np.zeros(6) if rack_force is None else np.asarray(rack_force, dtype=float)
    return np.r_[y, lengths + preload / model.transmission.stiffness, rates]


def natural_frequencies(model: Model, q: np.ndarray) -> np.ndarray:
    """Linearised transmission modes at pose q (rad/s, ascending): the springs k between the
    drive inertias m_d and the leg side's leg-space mass [m], omega^2 = eig(k (I / m_d +
    [m]^-1)); gravity's geometric stiffness and the damping left out."""


    m = mass_matrix(replace(model, drive=None, transmission=None), q)
    k, md = model.transmission.stiffness, model.drive.reflected_mass
    w2 = np.linalg.eigvals(k * (np.eye(6) / md + np.linalg.inv(m)))
    return np.sqrt(np.sort(w2.real))
