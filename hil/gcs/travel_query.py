"""TRA?: how far the platform can go from where it stands along a direction in X Y Z U V W, by the
feasibility engine's travel (stewart_fmu.reach.Engine.travel: every geometric limit and cond(J),
marched and bisected in the C core).

The engine moves a pose linearly in a frame's coordinates (stewart_fmu.frames: a frame M on the
platform, given in C, seen from a frame W, given in N; positions, and the contract's angles of
R_W^T R R_M). GCS's line is linear in X Y Z (the pivot's position) and in U V W, where the
orientation is R_home Rx(U) Ry(V) Rz(W) (hil.gcs.axes). The two lines are the same when M is at
the pivot and the direction turns about one of U, V, W, with M and W chosen per axis so that
the rotation left is the one about that axis alone (the others held at their values g0):

    U:  R_W = R_home,                 R_M = (Ry(V0) Rz(W0))^T,  R_W^T R R_M = Rx(U)
    V:  R_W = R_home Rx(U0),          R_M = Rz(W0)^T,           R_W^T R R_M = Ry(V)
    W:  R_W = R_home Rx(U0) Ry(V0),   R_M = I,                  R_W^T R R_M = Rz(W)

and the contract's angles of Rx(a), Ry(b), Rz(c) are (a, 0, 0), (0, b, 0), (0, 0, c) (|b| < 90
deg). A direction with no rotation takes the W row. A direction that turns about two or more of
U V W at once is not a straight line in any frame's angles: TRA? refuses it (error 17).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from hil.gcs import errors as E
from hil.gcs.axes import MM_PER_M, Frame, contract_angles, gcs_matrices
from stewart_fmu.frames import from_platform
from stewart_fmu.reach import Engine, Travel
from stewart_fmu.reach_params import FrameParams


def _frames(frame: Frame, g0: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """(R_W, R_M) for a turn about `axis` (3 U, 4 V, 5 W) from the GCS pose g0 (see the doc)."""
    u0, v0, w0 = np.radians(g0[3:])
    if axis == 3:
        return frame.r0, gcs_matrices(0.0, v0, w0)[0].T
    if axis == 4:
        return frame.r0 @ gcs_matrices(u0, 0.0, 0.0)[0], gcs_matrices(0.0, 0.0, w0)[0].T
    return frame.r0 @ gcs_matrices(u0, v0, 0.0)[0], np.eye(3)


def travel(model, frame: Frame, q_now: np.ndarray,
           direction: np.ndarray) -> tuple[Travel, np.ndarray]:
    """The engine's travel from the plant's pose `q_now` along the GCS `direction` (mm, deg per
    unit step; one rotation component at most) and the GCS pose it starts from: the end is
    `g0 + travel.step * direction`. GcsError 17 for a zero direction or one turning about two
    axes."""
    turning = [i for i in (3, 4, 5) if direction[i] != 0.0]
    if len(turning) > 1 or not np.any(direction != 0.0):
        raise E.GcsError(E.PARAM_OUT_OF_RANGE, "TRA? takes a direction turning about one axis "
                                               "of U V W at most, not zero")
    axis = turning[0] if turning else 5
    g0 = frame.from_pose(q_now)
    r_w, r_m = _frames(frame, g0, axis)
    user = (*frame.p0, *contract_angles(r_w[None])[0])
    tool = (*frame.pivot, *contract_angles(r_m[None])[0])
    m = dataclasses.replace(model, frames=FrameParams(pivot=tuple(frame.pivot), user=user,
                                                      tool=tool))
    f0 = from_platform(m, np.asarray(q_now, dtype=float), "user")
    d = np.zeros(6)
    d[:3] = r_w.T @ direction[:3] / MM_PER_M
    d[axis] = np.radians(direction[axis])
    return Engine(m).travel(f0, d, frame="user"), g0
