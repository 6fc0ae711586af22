"""Independent Newton-Euler inverse dynamics of the Stewart platform, kinematics by Taylor jets."""
from __future__ import annotations

from typing import Any

import numpy as np

ArrayLike = Any


class Jet:
    """Order-2 Taylor polynomial in s: c[0] + c[1] s + c[2] s^2, elementwise over c.shape[1:]."""

    __array_ufunc__ = None  # make numpy arrays defer to Jet's reflected operators

    def __init__(self, c: ArrayLike) -> None:
        """Wrap coefficient array c of shape (3, ...)."""
        self.c = np.asarray(c, dtype=float)

    @staticmethod
    def lift(v: Jet | ArrayLike) -> Jet:
        """Return v as a Jet (a constant if it is not one)."""
        if isinstance(v, Jet):
            return v
        v = np.asarray(v, dtype=float)
        return Jet(np.stack([v, np.zeros_like(v), np.zeros_like(v)]))

    def pair(self, o: Jet | ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients of self and o, padded so their trailing shapes broadcast like numpy arrays."""
        a, b = self.c, Jet.lift(o).c
        n = max(a.ndim, b.ndim)
        pad = lambda x: x.reshape(x.shape[:1] + (1,) * (n - x.ndim) + x.shape[1:])
        return pad(a), pad(b)

    @property
    def val(self) -> np.ndarray:
        """Value at s = 0."""
        return self.c[0]

    @property
    def d(self) -> np.ndarray:
        """First time derivative at s = 0."""
        return self.c[1]

    @property
    def dd(self) -> np.ndarray:
        """Second time derivative at s = 0."""
        return 2.0 * self.c[2]

    def deriv(self) -> Jet:
        """Time derivative as a jet exact to order 1 (order-2 coefficient unknown, set to 0)."""
        return Jet(np.stack([self.c[1], 2.0 * self.c[2], np.zeros_like(self.c[0])]))

    def __getitem__(self, idx: Any) -> Jet:
        """Index the trailing (non-Taylor) dimensions."""
        idx = idx if isinstance(idx, tuple) else (idx,)
        return Jet(self.c[(slice(None),) + idx])

    def sum(self, axis: int) -> Jet:
        """Sum over a trailing dimension (negative axis counts from the end)."""
        return Jet(self.c.sum(axis=axis if axis < 0 else axis + 1))

    def __add__(self, o: Jet | ArrayLike) -> Jet:
        """Sum."""
        a, b = self.pair(o)
        return Jet(a + b)

    __radd__ = __add__

    def __neg__(self) -> Jet:
        """Negation."""
        return Jet(-self.c)

    def __sub__(self, o: Jet | ArrayLike) -> Jet:
        """Difference."""
        a, b = self.pair(o)
        return Jet(a - b)

    def __rsub__(self, o: Jet | ArrayLike) -> Jet:
        """Reflected difference."""
        a, b = self.pair(o)
        return Jet(b - a)

    def __mul__(self, o: Jet | ArrayLike) -> Jet:
        """Truncated Cauchy product."""
        a, b = self.pair(o)
        return Jet(np.stack([a[0] * b[0], a[0] * b[1] + a[1] * b[0], a[0] * b[2] + a[1] * b[1] + a[2] * b[0]]))

    __rmul__ = __mul__

    def recip(self) -> Jet:
        """Reciprocal 1/self."""
        b = self.c
        r0 = 1.0 / b[0]
        r1 = -b[1] * r0 * r0
        r2 = -(b[1] * r1 + b[2] * r0) * r0
        return Jet(np.stack([r0, r1, r2]))

    def __truediv__(self, o: Jet | ArrayLike) -> Jet:
        """Quotient."""
        return self * Jet.lift(o).recip()

    def __rtruediv__(self, o: Jet | ArrayLike) -> Jet:
        """Reflected quotient."""
        return Jet.lift(o) * self.recip()


def jsqrt(a: Jet) -> Jet:
    """Square root of a jet."""
    f0 = np.sqrt(a.c[0])
    f1 = a.c[1] / (2.0 * f0)
    return Jet(np.stack([f0, f1, (a.c[2] - f1 * f1) / (2.0 * f0)]))


def jsin(a: Jet) -> Jet:
    """Sine of a jet."""
    s, c = np.sin(a.c[0]), np.cos(a.c[0])
    return Jet(np.stack([s, c * a.c[1], c * a.c[2] - 0.5 * s * a.c[1] ** 2]))


def jcos(a: Jet) -> Jet:
    """Cosine of a jet."""
    s, c = np.sin(a.c[0]), np.cos(a.c[0])
    return Jet(np.stack([c, -s * a.c[1], -s * a.c[2] - 0.5 * c * a.c[1] ** 2]))


def jstack(items: list[Jet | ArrayLike], axis: int = -1) -> Jet:
    """Stack jets (or constants) along a new trailing axis."""
    js = [Jet.lift(x) for x in items]
    return Jet(np.stack([j.c for j in js], axis=axis if axis < 0 else axis + 1))


def jdot(a: Jet, b: Jet | ArrayLike) -> Jet:
    """Dot product over the last axis."""
    return (a * b).sum(-1)


def jcross(a: Jet, b: Jet) -> Jet:
    """Cross product over the last axis."""
    return jstack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                   a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]])


def jmatmul(a: Jet, b: Jet) -> Jet:
    """Matrix product of two jet matrices (trailing shape (3, 3))."""
    return (a[:, :, None] * b[None, :, :]).sum(1)


def rotation(thx: Jet, thy: Jet, thz: Jet) -> Jet:
    """R = Rz(thz) @ Ry(thy) @ Rx(thx) as a jet matrix."""
    def rot(c: Jet, s: Jet, i: int, j: int) -> Jet:
        rows: list[list[Jet | float]] = [[float(r == k) for k in range(3)] for r in range(3)]
        rows[i][i], rows[j][j], rows[i][j], rows[j][i] = c, c, -s, s
        return jstack([jstack(r) for r in rows], axis=0)

    rx = rot(jcos(thx), jsin(thx), 1, 2)
    ry = rot(jcos(thy), jsin(thy), 2, 0)
    rz = rot(jcos(thz), jsin(thz), 0, 1)
    return jmatmul(rz, jmatmul(ry, rx))


def vee(w: np.ndarray) -> np.ndarray:
    """Vector of a skew-symmetric matrix."""
    return np.array([w[2, 1], w[0, 2], w[1, 0]])


def reference_inverse_dynamics(scene: dict, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> dict:
    """Actuator forces, leg kinematics and energy terms for one sample, by Newton-Euler."""
    g = np.asarray(scene.get("gravity", [0.0, 0.0, -9.81]), dtype=float)
    geo, plat = scene["geometry"], scene["platform"]
    a = np.asarray(geo["base_joints"], dtype=float)
    p = np.asarray(geo["platform_joints"], dtype=float)
    mp, ip = float(plat["mass"]), np.diag(np.asarray(plat["inertia"], dtype=float))
    legs = scene.get("legs")
    ma, mb = (float(legs["lower_mass"]), float(legs["upper_mass"])) if legs else (0.0, 0.0)
    ca, cb = (float(legs["lower_com"]), float(legs["upper_com"])) if legs else (0.0, 0.0)
    ita, itb = (float(legs["lower_inertia"][0]), float(legs["upper_inertia"][0])) if legs else (0.0, 0.0)
    drv = scene.get("drive")
    # drive inertia and friction: one number for all legs, or six (one per leg)
    rotor = np.asarray(drv["rotor_inertia"], dtype=float) if drv else 0.0
    md = drv["gear_ratio"] ** 2 * rotor / drv["pinion_radius"] ** 2 if drv else 0.0
    fr = scene.get("friction") or {"viscous": 0.0, "coulomb": 0.0}
    viscous, coulomb = np.asarray(fr["viscous"], dtype=float), np.asarray(fr["coulomb"], dtype=float)

    # Kinematics: positions only, as jets in s; derivatives are the jet coefficients.
    qj = Jet(np.stack([np.asarray(q, float), np.asarray(qd, float), 0.5 * np.asarray(qdd, float)]))
    x, rot = qj[0:3], rotation(qj[3], qj[4], qj[5])
    rp = (rot[None, :, :] * p[:, None, :]).sum(-1)  # (6, 3): R p_i
    lv = x[None, :] + rp - a
    l = jsqrt(jdot(lv, lv))
    u = lv / l[:, None]
    ra = a + ca * u  # CoM of lower parts
    rb = a + (l - cb)[:, None] * u  # CoM of upper parts

    r0, rd, rdd = rot.val, rot.d, rot.dd
    wmat = rd @ r0.T
    omega = vee(wmat)
    alpha = vee(rdd @ r0.T - wmat @ wmat)
    i_n = r0 @ ip @ r0.T
    u0, ud, udd = u.val, u.d, u.dd
    wl = np.cross(u0, ud)
    al = np.cross(u0, udd)
    ldot, lddot = l.d, l.dd
    mu = viscous * ldot + coulomb * np.sign(ldot)

    # Leg i (A+B) moments about a_i give the transverse part of F_i (force of leg on platform).
    rav, rbv = ra.val - a, rb.val - a
    m_leg = (np.cross(rav, ma * (ra.dd - g)) + np.cross(rbv, mb * (rb.dd - g)) + (ita + itb) * al)
    f_perp = np.cross(u0, m_leg) / l.val[:, None]
    # Axial balance of B: F_i.u = sigma_act - mu + mb g.u - mb aB.u =: sigma_act + c.
    c = -mu + mb * (u0 @ g) - mb * np.einsum("ij,ij->i", rb.dd, u0)
    # Platform Newton-Euler: sum F_i = mp (a - g), sum (R p_i) x F_i = I alpha + w x I w.
    jt = np.vstack([u0.T, np.cross(rp.val, u0).T])  # columns: wrench of a unit axial force
    rhs = np.concatenate([mp * (x.dd - g), i_n @ alpha + np.cross(omega, i_n @ omega)])
    rhs -= np.concatenate([f_perp.sum(0), np.cross(rp.val, f_perp).sum(0)])
    sigma_act = np.linalg.solve(jt, rhs - jt @ c)
    sigma = sigma_act + md * lddot

    # Energies as jets exact to order 1, so their s-coefficient is the exact rate.
    xv, rdj = x.deriv(), rot.deriv()
    wm = jmatmul(rdj, Jet(np.swapaxes(rot.c, -1, -2)))
    wj = jstack([wm[2, 1], wm[0, 2], wm[1, 0]])
    wb = (Jet(np.swapaxes(rot.c, -1, -2)) * wj[None, :]).sum(-1)  # body-frame angular velocity
    ud_j, va, vb, lvel = u.deriv(), ra.deriv(), rb.deriv(), l.deriv()
    wlj = jcross(u, ud_j)  # leg angular velocity
    kin = (0.5 * mp * jdot(xv, xv) + 0.5 * jdot(wb * np.diag(ip), wb)
           + (0.5 * ma * jdot(va, va) + 0.5 * mb * jdot(vb, vb) + 0.5 * (ita + itb) * jdot(wlj, wlj)
              + 0.5 * md * lvel * lvel).sum(0))
    pot = -mp * jdot(x, g) - (ma * jdot(ra, g) + mb * jdot(rb, g)).sum(0)
    return {
        "sigma": sigma, "l": l.val, "ldot": ldot, "lddot": lddot,
        "kinetic": float(kin.val), "potential": float(pot.val),
        "energy_rate": float(kin.d + pot.d), "friction_power": float(mu @ ldot),
        "omega": omega, "alpha": alpha, "leg_omega": wl, "leg_alpha": al,
    }
