/* kane.c -- Kane's equations of the paper (Eqs. 1-14) reduced to the platform twist
   nu = (v, omega) (kane.py): the generalized inertia and gravity forces per body group and
   the twist-space mass matrix. Leg space follows with J (ldot = J nu):
   K*_l = J^-T K*_nu, [m] = J^-T M_nu J^-1. */
#include <math.h>
#include "internal.h"

#define P(k) p[STEWART_P_##k]

void sw_ws_init(sw_ws *ws)
{
    int k;
    for (k = 0; k < 6; ++k)
        ws->order[k] = ws->order[6 + k] = k;
}

/* Add [f; r x f], the twist-space image of a force f per unit joint velocity. */
static void add_joint_force(double *g, double fx, double fy, double fz, double rx, double ry,
                            double rz)
{
    g[0] += fx;
    g[1] += fy;
    g[2] += fz;
    g[3] += ry * fz - rz * fy;
    g[4] += rz * fx - rx * fz;
    g[5] += rx * fy - ry * fx;
}

/* F* = -m a and T* = R (-(I alpha_c + omega_c x I omega_c)) in C (Eqs. 3-5). */
static void platform_inertia(const double *p, const double *R, const double *om,
                             const double *acc, const double *al, double *g)
{
    double mp = P(MASS), I0 = P(INERTIA), I1 = p[STEWART_P_INERTIA + 1],
           I2 = p[STEWART_P_INERTIA + 2];
    double wc0, wc1, wc2, ac0, ac1, ac2, h0, h1, h2, t0, t1, t2;
    g[0] = -mp * acc[0];
    g[1] = -mp * acc[1];
    g[2] = -mp * acc[2];
    wc0 = R[0] * om[0] + R[3] * om[1] + R[6] * om[2];
    wc1 = R[1] * om[0] + R[4] * om[1] + R[7] * om[2];
    wc2 = R[2] * om[0] + R[5] * om[1] + R[8] * om[2];
    ac0 = R[0] * al[0] + R[3] * al[1] + R[6] * al[2];
    ac1 = R[1] * al[0] + R[4] * al[1] + R[7] * al[2];
    ac2 = R[2] * al[0] + R[5] * al[1] + R[8] * al[2];
    h0 = I0 * wc0;
    h1 = I1 * wc1;
    h2 = I2 * wc2;
    t0 = -(I0 * ac0 + wc1 * h2 - wc2 * h1);
    t1 = -(I1 * ac1 + wc2 * h0 - wc0 * h2);
    t2 = -(I2 * ac2 + wc0 * h1 - wc1 * h0);
    g[3] = R[0] * t0 + R[1] * t1 + R[2] * t2;
    g[4] = R[3] * t0 + R[4] * t1 + R[5] * t2;
    g[5] = R[6] * t0 + R[7] * t1 + R[8] * t2;
}

/* Generalized inertia (Eqs. 3-7) and gravity (Eq. 8) forces on the twist (kane.twist_forces):
   ws->gen rows 0 platform inertia, 1 lower legs, 2 upper legs, 3 gravity; also U, Rr, the leg
   rows (l, ldot, lddot) and J^T with its rotational rows divided by the characteristic length,
   row r stored at ws->order[6 + r]. x, v, acc: pose, velocity, acceleration (entries 0-2 used),
   al the angular acceleration; ws->R and ws->om must hold the orientation. Returns OK, or STROKE when a leg is outside its
   limits. */
