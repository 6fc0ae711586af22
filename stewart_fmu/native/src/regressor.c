/* regressor.c -- the inverse dynamics written linear in the standard parameters pi of
   STEWART_STANDARD (stewart_table.h): sigma = Y(q, qd, qdd) pi, the identification model.
   Column k of Y is the rack force that one unit of parameter k takes. It reuses the kinematics
   of the inverse dynamics (sw_twist_forces of kane.c: R, omega, alpha, u_i, r_i = R p_i, the
   leg rows, udot_i and P uddot_i, the LU of J^T) and its J^-T solve (Eqs. 9-12), and splits
   each body's terms of Eqs. 3-8 by parameter. The platform's are Newton-Euler about C with a
   first moment and a full inertia tensor, which the scene's model (C at the centre of mass,
   principal axes) holds at zero. tests/stewart_fmu/test_regressor.py holds Y pi to
   stewart_inverse_dynamics on every shipped scene. */
#include <math.h>
#include "internal.h"

#define NS STEWART_N_STANDARD

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* The platform's columns of the generalized force [F; T about C] (Eqs. 3-5, 8): mass
   m (g - a_C); first moment h = R e_j: F = -(alpha x h + omega x (omega x h)),
   T = h x (g - a_C); inertia E_k (the symmetric unit tensor of component k, platform frame):
   T = -R (E_k alpha_b + omega_b x E_k omega_b), alpha_b = R^T alpha, omega_b = R^T omega. */
