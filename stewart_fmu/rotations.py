"""Orientation convention of the contract: R = Rz(thz) Ry(thy) Rx(thx), fixed axes X, Y, Z.

omega = E(theta) thetadot and alpha = E thetaddot + Edot thetadot convert Euler-angle rates to
the angular velocity and acceleration in N. E is singular at thy = +-pi/2 (gimbal lock). These
are the vectorised (numpy) forms over N samples; the C core has the per-sample ones
(native/src/rotations.c) with the same arithmetic.
"""
from __future__ import annotations

import numpy as np

GIMBAL_LIMIT = 1e-9  # |cos(thy)| below this: E cannot be inverted


def euler_motion(Q: np.ndarray, QD: np.ndarray, QDD: np.ndarray, R: np.ndarray, OM: np.ndarray,
                 AL: np.ndarray) -> None:
    """Fill R (N, 3, 3) = Rz Ry Rx, omega (N, 3) = E thd and alpha (N, 3) = E thdd + Edot thd
    (in N) from pose rows (N, 6) and their rates and accelerations."""
    th, thd, thdd = Q[:, 3:6], QD[:, 3:6], QDD[:, 3:6]
    cx, sx = np.cos(th[:, 0]), np.sin(th[:, 0])
    cy, sy = np.cos(th[:, 1]), np.sin(th[:, 1])
    cz, sz = np.cos(th[:, 2]), np.sin(th[:, 2])
    R[:, 0, 0] = cz * cy
    R[:, 0, 1] = cz * sy * sx - sz * cx
    R[:, 0, 2] = cz * sy * cx + sz * sx
    R[:, 1, 0] = sz * cy
    R[:, 1, 1] = sz * sy * sx + cz * cx
    R[:, 1, 2] = sz * sy * cx - cz * sx
    R[:, 2, 0] = -sy
    R[:, 2, 1] = cy * sx
    R[:, 2, 2] = cy * cx
    # Columns of E: Rz Ry e_x, Rz e_y, e_z; and their time derivatives.
    e1x, e1y, e1z = cy * cz, cy * sz, -sy
    e2x, e2y = -sz, cz
    d1x = -sy * thd[:, 1] * cz - cy * sz * thd[:, 2]
    d1y = -sy * thd[:, 1] * sz + cy * cz * thd[:, 2]
    d1z = -cy * thd[:, 1]
    d2x, d2y = -cz * thd[:, 2], -sz * thd[:, 2]
    OM[:, 0] = e1x * thd[:, 0] + e2x * thd[:, 1]
    OM[:, 1] = e1y * thd[:, 0] + e2y * thd[:, 1]
    OM[:, 2] = e1z * thd[:, 0] + thd[:, 2]
    AL[:, 0] = e1x * thdd[:, 0] + e2x * thdd[:, 1] + d1x * thd[:, 0] + d2x * thd[:, 1]
    AL[:, 1] = e1y * thdd[:, 0] + e2y * thdd[:, 1] + d1y * thd[:, 0] + d2y * thd[:, 1]
    AL[:, 2] = e1z * thdd[:, 0] + thdd[:, 2] + d1z * thd[:, 0]


def solve_rate_matrices(Q: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Euler-angle rates X (N, 3) with E(th) X = W for pose rows Q (N, 6) and angular
    velocities W (N, 3), and ok (N,) (False at gimbal lock, where X is left 0): the vectorised
    form of solve_rate_matrix, the same arithmetic."""
    cy, sy = np.cos(Q[:, 4]), np.sin(Q[:, 4])
    cz, sz = np.cos(Q[:, 5]), np.sin(Q[:, 5])
    ok = np.abs(cy) >= GIMBAL_LIMIT
    X = np.zeros((len(Q), 3))
    x0 = (cz[ok] * W[ok, 0] + sz[ok] * W[ok, 1]) / cy[ok]
    X[ok, 0] = x0
    X[ok, 1] = -sz[ok] * W[ok, 0] + cz[ok] * W[ok, 1]
    X[ok, 2] = W[ok, 2] + sy[ok] * x0
    return X, ok


def solve_rate_matrix(q, w0: float, w1: float, w2: float) -> tuple[bool, float, float, float]:
    """Euler-angle rates x with E(th) x = w (th = q[3:6]): (ok, x0, x1, x2); ok False at gimbal
    lock. One pose in plain floats (the device's per-tick forward kinematics): the arithmetic of
    solve_rate_matrices."""
    cy, sy = np.cos(q[4]), np.sin(q[4])
    if abs(cy) < GIMBAL_LIMIT:
        return False, 0.0, 0.0, 0.0
    cz, sz = np.cos(q[5]), np.sin(q[5])
    x0 = (cz * w0 + sz * w1) / cy
    return True, x0, -sz * w0 + cz * w1, w2 + sy * x0