int sw_twist_forces(const double *p, const double x[6], const double v[6], const double acc[6],
                    const double al[3], sw_ws *ws)
{
    int status = STEWART_OK, i, k;
    const double gx = P(GRAVITY), gy = p[STEWART_P_GRAVITY + 1], gz = p[STEWART_P_GRAVITY + 2];
    const double mp = P(MASS);
    const double *R = ws->R, *om = ws->om;
    const int *at = ws->order + 6;
    double *gen = ws->gen, inv[6];
    const int has_legs = P(HAS_LEGS) != 0.0;
    const double ic = 1.0 / P(CHAR_LENGTH);
    const double mA = P(LOWER), cA = p[STEWART_P_LOWER + 1], ItA = p[STEWART_P_LOWER + 2];
    const double mB = P(UPPER), cB = p[STEWART_P_UPPER + 1], ItB = p[STEWART_P_UPPER + 2];
    for (k = 0; k < 24; ++k)
        gen[k] = 0.0;
    platform_inertia(p, R, om, acc, al, gen);
    gen[18] = mp * gx;
    gen[19] = mp * gy;
    gen[20] = mp * gz;
    /* Leg kinematics first, all six legs: r = R p_i, L = x + r - a_i, l = |L| (the square
       roots and divisions of the legs are independent: this lets them overlap). */
    for (i = 0; i < 6; ++i) {
        const int b = STEWART_P_PLATFORM + 3 * i, a = STEWART_P_BASE + 3 * i;
        const double rx = R[0] * p[b] + R[1] * p[b + 1] + R[2] * p[b + 2];
        const double ry = R[3] * p[b] + R[4] * p[b + 1] + R[5] * p[b + 2];
        const double rz = R[6] * p[b] + R[7] * p[b + 1] + R[8] * p[b + 2];
        const double Lx = x[0] + rx - p[a], Ly = x[1] + ry - p[a + 1], Lz = x[2] + rz - p[a + 2];
        ws->Rr[3 * i] = rx;
        ws->Rr[3 * i + 1] = ry;
        ws->Rr[3 * i + 2] = rz;
        ws->U[3 * i] = Lx;
        ws->U[3 * i + 1] = Ly;
        ws->U[3 * i + 2] = Lz;
        ws->leg[3 * i] = sqrt(Lx * Lx + Ly * Ly + Lz * Lz);
    }
    for (i = 0; i < 6; ++i)
        inv[i] = 1.0 / ws->leg[3 * i];  /* one division per leg: the rest multiply */
    for (i = 0; i < 6; ++i) {
        const double rx = ws->Rr[3 * i], ry = ws->Rr[3 * i + 1], rz = ws->Rr[3 * i + 2];
        const double l = ws->leg[3 * i], il = inv[i];
        const double ux = ws->U[3 * i] * il, uy = ws->U[3 * i + 1] * il,
                     uz = ws->U[3 * i + 2] * il;
        double wrx, wry, wrz, vpx, vpy, vpz, apx, apy, apz, ld, udx, udy, udz, ud2, ldd;
        double uddx, uddy, uddz;
        if (l < P(LEG_MIN) || l > P(LEG_MAX))
            status = STEWART_STROKE;
        /* Joint velocity vp = v + om x r and acceleration ap = acc + al x r + om x (om x r). */
        wrx = om[1] * rz - om[2] * ry;
        wry = om[2] * rx - om[0] * rz;
        wrz = om[0] * ry - om[1] * rx;
        vpx = v[0] + wrx;
        vpy = v[1] + wry;
        vpz = v[2] + wrz;
        apx = acc[0] + al[1] * rz - al[2] * ry + om[1] * wrz - om[2] * wry;
        apy = acc[1] + al[2] * rx - al[0] * rz + om[2] * wrx - om[0] * wrz;
        apz = acc[2] + al[0] * ry - al[1] * rx + om[0] * wry - om[1] * wrx;
        ld = ux * vpx + uy * vpy + uz * vpz;
        udx = (vpx - ld * ux) * il;
        udy = (vpy - ld * uy) * il;
        udz = (vpz - ld * uz) * il;
        ud2 = udx * udx + udy * udy + udz * udz;
        ldd = ux * apx + uy * apy + uz * apz + l * ud2;
        /* uddot from L'' = ldd u + 2 ld udot + l uddot. */
        uddx = (apx - ldd * ux - 2.0 * ld * udx) * il;
        uddy = (apy - ldd * uy - 2.0 * ld * udy) * il;
        uddz = (apz - ldd * uz - 2.0 * ld * udz) * il;
        ws->U[3 * i] = ux;
        ws->U[3 * i + 1] = uy;
        ws->U[3 * i + 2] = uz;
        ws->leg[3 * i + 1] = ld;
        ws->leg[3 * i + 2] = ldd;
        ws->JT[at[0] * 6 + i] = ux;
        ws->JT[at[1] * 6 + i] = uy;
        ws->JT[at[2] * 6 + i] = uz;
        ws->JT[at[3] * 6 + i] = (ry * uz - rz * uy) * ic;
        ws->JT[at[4] * 6 + i] = (rz * ux - rx * uz) * ic;
        ws->JT[at[5] * 6 + i] = (rx * uy - ry * ux) * ic;
        if (has_legs) {
            /* P uddot = uddot + |udot|^2 u, since u . uddot = -|udot|^2. */
            double pux = uddx + ud2 * ux, puy = uddy + ud2 * uy, puz = uddz + ud2 * uz;
            double s, e, axial, sp, st, fx, fy, fz, ug, c;
            /* Part A: (c_A/l) P (-m_A c_A uddot) plus the torque -I_t alpha through [u]x/l. */
            s = -(mA * cA * cA + ItA) * il;
            add_joint_force(gen + 6, s * pux, s * puy, s * puz, rx, ry, rz);
            /* Part B: a_B = ldd u + 2 ld udot + (l - c_B) uddot, by dV_B/dvp and dw/dvp. */
            e = l - cB;
            axial = -mB * (ldd - e * ud2);
            sp = -mB * e * il;
            st = -ItB * il;
            fx = axial * ux + sp * (2.0 * ld * udx + e * pux) + st * pux;
            fy = axial * uy + sp * (2.0 * ld * udy + e * puy) + st * puy;
            fz = axial * uz + sp * (2.0 * ld * udz + e * puz) + st * puz;
            add_joint_force(gen + 12, fx, fy, fz, rx, ry, rz);
            /* Eq. 8 for both parts: m_B (u.g) u + ((m_A c_A + m_B (l - c_B)) / l) P g. */
            ug = ux * gx + uy * gy + uz * gz;
            s = (mA * cA + mB * (l - cB)) * il;
            c = mB * ug - s * ug;
            add_joint_force(gen + 18, s * gx + c * ux, s * gy + c * uy, s * gz + c * uz,
                            rx, ry, rz);
        }
    }
    return status;
}

