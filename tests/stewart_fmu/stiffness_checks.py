"""The independent routes the stiffness tests compare the C core's stiffness.c against: the
static wrench of the full nonlinear model (Kane's generalized gravity forces of the core's
kane.c, the payload's weight among them, the legs as springs about their equilibrium lengths and the
joints' flexures with their exact bending angles), and poses moved by a twist."""
from __future__ import annotations

import numpy as np

from stewart_fmu.model import Model
from stewart_fmu.native import core
from tests.helpers import rotation as helpers_rotation


def rotation(q) -> np.ndarray:
    """R of pose q (helpers.rotation of its angles)."""
    return helpers_rotation(q[3:])


def euler(R: np.ndarray) -> np.ndarray:
    """(thx, thy, thz) of R = Rz Ry Rx (|thy| < pi/2)."""
    return np.array([np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(R[2, 0]), np.arctan2(R[1, 0], R[0, 0])])


def skew(v) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def expm_so3(w) -> np.ndarray:
    """exp([w]x) by Rodrigues' formula."""
    t = np.linalg.norm(w)
    if t == 0.0:
        return np.eye(3)
    K = skew(np.asarray(w) / t)
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


def moved(q0, chi) -> np.ndarray:
    """The pose q0 moved by the twist chi = (dx, dtheta): x + dx, exp([dtheta]x) R."""
    q = np.empty(6)
    q[:3] = np.asarray(q0[:3]) + chi[:3]
    q[3:] = euler(expm_so3(chi[3:]) @ rotation(q0))
    return q


def _legs(model: Model, q):
    R = rotation(q)
    r = model.platform_joints @ R.T
    L = q[:3] + r - model.base_joints
    return R, r, L


def _angle(a, b):
    """The angle between unit vectors a and b, and theta / sin(theta)."""
    s, c = np.linalg.norm(np.cross(a, b)), float(a @ b)
    t = np.arctan2(s, c)
    return t, (t / s if s > 0.0 else 1.0)


class NonlinearStatics:
    """The static wrench on the platform (force, moment about C's origin, in N) at any pose:
    gravity on the platform, the payload and the leg parts as the core's Kane terms give it
    (kane.c, Eq. 8), each leg a spring k (l - l0) about the length l0 that holds the reference
    pose q0, and with flexure joints the bending moments k_b theta of their exact angles against
    their directions at q0 (the leg's against the base, and against the platform in C)."""

    def __init__(self, model: Model, q0):
        self.model, self.q0 = model, np.asarray(q0, dtype=float)
        s = model.stiffness
        self.k = s.leg_legs.copy()
        if model.transmission is not None:
            kt = model.transmission.stiffness
            self.k = self.k * kt / (self.k + kt)
        self.kb = s.joint_bending or 0.0
        R0, _, L0 = _legs(model, self.q0)
        self.u0 = L0 / np.linalg.norm(L0, axis=1)[:, None]
        self.w0 = self.u0 @ R0          # rows R0^T u0: the legs' directions in C
        self.l0 = np.zeros(6)
        self.l0 = np.linalg.norm(L0, axis=1) - self._spring_force_needed() / self.k

    def _loads(self, q) -> np.ndarray:
        """The weights' wrench: Kane's generalized gravity forces (platform, payload, legs)."""
        gen, _, st = core.twist_forces(self.model.native, q, np.zeros(6), np.zeros(6))
        assert st == core.OK
        return gen[3].copy()

    def _spring_force_needed(self) -> np.ndarray:
        """The leg tensions k (l - l0) that balance the loads and the (relaxed) joints at q0."""
        R, r, L = _legs(self.model, self.q0)
        u = L / np.linalg.norm(L, axis=1)[:, None]
        JT = np.vstack([u.T, np.cross(r, u).T])
        return np.linalg.solve(JT, self._loads(self.q0))

    def wrench(self, q) -> np.ndarray:
        R, r, L = _legs(self.model, q)
        l = np.linalg.norm(L, axis=1)
        u = L / l[:, None]
        W = self._loads(q)
        for i in range(6):
            f = -self.k[i] * (l[i] - self.l0[i]) * u[i]     # the spring's force on the platform
            W += np.concatenate([f, np.cross(r[i], f)])
            if self.kb:
                W += self._bending(R, r[i], u[i], l[i], i)
        return W

    def _bending(self, R, r, u, l, i) -> np.ndarray:
        P = np.eye(3) - np.outer(u, u)
        # base joint: V = k_b theta^2 / 2, theta the angle of u from u0; dV/dL = g
        t, ts = _angle(self.u0[i], u)
        g = -self.kb * ts * (P @ self.u0[i]) / l
        grad = np.concatenate([g, np.cross(r, g)])
        # platform joint: the angle of w = R^T u from w0; dV = h . du - (u x h) . dtheta
        t, ts = _angle(self.w0[i], R.T @ u)
        h = -self.kb * ts * (R @ self.w0[i])
        hp = P @ h / l
        grad += np.concatenate([hp, np.cross(r, hp) - np.cross(u, h)])
        return -grad

    def stiffness_fd(self, step_x: float, step_r: float) -> np.ndarray:
        """-dW/dchi at q0 by central differences of the wrench."""
        K = np.empty((6, 6))
        for k in range(6):
            e = np.zeros(6)
            e[k] = step_x if k < 3 else step_r
            K[:, k] = -(self.wrench(moved(self.q0, e)) - self.wrench(moved(self.q0, -e))) / (2 * e[k])
        return K
