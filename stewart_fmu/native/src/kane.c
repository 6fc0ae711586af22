/* kane.c -- Kane's equations of the paper (Eqs. 1-14) reduced to the platform twist
   nu = (v, omega): the generalized inertia and gravity forces per body group and
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

/* The payload's lever rho = R c in N, from C's origin to its centre of mass. */
void sw_payload_lever(const double *p, const double R[9], double rho[3])
{
    const double *c = p + STEWART_P_PAYLOAD_COM;
    int a;
    for (a = 0; a < 3; ++a)
        rho[a] = R[3 * a] * c[0] + R[3 * a + 1] * c[1] + R[3 * a + 2] * c[2];
}

/* The payload's inertia tensor about its centre of mass in N, R I_c R^T (row-major). */
static void payload_inertia_n(const double *p, const double R[9], double IN[9])
{
    const double *I = p + STEWART_P_PAYLOAD_INERTIA;
    const double Ic[9] = {I[0], I[3], I[4], I[3], I[1], I[5], I[4], I[5], I[2]};
    int a, b, k;
    for (a = 0; a < 3; ++a)
        for (b = 0; b < 3; ++b) {
            double s = 0.0;
            for (k = 0; k < 3; ++k)
                s += R[a * 3 + k] * (Ic[k * 3] * R[b * 3] + Ic[k * 3 + 1] * R[b * 3 + 1]
                                     + Ic[k * 3 + 2] * R[b * 3 + 2]);
            IN[a * 3 + b] = s;
        }
}

/* The payload's inertia forces on the twist, added to g: F* = -m (a + alpha x rho + omega x
   (omega x rho)) at its centre of mass, and about C's origin rho x F* - (I alpha + omega x
   I omega), I = R I_c R^T (Eqs. 3-5 for a body off C). */
static void payload_inertia_forces(const double *p, const double *R, const double *om,
                                   const double *acc, const double *al, double *g)
{
    const double m = P(PAYLOAD_MASS);
    double rho[3], IN[9], ar[3], wr[3], a[3], F[3], Ia[3], Iw[3];
    int k;
    sw_payload_lever(p, R, rho);
    payload_inertia_n(p, R, IN);
    ar[0] = al[1] * rho[2] - al[2] * rho[1];
    ar[1] = al[2] * rho[0] - al[0] * rho[2];
    ar[2] = al[0] * rho[1] - al[1] * rho[0];
    wr[0] = om[1] * rho[2] - om[2] * rho[1];
    wr[1] = om[2] * rho[0] - om[0] * rho[2];
    wr[2] = om[0] * rho[1] - om[1] * rho[0];
    a[0] = acc[0] + ar[0] + om[1] * wr[2] - om[2] * wr[1];
    a[1] = acc[1] + ar[1] + om[2] * wr[0] - om[0] * wr[2];
    a[2] = acc[2] + ar[2] + om[0] * wr[1] - om[1] * wr[0];
    for (k = 0; k < 3; ++k) {
        F[k] = -m * a[k];
        Ia[k] = IN[3 * k] * al[0] + IN[3 * k + 1] * al[1] + IN[3 * k + 2] * al[2];
        Iw[k] = IN[3 * k] * om[0] + IN[3 * k + 1] * om[1] + IN[3 * k + 2] * om[2];
    }
    g[0] += F[0];
    g[1] += F[1];
    g[2] += F[2];
    g[3] += rho[1] * F[2] - rho[2] * F[1] - (Ia[0] + om[1] * Iw[2] - om[2] * Iw[1]);
    g[4] += rho[2] * F[0] - rho[0] * F[2] - (Ia[1] + om[2] * Iw[0] - om[0] * Iw[2]);
    g[5] += rho[0] * F[1] - rho[1] * F[0] - (Ia[2] + om[0] * Iw[1] - om[1] * Iw[0]);
}

