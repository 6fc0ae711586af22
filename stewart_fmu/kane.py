"""Kane's equations of the paper, Eqs. 1-14.

Generalized speeds are the leg rates ldot (the paper's choice). Internally the compiled kernel
projects every body's inertia and gravity forces onto the platform twist nu = (v, omega) and maps
to leg space with the Jacobian J (ldot = J nu), because the partial velocities with respect to
ldot are those with respect to nu times J^-1:

    K*_l = J^-T K*_nu,   [m] = J^-T M_nu J^-1,   [a] = I.

Sign convention: we write the generalized inertia force as K* = -([m] lddot + b), with [m] the
(positive-definite) mass matrix, and the active force K = g + [a] sigma + f (Eq. 10), so Kane's
equations K* + K = 0 (Eq. 11) give sigma = [a]^-1 ([m] lddot + b - g - f). The paper folds the
minus sign into [m] and b; the forces are the same. With the drive (Eq. 12) the rack delivers
sigma + [m_d] lddot, [m_d] = diag(zeta^2 I / r^2) (Eqs. 13-14, the paper's typo corrected).

The per-leg reduction used by the kernel follows from the leg partial velocities: with vp the
velocity of the platform joint, the lower part A, the upper part B and their common angular
velocity w have

    dV_A/dvp = (c_A / l) P,   dV_B/dvp = u u^T + ((l - c_B) / l) P,   dw/dvp = [u]x / l,

P = I - u u^T. The partial velocities of vp with respect to nu are [I, -[r]x], so a leg
contributes [f; r x f] to the twist-space forces, f = the sum over its parts of the transposed
partial velocities times the part's inertia force and torque.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from . import model as M
from .status import STROKE


# Inlined at the numba IR level: as a real call, the dozen scratch arrays it takes each cost an
# atomic reference count pair per sample around the call (~20% of the batch inverse dynamics).
@njit(cache=True, error_model="numpy", inline="always")
def twist_forces(p, x, R, v, om, acc, al, U, Rr, leg, JT, order, gen) -> int:
    """Generalized inertia (Eqs. 3-7) and gravity (Eq. 8) forces on the twist, per body group.

    gen rows: 0 platform inertia, 1 lower-leg inertia, 2 upper-leg inertia, 3 gravity.
    Also fills U (unit vectors u_i), Rr (R p_i), leg rows (l, ldot, lddot) and JT = J^T with
    its rotational rows divided by the characteristic length (dimensionless, entries O(1)),
    row r of J^T stored in row order[1, r] (see linalg.lu_factor, which factors JT in place).
    Returns 0, or STROKE when a leg is outside its limits.
    """
    status = 0
    gx, gy, gz = p[M.P_GRAVITY], p[M.P_GRAVITY + 1], p[M.P_GRAVITY + 2]
    mp = p[M.P_MASS]
    for k in range(4):
        for j in range(6):
            gen[k, j] = 0.0
    _platform_inertia(p, R, om, acc, al, gen)
    gen[3, 0], gen[3, 1], gen[3, 2] = mp * gx, mp * gy, mp * gz
    has_legs = p[M.P_HAS_LEGS] != 0.0
    ic = 1.0 / p[M.P_CHAR_LENGTH]
    for i in range(6):
        # Leg kinematics: r = R p_i, L = x + r - a_i, u = L / l.
        b = M.P_PLATFORM + 3 * i
        rx = R[0, 0] * p[b] + R[0, 1] * p[b + 1] + R[0, 2] * p[b + 2]
        ry = R[1, 0] * p[b] + R[1, 1] * p[b + 1] + R[1, 2] * p[b + 2]
        rz = R[2, 0] * p[b] + R[2, 1] * p[b + 1] + R[2, 2] * p[b + 2]
        a = M.P_BASE + 3 * i
        Lx, Ly, Lz = x[0] + rx - p[a], x[1] + ry - p[a + 1], x[2] + rz - p[a + 2]
        l = np.sqrt(Lx * Lx + Ly * Ly + Lz * Lz)
        il = 1.0 / l  # one division per leg: the rest multiply
        ux, uy, uz = Lx * il, Ly * il, Lz * il
        if l < p[M.P_LEG_MIN] or l > p[M.P_LEG_MAX]:
            status = STROKE
        # Joint velocity vp = v + om x r and acceleration ap = acc + al x r + om x (om x r).
        wrx, wry, wrz = om[1] * rz - om[2] * ry, om[2] * rx - om[0] * rz, om[0] * ry - om[1] * rx
        vpx, vpy, vpz = v[0] + wrx, v[1] + wry, v[2] + wrz
        apx = acc[0] + al[1] * rz - al[2] * ry + om[1] * wrz - om[2] * wry
        apy = acc[1] + al[2] * rx - al[0] * rz + om[2] * wrx - om[0] * wrz
        apz = acc[2] + al[0] * ry - al[1] * rx + om[0] * wry - om[1] * wrx
        ld = ux * vpx + uy * vpy + uz * vpz
        udx, udy, udz = (vpx - ld * ux) * il, (vpy - ld * uy) * il, (vpz - ld * uz) * il
        ud2 = udx * udx + udy * udy + udz * udz
        ldd = ux * apx + uy * apy + uz * apz + l * ud2
        # uddot from L'' = ldd u + 2 ld udot + l uddot.
        uddx = (apx - ldd * ux - 2.0 * ld * udx) * il
        uddy = (apy - ldd * uy - 2.0 * ld * udy) * il
        uddz = (apz - ldd * uz - 2.0 * ld * udz) * il
        U[i, 0], U[i, 1], U[i, 2] = ux, uy, uz
        Rr[i, 0], Rr[i, 1], Rr[i, 2] = rx, ry, rz
        leg[i, 0], leg[i, 1], leg[i, 2] = l, ld, ldd
        at = order[1]
        JT[at[0], i], JT[at[1], i], JT[at[2], i] = ux, uy, uz
        JT[at[3], i] = (ry * uz - rz * uy) * ic
        JT[at[4], i] = (rz * ux - rx * uz) * ic
        JT[at[5], i] = (rx * uy - ry * ux) * ic
        if has_legs:
            # P uddot = uddot + |udot|^2 u, since u . uddot = -|udot|^2.
            pux, puy, puz = uddx + ud2 * ux, uddy + ud2 * uy, uddz + ud2 * uz
            _lower_leg(p, il, pux, puy, puz, rx, ry, rz, gen)
            _upper_leg(p, l, il, ld, ldd, ud2, udx, udy, udz, pux, puy, puz, ux, uy, uz,
                       rx, ry, rz, gen)
            _leg_gravity(p, l, il, ux, uy, uz, gx, gy, gz, rx, ry, rz, gen)
    return status


@njit(cache=True, error_model="numpy")
def _platform_inertia(p, R, om, acc, al, gen) -> None:
    """F* = -m a and T* = R (-(I alpha_c + omega_c x I omega_c)) in C (Eqs. 3-5)."""
    mp = p[M.P_MASS]
    I0, I1, I2 = p[M.P_INERTIA], p[M.P_INERTIA + 1], p[M.P_INERTIA + 2]
    gen[0, 0], gen[0, 1], gen[0, 2] = -mp * acc[0], -mp * acc[1], -mp * acc[2]
    wc0 = R[0, 0] * om[0] + R[1, 0] * om[1] + R[2, 0] * om[2]
    wc1 = R[0, 1] * om[0] + R[1, 1] * om[1] + R[2, 1] * om[2]
    wc2 = R[0, 2] * om[0] + R[1, 2] * om[1] + R[2, 2] * om[2]
    ac0 = R[0, 0] * al[0] + R[1, 0] * al[1] + R[2, 0] * al[2]
    ac1 = R[0, 1] * al[0] + R[1, 1] * al[1] + R[2, 1] * al[2]
    ac2 = R[0, 2] * al[0] + R[1, 2] * al[1] + R[2, 2] * al[2]
    h0, h1, h2 = I0 * wc0, I1 * wc1, I2 * wc2
    t0 = -(I0 * ac0 + wc1 * h2 - wc2 * h1)
    t1 = -(I1 * ac1 + wc2 * h0 - wc0 * h2)
    t2 = -(I2 * ac2 + wc0 * h1 - wc1 * h0)
    gen[0, 3] = R[0, 0] * t0 + R[0, 1] * t1 + R[0, 2] * t2
    gen[0, 4] = R[1, 0] * t0 + R[1, 1] * t1 + R[1, 2] * t2
    gen[0, 5] = R[2, 0] * t0 + R[2, 1] * t1 + R[2, 2] * t2


@njit(cache=True, error_model="numpy")
def _add_joint_force(gen, k, fx, fy, fz, rx, ry, rz) -> None:
    """Add [f; r x f], the twist-space image of a force f per unit joint velocity."""
    gen[k, 0] += fx
    gen[k, 1] += fy
    gen[k, 2] += fz
    gen[k, 3] += ry * fz - rz * fy
    gen[k, 4] += rz * fx - rx * fz
    gen[k, 5] += rx * fy - ry * fx


@njit(cache=True, error_model="numpy")
def _lower_leg(p, il, pux, puy, puz, rx, ry, rz, gen) -> None:
    """Part A: (c_A/l) P (-m_A c_A uddot) plus the torque -I_t alpha through [u]x/l."""
    mA, cA, ItA = p[M.P_LOWER], p[M.P_LOWER + 1], p[M.P_LOWER + 2]
    s = -(mA * cA * cA + ItA) * il
    _add_joint_force(gen, 1, s * pux, s * puy, s * puz, rx, ry, rz)


@njit(cache=True, error_model="numpy")
def _upper_leg(p, l, il, ld, ldd, ud2, udx, udy, udz, pux, puy, puz, ux, uy, uz,
               rx, ry, rz, gen) -> None:
    """Part B: a_B = ldd u + 2 ld udot + (l - c_B) uddot, projected by dV_B/dvp and dw/dvp."""
    mB, cB, ItB = p[M.P_UPPER], p[M.P_UPPER + 1], p[M.P_UPPER + 2]
    e = l - cB
    axial = -mB * (ldd - e * ud2)            # u . F*_B
    sp, st = -mB * e * il, -ItB * il
    fx = axial * ux + sp * (2.0 * ld * udx + e * pux) + st * pux
    fy = axial * uy + sp * (2.0 * ld * udy + e * puy) + st * puy
    fz = axial * uz + sp * (2.0 * ld * udz + e * puz) + st * puz
    _add_joint_force(gen, 2, fx, fy, fz, rx, ry, rz)


@njit(cache=True, error_model="numpy")
def _leg_gravity(p, l, il, ux, uy, uz, gx, gy, gz, rx, ry, rz, gen) -> None:
    """Eq. 8 for both parts: m_B (u.g) u + ((m_A c_A + m_B (l - c_B)) / l) P g."""
    mA, cA = p[M.P_LOWER], p[M.P_LOWER + 1]
    mB, cB = p[M.P_UPPER], p[M.P_UPPER + 1]
    ug = ux * gx + uy * gy + uz * gz
    s = (mA * cA + mB * (l - cB)) * il
    c = mB * ug - s * ug
    _add_joint_force(gen, 3, s * gx + c * ux, s * gy + c * uy, s * gz + c * uz, rx, ry, rz)


@njit(cache=True, error_model="numpy")
def twist_mass_matrix(p, R, U, Rr, leg, Mt) -> None:
    """M_nu = M_platform + sum_i S_i^T (M_leg,i + m_d u u^T) S_i with S_i = [I, -[r_i]x] (vp = S nu).

    M_leg = m_B uu^T + (k / l^2) P, k = m_A c_A^2 + m_B (l - c_B)^2 + I_tA + I_tB (the leg's
    inertia about its base joint), P = I - uu^T. Writing M_leg + m_d uu^T = kp I + ax uu^T,
    S^T S = [[I, -[r]x], [[r]x, |r|^2 I - r r^T]] and S^T u = j_i, the Jacobian row [u; r x u].
    """
    has_legs = p[M.P_HAS_LEGS] != 0.0
    has_drive = p[M.P_HAS_DRIVE] != 0.0
    for i in range(6):
        for j in range(6):
            Mt[i, j] = 0.0
    mp = p[M.P_MASS]
    for a in range(3):
        Mt[a, a] = mp
    if has_legs or has_drive:  # a platform-only model has no per-leg mass at all
        _leg_masses(p, has_legs, has_drive, U, Rr, leg, Mt)
    for a in range(3):
        for b in range(3):
            s = 0.0
            for k in range(3):
                s += R[a, k] * p[M.P_INERTIA + k] * R[b, k]
            Mt[3 + a, 3 + b] += s


@njit(cache=True, error_model="numpy", inline="always")
def _leg_masses(p, has_legs, has_drive, U, Rr, leg, Mt) -> None:
    """Add sum_i S_i^T (M_leg,i + m_d u u^T) S_i to Mt: the legs' part only with [legs], the
    drive's only with [drive] (see twist_mass_matrix)."""
    md = p[M.P_DRIVE_MASS] if has_drive else 0.0
    s0 = 0.0
    s1x = s1y = s1z = 0.0
    for n in range(6):
        u0, u1, u2 = U[n, 0], U[n, 1], U[n, 2]
        r0, r1, r2 = Rr[n, 0], Rr[n, 1], Rr[n, 2]
        ax = md
        if has_legs:
            l = leg[n, 0]
            mA, cA, ItA = p[M.P_LOWER], p[M.P_LOWER + 1], p[M.P_LOWER + 2]
            mB, cB, ItB = p[M.P_UPPER], p[M.P_UPPER + 1], p[M.P_UPPER + 2]
            kp = (mA * cA * cA + mB * (l - cB) ** 2 + ItA + ItB) / (l * l)
            ax += mB - kp
            # kp S^T S: translational trace, coupling [kp r]x, rotational kp (|r|^2 I - r r^T).
            s0 += kp
            s1x += kp * r0
            s1y += kp * r1
            s1z += kp * r2
            rr = r0 * r0 + r1 * r1 + r2 * r2
            rv = (r0, r1, r2)
            for a in range(3):
                for b in range(3):
                    Mt[3 + a, 3 + b] += kp * ((rr if a == b else 0.0) - rv[a] * rv[b])
        # ax j j^T
        j = (u0, u1, u2, r1 * u2 - r2 * u1, r2 * u0 - r0 * u2, r0 * u1 - r1 * u0)
        for a in range(6):
            for b in range(6):
                Mt[a, b] += ax * j[a] * j[b]
    if has_legs:
        for a in range(3):
            Mt[a, a] += s0
        # -[s1]x in the upper right block, its transpose [s1]x in the lower left.
        for a, b, v in ((0, 4, s1z), (0, 5, -s1y), (1, 3, -s1z), (1, 5, s1x), (2, 3, s1y),
                        (2, 4, -s1x)):
            Mt[a, b] += v
            Mt[b, a] += v
