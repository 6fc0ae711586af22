"""The hexapod's GCS axes X Y Z (mm) and U V W (deg), mapped exactly onto the contract's pose.

PI's hexapods (C-887 controllers; the H-8xx manuals, "Motion"): translations X, Y, Z are along
the spatially fixed axes; rotations U, V, W are about rotational axes that meet at the pivot
point and move with the platform, and a rotation is composed in the order U -> V -> W. Axes that
move with the platform make these intrinsic rotations, so the platform's orientation is

    R_gcs(U, V, W) = Rx(U) @ Ry(V) @ Rz(W)

while the contract (/work/shared/CONVENTIONS.md) writes R = Rz(thz) @ Ry(thy) @ Rx(thx). POS?
reports the pivot point's displacement from its position at the reference pose (the scene's
home, where POS? is 0 0 0 0 0 0 after FRF), in mm, and U V W in deg. With `home` = (x0, R0) and
the pivot p (in C; the origin of C unless a pivot is set):

    position:     x + R p = x0 + R0 p + (X, Y, Z) / 1000
    orientation:  R = R0 @ R_gcs(U, V, W)

`to_pose` and `from_pose` are these two maps; they are inverse to each other for |V| < 90 deg
(and |thy| < 90 deg: the contract's own gimbal lock).
"""
from __future__ import annotations

import numpy as np

AXES = ("X", "Y", "Z", "U", "V", "W")
MM_PER_M = 1e3


def _rotations(axis: int, angles) -> np.ndarray:
    """(N, 3, 3) rotations about the fixed axis 0 (x), 1 (y) or 2 (z) by N angles (radians)."""
    a = np.atleast_1d(np.asarray(angles, dtype=float))
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.shape[0], 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]       # the plane the rotation turns
    r[:, axis, axis] = 1.0
    r[:, i, i] = c
    r[:, j, j] = c
    r[:, i, j] = -s
    r[:, j, i] = s
    return r


def contract_matrices(thx, thy, thz) -> np.ndarray:
    """The contract's R = Rz(thz) Ry(thy) Rx(thx) (radians; numbers or (N,) arrays: (N, 3, 3))."""
    return _rotations(2, thz) @ _rotations(1, thy) @ _rotations(0, thx)


def gcs_matrices(u, v, w) -> np.ndarray:
    """PI's R = Rx(U) Ry(V) Rz(W) (radians; numbers or (N,) arrays: (N, 3, 3))."""
    return _rotations(0, u) @ _rotations(1, v) @ _rotations(2, w)


def contract_angles(r: np.ndarray) -> np.ndarray:
    """(N, 3) (thx, thy, thz) with contract_matrices(...) = r, (N, 3, 3)."""
    thy = np.arcsin(np.clip(-r[:, 2, 0], -1.0, 1.0))
    return np.stack([np.arctan2(r[:, 2, 1], r[:, 2, 2]), thy,
                     np.arctan2(r[:, 1, 0], r[:, 0, 0])], axis=1)


def gcs_angles(r: np.ndarray) -> np.ndarray:
    """(N, 3) (U, V, W) in radians with gcs_matrices(...) = r, (N, 3, 3): r's first row is
    (cV cW, -cV sW, sV) and its last column (sV, -sU cV, cU cV)."""
    v = np.arcsin(np.clip(r[:, 0, 2], -1.0, 1.0))
    return np.stack([np.arctan2(-r[:, 1, 2], r[:, 2, 2]), v,
                     np.arctan2(-r[:, 0, 1], r[:, 0, 0])], axis=1)


class Frame:
    """The map between GCS coordinates (X Y Z mm, U V W deg) and the contract's pose q for a
    scene's home pose and a pivot point (m, in C). Every map takes one pose (6,) or N poses
    (N, 6) and answers in the same shape."""

    def __init__(self, home: np.ndarray, pivot: np.ndarray | None = None) -> None:
        self.home = np.asarray(home, dtype=float).copy()
        self.r0 = contract_matrices(*self.home[3:])[0]
        self.pivot = np.zeros(3) if pivot is None else np.asarray(pivot, dtype=float).copy()
        self.p0 = self.home[:3] + self.r0 @ self.pivot     # the pivot in N at the reference

    def placements(self, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x (N, 3), R (N, 3, 3)): C's origin in N (m) and the platform's orientation for the
        GCS coordinates g (N, 6)."""
        g = np.atleast_2d(np.asarray(g, dtype=float))
        r = self.r0 @ gcs_matrices(*np.radians(g[:, 3:]).T)
        return self.p0 + g[:, :3] / MM_PER_M - r @ self.pivot, r

    def to_pose(self, g: np.ndarray) -> np.ndarray:
        """The contract's q (m, rad) of the GCS coordinates g (mm, deg)."""
        x, r = self.placements(g)
        q = np.concatenate([x, contract_angles(r)], axis=1)
        return q if np.ndim(g) == 2 else q[0]

    def from_pose(self, q: np.ndarray) -> np.ndarray:
        """The GCS coordinates (mm, deg) of the contract's pose q (m, rad)."""
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        r = contract_matrices(*qa[:, 3:].T)
        p = qa[:, :3] + r @ self.pivot
        g = np.concatenate([(p - self.p0) * MM_PER_M,
                            np.degrees(gcs_angles(self.r0.T @ r))], axis=1)
        return g if np.ndim(q) == 2 else g[0]