/* M_nu = M_platform + sum_i S_i^T (M_leg,i + m_d u u^T) S_i, S_i = [I, -[r_i]x]
   (kane.twist_mass_matrix); M_leg = m_B uu^T + (k / l^2) P, k = m_A c_A^2 + m_B (l - c_B)^2
   + I_tA + I_tB. Reads ws->R, U, Rr, leg; writes ws->Mt, all of it when `full`, else only
   its lower triangle (all that sw_cholesky_solve reads; each entry computed as in full). */
void sw_twist_mass_matrix(const double *p, sw_ws *ws, int full)
{
    const int has_legs = P(HAS_LEGS) != 0.0, has_drive = P(HAS_DRIVE) != 0.0;
    double *Mt = ws->Mt;
    const double *R = ws->R;
    int a, b, k, n;
    for (k = 0; k < 36; ++k)
        Mt[k] = 0.0;
    for (a = 0; a < 3; ++a)
        Mt[a * 7] = P(MASS);
    if (has_legs || has_drive) {  /* a platform-only model has no per-leg mass at all */
        const double md = has_drive ? P(DRIVE_MASS) : 0.0;
        double s0 = 0.0, s1x = 0.0, s1y = 0.0, s1z = 0.0;
        for (n = 0; n < 6; ++n) {
            const double u0 = ws->U[3 * n], u1 = ws->U[3 * n + 1], u2 = ws->U[3 * n + 2];
            const double r0 = ws->Rr[3 * n], r1 = ws->Rr[3 * n + 1], r2 = ws->Rr[3 * n + 2];
            double ax = md, j[6];
            if (has_legs) {
                const double l = ws->leg[3 * n];
                const double mA = P(LOWER), cA = p[STEWART_P_LOWER + 1],
                             ItA = p[STEWART_P_LOWER + 2];
                const double mB = P(UPPER), cB = p[STEWART_P_UPPER + 1],
                             ItB = p[STEWART_P_UPPER + 2];
                const double e = l - cB;
                const double kp = (mA * cA * cA + mB * (e * e) + ItA + ItB) / (l * l);
                const double rr = r0 * r0 + r1 * r1 + r2 * r2;
                const double rv[3] = {r0, r1, r2};
                ax += mB - kp;
                /* kp S^T S: translational trace, coupling [kp r]x, rotational
                   kp (|r|^2 I - r r^T). */
                s0 += kp;
                s1x += kp * r0;
                s1y += kp * r1;
                s1z += kp * r2;
                for (a = 0; a < 3; ++a)
                    for (b = 0; b < (full ? 3 : a + 1); ++b)
                        Mt[(3 + a) * 6 + 3 + b] += kp * ((a == b ? rr : 0.0) - rv[a] * rv[b]);
            }
            /* ax j j^T, j the Jacobian row [u; r x u] */
            j[0] = u0;
            j[1] = u1;
            j[2] = u2;
            j[3] = r1 * u2 - r2 * u1;
            j[4] = r2 * u0 - r0 * u2;
            j[5] = r0 * u1 - r1 * u0;
            for (a = 0; a < 6; ++a) {
                const double aj = ax * j[a];
                for (b = 0; b < (full ? 6 : a + 1); ++b)
                    Mt[a * 6 + b] += aj * j[b];
            }
        }
        if (has_legs) {
            for (a = 0; a < 3; ++a)
                Mt[a * 7] += s0;
            /* -[s1]x in the upper right block, its transpose [s1]x in the lower left. */
            Mt[0 * 6 + 4] += s1z;  Mt[4 * 6 + 0] += s1z;
            Mt[0 * 6 + 5] += -s1y; Mt[5 * 6 + 0] += -s1y;
            Mt[1 * 6 + 3] += -s1z; Mt[3 * 6 + 1] += -s1z;
            Mt[1 * 6 + 5] += s1x;  Mt[5 * 6 + 1] += s1x;
            Mt[2 * 6 + 3] += s1y;  Mt[3 * 6 + 2] += s1y;
            Mt[2 * 6 + 4] += -s1x; Mt[4 * 6 + 2] += -s1x;
        }
    }
    for (a = 0; a < 3; ++a)
        for (b = 0; b < (full ? 3 : a + 1); ++b) {
            double s = 0.0;
            for (k = 0; k < 3; ++k)
                s += R[a * 3 + k] * p[STEWART_P_INERTIA + k] * R[b * 3 + k];
            Mt[(3 + a) * 6 + 3 + b] += s;
        }
}

int stewart_twist_forces(const double *params, const double q[6], const double qd[6],
                         const double qdd[6], double gen[24], double leg[18])
{
    sw_ws ws;
    int st, k;
    sw_ws_init(&ws);
    sw_orientation(q, qd, qdd, ws.R, ws.om, ws.al, 0);
    st = sw_twist_forces(params, q, qd, qdd, ws.al, &ws);
    for (k = 0; k < 24; ++k)
        gen[k] = ws.gen[k];
    for (k = 0; k < 18; ++k)
        leg[k] = ws.leg[k];
    return st;
}

int stewart_mass_matrix(const double *params, const double q[6], double M[36])
{
    static const double zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    sw_ws ws;
    int st, k;
    sw_ws_init(&ws);
    sw_orientation(q, zero, zero, ws.R, ws.om, ws.al, 0);
    st = sw_twist_forces(params, q, zero, zero, ws.al, &ws);
    sw_twist_mass_matrix(params, &ws, 1);
    for (k = 0; k < 36; ++k)
        M[k] = ws.Mt[k];
    return st;
}
