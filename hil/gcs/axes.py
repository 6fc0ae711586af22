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

import math

import numpy as np

AXES = ("X", "Y", "Z", "U", "V", "W")
UNITS = ("mm", "mm", "mm", "deg", "deg", "deg")
MM_PER_M = 1e3
SCALE = np.array([MM_PER_M] * 3 + [180.0 / math.pi] * 3)   # contract units -> GCS units


def rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def contract_matrix(thx: float, thy: float, thz: float) -> np.ndarray:
    """The contract's R = Rz(thz) Ry(thy) Rx(thx) (radians)."""
    return rz(thz) @ ry(thy) @ rx(thx)


def gcs_matrix(u: float, v: float, w: float) -> np.ndarray:
    """PI's R = Rx(U) Ry(V) Rz(W) (radians)."""
    return rx(u) @ ry(v) @ rz(w)


def contract_angles(r: np.ndarray) -> tuple[float, float, float]:
    """(thx, thy, thz) with contract_matrix(...) = r."""
    thy = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    return math.atan2(r[2, 1], r[2, 2]), thy, math.atan2(r[1, 0], r[0, 0])


def gcs_angles(r: np.ndarray) -> tuple[float, float, float]:
    """(U, V, W) in radians with gcs_matrix(...) = r: r's first row is (cV cW, -cV sW, sV) and
    its last column (sV, -sU cV, cU cV)."""
    v = math.asin(max(-1.0, min(1.0, r[0, 2])))
    return math.atan2(-r[1, 2], r[2, 2]), v, math.atan2(-r[0, 1], r[0, 0])


class Frame:
    """The map between GCS coordinates (X Y Z mm, U V W deg) and the contract's pose q for a
    scene's home pose and a pivot point (m, in C)."""

    def __init__(self, home: np.ndarray, pivot: np.ndarray | None = None) -> None:
        self.home = np.asarray(home, dtype=float).copy()
        self.r0 = contract_matrix(*self.home[3:])
        self.pivot = np.zeros(3) if pivot is None else np.asarray(pivot, dtype=float).copy()
        self.p0 = self.home[:3] + self.r0 @ self.pivot     # the pivot in N at the reference

    def placement(self, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, R): C's origin in N (m) and the platform's orientation for GCS coordinates g."""
        r = self.r0 @ gcs_matrix(*(math.radians(a) for a in g[3:]))
        return self.p0 + np.asarray(g[:3], dtype=float) / MM_PER_M - r @ self.pivot, r

    def to_pose(self, g: np.ndarray) -> np.ndarray:
        """The contract's q (m, rad) of the GCS coordinates g (mm, deg)."""
        x, r = self.placement(g)
        return np.r_[x, contract_angles(r)]

    def from_pose(self, q: np.ndarray) -> np.ndarray:
        """The GCS coordinates (mm, deg) of the contract's pose q (m, rad)."""
        r = contract_matrix(*q[3:])
        p = np.asarray(q[:3], dtype=float) + r @ self.pivot
        return np.r_[(p - self.p0) * MM_PER_M, np.degrees(gcs_angles(self.r0.T @ r))]