/* The payload's twist mass matrix, added to M: [[m I, -m X], [m X, I - m X X]], X = [rho]x. */
void sw_payload_mass(const double *p, const double R[9], double M[36])
{
    const double m = P(PAYLOAD_MASS);
    double rho[3], IN[9], rr;
    int a, b;
    sw_payload_lever(p, R, rho);
    payload_inertia_n(p, R, IN);
    rr = rho[0] * rho[0] + rho[1] * rho[1] + rho[2] * rho[2];
    for (a = 0; a < 3; ++a) {
        M[a * 7] += m;
        for (b = 0; b < 3; ++b)
            M[(3 + a) * 6 + 3 + b] += IN[a * 3 + b] + m * ((a == b ? rr : 0.0) - rho[a] * rho[b]);
    }
    M[0 * 6 + 4] += m * rho[2];  M[4 * 6 + 0] += m * rho[2];
    M[0 * 6 + 5] += -m * rho[1]; M[5 * 6 + 0] += -m * rho[1];
    M[1 * 6 + 3] += -m * rho[2]; M[3 * 6 + 1] += -m * rho[2];
    M[1 * 6 + 5] += m * rho[0];  M[5 * 6 + 1] += m * rho[0];
    M[2 * 6 + 3] += m * rho[1];  M[3 * 6 + 2] += m * rho[1];
    M[2 * 6 + 4] += -m * rho[0]; M[4 * 6 + 2] += -m * rho[0];
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

/* Generalized inertia (Eqs. 3-7) and gravity (Eq. 8) forces on the twist:
   ws->gen rows 0 platform inertia, 1 lower legs, 2 upper legs, 3 gravity; also U, Rr, the leg
   rows (l, ldot, lddot) and J^T with its rotational rows divided by the characteristic length,
   row r stored at ws->order[6 + r]. x, v, acc: pose, velocity, acceleration (entries 0-2 used),
   al the angular acceleration; ws->R and ws->om must hold the orientation. Returns OK, or
   STROKE when a leg is outside its limits.

   Layout for speed, arithmetic as the recorded reference's (tests/data/plant_reference.npz, held
   by tests/stewart_fmu/test_plant_reference.py): the per-leg terms are computed leg-parallel over
   arrays of six (loops the compiler vectorizes), each leg's contribution [f; r x f] to a body
   group is kept, and the contributions are then summed over the legs in leg order 0..5 as the
   reference accumulates them, so every result is the same to the last bit. */
int sw_twist_forces(const double *p, const double x[6], const double v[6], const double acc[6],
                    const double al[3], sw_ws *ws)
{
    int status = STEWART_OK, i, k, j;
    const double gx = P(GRAVITY), gy = p[STEWART_P_GRAVITY + 1], gz = p[STEWART_P_GRAVITY + 2];
    const double mp = P(MASS);
    const double *R = ws->R, *om = ws->om;
    const int *at = ws->order + 6;
    double *gen = ws->gen;
    const int has_legs = P(HAS_LEGS) != 0.0;
    const double ic = 1.0 / P(CHAR_LENGTH), lmin = P(LEG_MIN), lmax = P(LEG_MAX);
    const double mA = P(LOWER), cA = p[STEWART_P_LOWER + 1], ItA = p[STEWART_P_LOWER + 2];
    const double mB = P(UPPER), cB = p[STEWART_P_UPPER + 1], ItB = p[STEWART_P_UPPER + 2];
    const double sA = -(mA * cA * cA + ItA), mAcA = mA * cA;
    double rx[6], ry[6], rz[6], ux[6], uy[6], uz[6], l[6], il[6], ld[6], ldd[6];
    double ud2[6], udx[6], udy[6], udz[6], pux[6], puy[6], puz[6];
    double c[3][6][6];   /* per body group (lower, upper, gravity), component, leg */
    for (k = 0; k < 24; ++k)
        gen[k] = 0.0;
    platform_inertia(p, R, om, acc, al, gen);
    gen[18] = mp * gx;
    gen[19] = mp * gy;
    gen[20] = mp * gz;
    if (P(HAS_PAYLOAD) != 0.0) {   /* with the platform's parts: its inertia and its weight */
        const double m = P(PAYLOAD_MASS);
        double rho[3];
        payload_inertia_forces(p, R, om, acc, al, gen);
        sw_payload_lever(p, R, rho);
        gen[18] += m * gx;
        gen[19] += m * gy;
        gen[20] += m * gz;
        gen[21] += m * (rho[1] * gz - rho[2] * gy);
        gen[22] += m * (rho[2] * gx - rho[0] * gz);
        gen[23] += m * (rho[0] * gy - rho[1] * gx);
    }
    /* Leg kinematics: r = R p_i, L = x + r - a_i, u = L / l (one division per leg). */
    for (i = 0; i < 6; ++i) {
        const double *pb = p + STEWART_P_PLATFORM + 3 * i, *pa = p + STEWART_P_BASE + 3 * i;
        double Lx, Ly, Lz;
        rx[i] = R[0] * pb[0] + R[1] * pb[1] + R[2] * pb[2];
        ry[i] = R[3] * pb[0] + R[4] * pb[1] + R[5] * pb[2];
        rz[i] = R[6] * pb[0] + R[7] * pb[1] + R[8] * pb[2];
        Lx = x[0] + rx[i] - pa[0];
        Ly = x[1] + ry[i] - pa[1];
        Lz = x[2] + rz[i] - pa[2];
        l[i] = sqrt(Lx * Lx + Ly * Ly + Lz * Lz);
        il[i] = 1.0 / l[i];
        ux[i] = Lx * il[i];
        uy[i] = Ly * il[i];
        uz[i] = Lz * il[i];
    }
    for (i = 0; i < 6; ++i)
        if (l[i] < lmin || l[i] > lmax)
            status = STEWART_STROKE;
    for (i = 0; i < 6; ++i) {
        /* Joint velocity vp = v + om x r and acceleration ap = acc + al x r + om x (om x r). */
        const double wrx = om[1] * rz[i] - om[2] * ry[i];
        const double wry = om[2] * rx[i] - om[0] * rz[i];
        const double wrz = om[0] * ry[i] - om[1] * rx[i];
        const double vpx = v[0] + wrx, vpy = v[1] + wry, vpz = v[2] + wrz;
        const double apx = acc[0] + al[1] * rz[i] - al[2] * ry[i] + om[1] * wrz - om[2] * wry;
        const double apy = acc[1] + al[2] * rx[i] - al[0] * rz[i] + om[2] * wrx - om[0] * wrz;
        const double apz = acc[2] + al[0] * ry[i] - al[1] * rx[i] + om[0] * wry - om[1] * wrx;
        const double d = ux[i] * vpx + uy[i] * vpy + uz[i] * vpz;
        double dd, ddx, ddy, ddz, u2;
        ld[i] = d;
        ddx = (vpx - d * ux[i]) * il[i];
        ddy = (vpy - d * uy[i]) * il[i];
        ddz = (vpz - d * uz[i]) * il[i];
        u2 = ddx * ddx + ddy * ddy + ddz * ddz;
        dd = ux[i] * apx + uy[i] * apy + uz[i] * apz + l[i] * u2;
        udx[i] = ddx;
        udy[i] = ddy;
        udz[i] = ddz;
        ud2[i] = u2;
        ldd[i] = dd;
        /* uddot from L'' = ldd u + 2 ld udot + l uddot; P uddot = uddot + |udot|^2 u, since
           u . uddot = -|udot|^2. */
        pux[i] = (apx - dd * ux[i] - 2.0 * d * ddx) * il[i] + u2 * ux[i];
        puy[i] = (apy - dd * uy[i] - 2.0 * d * ddy) * il[i] + u2 * uy[i];
        puz[i] = (apz - dd * uz[i] - 2.0 * d * ddz) * il[i] + u2 * uz[i];
    }
    for (i = 0; i < 6; ++i) {
        ws->U[3 * i] = ux[i];
        ws->U[3 * i + 1] = uy[i];
        ws->U[3 * i + 2] = uz[i];
        ws->Rr[3 * i] = rx[i];
        ws->Rr[3 * i + 1] = ry[i];
        ws->Rr[3 * i + 2] = rz[i];
        ws->leg[3 * i] = l[i];
        ws->leg[3 * i + 1] = ld[i];
        ws->leg[3 * i + 2] = ldd[i];
        ws->Ud[3 * i] = udx[i];
        ws->Ud[3 * i + 1] = udy[i];
        ws->Ud[3 * i + 2] = udz[i];
        ws->Pu[3 * i] = pux[i];
        ws->Pu[3 * i + 1] = puy[i];
        ws->Pu[3 * i + 2] = puz[i];
    }
    for (i = 0; i < 6; ++i) {
        ws->JT[at[0] * 6 + i] = ux[i];
        ws->JT[at[1] * 6 + i] = uy[i];
        ws->JT[at[2] * 6 + i] = uz[i];
        ws->JT[at[3] * 6 + i] = (ry[i] * uz[i] - rz[i] * uy[i]) * ic;
        ws->JT[at[4] * 6 + i] = (rz[i] * ux[i] - rx[i] * uz[i]) * ic;
        ws->JT[at[5] * 6 + i] = (rx[i] * uy[i] - ry[i] * ux[i]) * ic;
    }
    if (!has_legs)
        return status;
    for (i = 0; i < 6; ++i) {
        /* Part A: (c_A/l) P (-m_A c_A uddot) plus the torque -I_t alpha through [u]x/l. */
        const double s = sA * il[i];
        /* Part B: a_B = ldd u + 2 ld udot + (l - c_B) uddot, by dV_B/dvp and dw/dvp. */
        const double e = l[i] - cB;
        const double axial = -mB * (ldd[i] - e * ud2[i]);
        const double sp = -mB * e * il[i], st = -ItB * il[i];
        /* Eq. 8 for both parts: m_B (u.g) u + ((m_A c_A + m_B (l - c_B)) / l) P g. */
        const double ug = ux[i] * gx + uy[i] * gy + uz[i] * gz;
        const double sg = (mAcA + mB * (l[i] - cB)) * il[i];
        const double cg = mB * ug - sg * ug;
        c[0][0][i] = s * pux[i];
        c[0][1][i] = s * puy[i];
        c[0][2][i] = s * puz[i];
        c[1][0][i] = axial * ux[i] + sp * (2.0 * ld[i] * udx[i] + e * pux[i]) + st * pux[i];
        c[1][1][i] = axial * uy[i] + sp * (2.0 * ld[i] * udy[i] + e * puy[i]) + st * puy[i];
        c[1][2][i] = axial * uz[i] + sp * (2.0 * ld[i] * udz[i] + e * puz[i]) + st * puz[i];
        c[2][0][i] = sg * gx + cg * ux[i];
        c[2][1][i] = sg * gy + cg * uy[i];
        c[2][2][i] = sg * gz + cg * uz[i];
    }
    for (k = 0; k < 3; ++k)   /* the moments r x f of each contribution */
        for (i = 0; i < 6; ++i) {
            const double fx = c[k][0][i], fy = c[k][1][i], fz = c[k][2][i];
            c[k][3][i] = ry[i] * fz - rz[i] * fy;
            c[k][4][i] = rz[i] * fx - rx[i] * fz;
            c[k][5][i] = rx[i] * fy - ry[i] * fx;
        }
    for (k = 0; k < 3; ++k)   /* summed in leg order, as the Python kernel adds them */
        for (j = 0; j < 6; ++j) {
            double g = gen[6 * (k + 1) + j];
            for (i = 0; i < 6; ++i)
                g += c[k][j][i];
            gen[6 * (k + 1) + j] = g;
        }
    return status;
}

/* M_nu = M_platform (+ the payload's) + sum_i S_i^T (M_leg,i + m_d,i u u^T) S_i, S_i = [I, -[r_i]x];
   M_leg = m_B uu^T + (k / l^2) P, k = m_A c_A^2 + m_B (l - c_B)^2
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
        double s0 = 0.0, s1x = 0.0, s1y = 0.0, s1z = 0.0;
        for (n = 0; n < 6; ++n) {
            const double u0 = ws->U[3 * n], u1 = ws->U[3 * n + 1], u2 = ws->U[3 * n + 2];
            const double r0 = ws->Rr[3 * n], r1 = ws->Rr[3 * n + 1], r2 = ws->Rr[3 * n + 2];
            double ax = has_drive ? p[STEWART_P_DRIVE_MASS + n] : 0.0, j[6];
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
    if (P(HAS_PAYLOAD) != 0.0)
        sw_payload_mass(p, R, Mt);
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