static void platform_columns(const double *g, const double *acc, const sw_ws *ws, double G[][6])
{
    static const int pair[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    const double *R = ws->R, *om = ws->om, *al = ws->al;
    double ga[3], wb[3], ab[3], h[3], wh[3], t[3];
    int j, k, a;
    for (a = 0; a < 3; ++a) {
        ga[a] = g[a] - acc[a];
        wb[a] = R[a] * om[0] + R[3 + a] * om[1] + R[6 + a] * om[2];
        ab[a] = R[a] * al[0] + R[3 + a] * al[1] + R[6 + a] * al[2];
    }
    for (a = 0; a < 3; ++a) {
        G[STEWART_S_PLATFORM_MASS][a] = ga[a];
        G[STEWART_S_PLATFORM_MASS][3 + a] = 0.0;
    }
    for (j = 0; j < 3; ++j) {
        double *col = G[STEWART_S_PLATFORM_MOMENT + j], ah[3], wwh[3];
        h[0] = R[j];
        h[1] = R[3 + j];
        h[2] = R[6 + j];
        cross(al, h, ah);
        cross(om, h, wh);
        cross(om, wh, wwh);
        cross(h, ga, t);
        for (a = 0; a < 3; ++a) {
            col[a] = -(ah[a] + wwh[a]);
            col[3 + a] = t[a];
        }
    }
    for (k = 0; k < 6; ++k) {
        double *col = G[STEWART_S_PLATFORM_INERTIA + k], Ea[3] = {0.0, 0.0, 0.0},
               Ew[3] = {0.0, 0.0, 0.0}, wEw[3];
        const int r = pair[k][0], c = pair[k][1];
        Ea[r] += ab[c];
        Ew[r] += wb[c];
        if (r != c) {
            Ea[c] += ab[r];
            Ew[c] += wb[r];
        }
        cross(wb, Ew, wEw);
        for (a = 0; a < 3; ++a)
            t[a] = -(Ea[a] + wEw[a]);
        for (a = 0; a < 3; ++a) {
            col[a] = 0.0;
            col[3 + a] = R[3 * a] * t[0] + R[3 * a + 1] * t[1] + R[3 * a + 2] * t[2];
        }
    }
}

/* Adds leg i's force f on the platform joint, with its moment r_i x f, to column col. */
static void add_leg(double *col, const double *r, const double f[3])
{
    double m[3];
    int a;
    cross(r, f, m);
    for (a = 0; a < 3; ++a) {
        col[a] += f[a];
        col[3 + a] += m[a];
    }
}

/* The leg parts' columns (Eqs. 6-8 split by parameter; l, ldot, lddot, u, udot, P uddot of
   leg i): lower m_A c_A: (g - (u.g) u) / l; lower joint inertia: -P uddot / l; upper m_B:
   g - a_p (a_p = lddot u + 2 ldot udot + l uddot, the platform joint's acceleration); upper
   m_B c_B: -|udot|^2 u + 2 ldot udot / l + 2 P uddot - (g - (u.g) u) / l; upper joint inertia:
   -P uddot / l. Masses and axial moments that Eqs. 6-8 do not hold keep zero columns. */
static void leg_columns(const double *g, const sw_ws *ws, double G[][6])
{
    int i, a;
    for (i = 0; i < 6; ++i) {
        const double *u = ws->U + 3 * i, *r = ws->Rr + 3 * i, *ud = ws->Ud + 3 * i,
                     *pu = ws->Pu + 3 * i;
        const double l = ws->leg[3 * i], ld = ws->leg[3 * i + 1], ldd = ws->leg[3 * i + 2];
        const double il = 1.0 / l, ug = u[0] * g[0] + u[1] * g[1] + u[2] * g[2];
        const double ud2 = ud[0] * ud[0] + ud[1] * ud[1] + ud[2] * ud[2];
        double fa[3], fi[3], fm[3], fc[3];
        for (a = 0; a < 3; ++a) {
            const double perp = (g[a] - ug * u[a]) * il;
            fa[a] = perp;
            fi[a] = -pu[a] * il;
            fm[a] = g[a] - (ldd - l * ud2) * u[a] - 2.0 * ld * ud[a] - l * pu[a];
            fc[a] = -ud2 * u[a] + 2.0 * ld * il * ud[a] + 2.0 * pu[a] - perp;
        }
        add_leg(G[STEWART_S_LOWER_MOMENT], r, fa);
        add_leg(G[STEWART_S_LOWER_INERTIA], r, fi);
        add_leg(G[STEWART_S_UPPER_MASS], r, fm);
        add_leg(G[STEWART_S_UPPER_MOMENT], r, fc);
        add_leg(G[STEWART_S_UPPER_INERTIA], r, fi);
    }
}

/* Y of one sample, out[i * NS + k] (leg i, column k). */
int sw_regressor_sample(const double *p, const double q[6], const double qd[6],
                        const double qdd[6], sw_ws *ws, double out[6 * STEWART_N_STANDARD])
{
    const double *g = p + STEWART_P_GRAVITY;
    double G[STEWART_S_DRIVE_MASS][6];   /* the columns that act through the platform */
    int status, i, k, j, ok = 1;
    sw_orientation(q, qd, qdd, ws->R, ws->om, ws->al, ws->trig);
    status = sw_twist_forces(p, q, qd, qdd, ws->al, ws);
    if (status != STEWART_OK)
        return status;
    if (!(sw_lu_factor(ws->JT, ws->order) >= STEWART_SINGULAR_PIVOT))
        return STEWART_SINGULAR;
    for (k = 0; k < STEWART_S_DRIVE_MASS; ++k)
        for (j = 0; j < 6; ++j)
            G[k][j] = 0.0;
    platform_columns(g, qdd, ws, G);
    leg_columns(g, ws, G);
    for (k = 0; k < NS * 6; ++k)
        out[k] = 0.0;
    for (k = 0; k < STEWART_S_DRIVE_MASS; ++k) {
        for (j = 0; j < 6; ++j)
            ws->rhs[j] = -G[k][ws->order[j]];
        sw_solve_jt(p, ws, ws->rhs);
        for (i = 0; i < 6; ++i)
            out[i * NS + k] = ws->rhs[i];
    }
    for (i = 0; i < 6; ++i) {  /* Eqs. 9 and 12: straight onto leg i */
        out[i * NS + STEWART_S_DRIVE_MASS + i] = ws->leg[3 * i + 2];
        out[i * NS + STEWART_S_VISCOUS + i] = ws->leg[3 * i + 1];
        out[i * NS + STEWART_S_COULOMB + i] = sw_friction_sign(ws->leg[3 * i + 1]);
    }
    for (k = 0; k < NS * 6; ++k)
        ok = ok && isfinite(out[k]);
    return ok ? STEWART_OK : STEWART_OVERFLOW;
}

int stewart_regressor(const double *params, const double q[6], const double qd[6],
                      const double qdd[6], double Y[])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    st = sw_regressor_sample(params, q, qd, qdd, &ws, Y);
    return st == STEWART_OK ? st : sw_classify(st, q, qd, qdd);
}

long stewart_regressor_batch(const double *params, long n, const double *Q, const double *QD,
                             const double *QDD, double *Y, int *status)
{
    return sw_batch(sw_regressor_sample, 6 * NS, params, n, Q, QD, QDD, Y, status);
}
