"""TRA?: how far the platform can go from where it stands along a direction in X Y Z U V W, by the
feasibility engine's travel (stewart_fmu.reach.Engine.travel: every geometric limit and cond(J),
the first found to 1e-9 however narrow the region outside it, by conservative advancement in
the C core).

The engine moves a pose linearly in a frame's coordinates (stewart_fmu.frames: a frame M on the
platform, given in C, seen from a frame F, given in N; positions, and the contract's angles of
R_F^T R R_M). GCS's line is linear in X Y Z and in U V W of the frame POS? speaks in: the tool
(the pivot, or an enabled tool system p_t, R_t on it) seen from the work (ZERO, or an enabled
work system p_w, R_w in ZERO's coordinates), orientation R = R_home R_w R(U, V, W) R_t^T with
R(U, V, W) = Rx(U) Ry(V) Rz(W) (hil.gcs.axes, hil.gcs.coordinate_systems). The two lines are
the same for a direction that turns about one of U, V, W, with M and F chosen per axis so that
the rotation left is the one about that axis alone, R(U, V, W) = R_a R_axis R_b (the other
angles held at their values g0):

    U:  R_a = I,               R_b = Ry(V0) Rz(W0)
    V:  R_a = Rx(U0),          R_b = Rz(W0)
    W:  R_a = Rx(U0) Ry(V0),   R_b = I

    F = (the pivot at the reference + p_w, R_home R_w R_a),  M = (pivot + p_t, R_t R_b^T),
    R_F^T R R_M = R_axis,  positions along R_F^T R_w (X, Y, Z)

and the contract's angles of Rx(a), Ry(b), Rz(c) are (a, 0, 0), (0, b, 0), (0, 0, c) (|b| < 90
deg). A direction with no rotation takes the W row. A direction that turns about two or more of
U V W at once is not a straight line in any frame's angles: TRA? refuses it (error 17).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from hil.gcs import errors as E
from hil.gcs.axes import MM_PER_M, Frame, contract_angles, gcs_matrices
from hil.gcs.coordinate_systems import Enabled
from stewart_fmu.frames import from_platform
from stewart_fmu.reach import Engine, Travel
from stewart_fmu.reach_params import FrameParams

_ZERO6 = np.zeros(6)


def _split(g0: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """(R_a, R_b) with R(U, V, W) = R_a R_axis R_b for a turn about `axis` (3 U, 4 V, 5 W) from
    the angles of g0 (see the module doc)."""
    u0, v0, w0 = np.radians(g0[3:])
    if axis == 3:
        return np.eye(3), gcs_matrices(0.0, v0, w0)[0]
    if axis == 4:
        return gcs_matrices(u0, 0.0, 0.0)[0], gcs_matrices(0.0, 0.0, w0)[0]
    return gcs_matrices(u0, v0, 0.0)[0], np.eye(3)


def _pose(g) -> tuple[np.ndarray, np.ndarray]:
    """(position m, rotation) of a GCS pose (mm, deg)."""
    g = np.asarray(g, dtype=float)
    return g[:3] / MM_PER_M, gcs_matrices(*np.radians(g[3:]))[0]


def travel(model, frame: Frame | Enabled, q_now: np.ndarray,
           direction: np.ndarray) -> tuple[Travel, np.ndarray]:
    """The engine's travel from the plant's pose `q_now` along the GCS `direction` (mm, deg per
    unit step; one rotation component at most) in the frame POS? speaks in, and the GCS pose it
    starts from: the end is `g0 + travel.step * direction`. GcsError 17 for a zero direction or
    one turning about two axes."""
    turning = [i for i in (3, 4, 5) if direction[i] != 0.0]
    if len(turning) > 1 or not np.any(direction != 0.0):
        raise E.GcsError(E.PARAM_OUT_OF_RANGE, "TRA? takes a direction turning about one axis "
                                               "of U V W at most, not zero")
    axis = turning[0] if turning else 5
    zero = frame.zero if isinstance(frame, Enabled) else frame
    work, tool = (frame.work, frame.tool) if isinstance(frame, Enabled) else (_ZERO6, _ZERO6)
    g0 = frame.from_pose(q_now)
    r_a, r_b = _split(g0, axis)
    (w_p, w_r), (m_p, m_r) = _pose(work), _pose(tool)
    r_fix = zero.r0 @ w_r @ r_a
    user = (*(zero.p0 + w_p), *contract_angles(r_fix[None])[0])
    mov = (*(zero.pivot + m_p), *contract_angles((m_r @ r_b.T)[None])[0])
    m = dataclasses.replace(model, frames=FrameParams(pivot=tuple(zero.pivot), user=user,
                                                      tool=mov))
    f0 = from_platform(m, np.asarray(q_now, dtype=float), "user")
    d = np.zeros(6)
    d[:3] = r_fix.T @ w_r @ direction[:3] / MM_PER_M
    d[axis] = np.radians(direction[axis])
    return Engine(m).travel(f0, d, frame="user"), g0
