/* dynamics.c -- inverse dynamics, its breakdown by part and forward dynamics over the Kane
   terms of kane.c (stewart_fmu/dynamics.py), per sample and over batches. Friction and drive
   inertia are per leg (six values each in the packed parameters). */
#include <math.h>
#include "internal.h"

#define P(k) p[STEWART_P_##k]

static int finite6(const double a[6])
{
    int j;
    for (j = 0; j < 6; ++j)
        if (!isfinite(a[j]))
            return 0;
    return 1;
}

/* The error of a failed sample: a non-finite input explains any failure;
   otherwise an overflowed output means a near-singular pose. */
int sw_classify(int status, const double a[6], const double b[6], const double c[6])
{
    if (!(finite6(a) && finite6(b) && finite6(c)))
        return STEWART_NONFINITE;
    return status == STEWART_OVERFLOW ? STEWART_SINGULAR : status;
}

/* The sign Coulomb friction takes: 1, -1, or the argument itself for +-0 and NaN. */
double sw_friction_sign(double ld)
{
    return ld > 0.0 ? 1.0 : (ld < 0.0 ? -1.0 : ld);
}

/* mu_i of Eq. 9 for leg i: the force friction opposes to extension. */
static double friction(const double *p, int i, double ld)
{
    double sg;
    if (P(HAS_FRICTION) == 0.0)
        return 0.0;
    sg = sw_friction_sign(ld);
    return p[STEWART_P_VISCOUS + i] * ld + p[STEWART_P_COULOMB + i] * sg;
}

/* m_d,i lddot_i of Eq. 12, the force leg i's drive inertia takes (absent: not computed). */
static double drive_force(const double *p, int i, double ldd)
{
    if (P(HAS_DRIVE) == 0.0)
        return 0.0;
    return p[STEWART_P_DRIVE_MASS + i] * ldd;
}

/* rhs <- J^-T rhs with the LU of the scaled J^T; rhs in the factors' row order, its moments
   scaled like J^T here. */
void sw_solve_jt(const double *p, sw_ws *ws, double *rhs)
{
    const double ic = 1.0 / P(CHAR_LENGTH);
    int k;
    for (k = 0; k < 6; ++k)
        if (ws->order[k] >= 3)
            rhs[k] *= ic;
    sw_lu_solve(ws->JT, rhs);
}

/* sigma = J^-T (-K*_nu - K_g,nu) + mu + m_d lddot for one sample (Eqs. 9-12). */
int sw_inverse_sample(const double *p, const double q[6], const double qd[6],
                      const double qdd[6], sw_ws *ws, double out[6])
{
    int status, k, i, ok = 1;
    const double *gen = ws->gen;
    sw_orientation(q, qd, qdd, ws->R, ws->om, ws->al, ws->trig);
    status = sw_twist_forces(p, q, qd, qdd, ws->al, ws);
    if (status != STEWART_OK)
        return status;
    if (!(sw_lu_factor(ws->JT, ws->order) >= STEWART_SINGULAR_PIVOT))
        return STEWART_SINGULAR;
    for (k = 0; k < 6; ++k) {
        int j = ws->order[k];
        ws->rhs[k] = -(gen[j] + gen[6 + j] + gen[12 + j] + gen[18 + j]);
    }
    sw_solve_jt(p, ws, ws->rhs);
    for (i = 0; i < 6; ++i) {
        double s = ws->rhs[i] + friction(p, i, ws->leg[3 * i + 1]) + drive_force(p, i, ws->leg[3 * i + 2]);
        out[i] = s;
        ok = ok && isfinite(s);
    }
    return ok ? STEWART_OK : STEWART_OVERFLOW;
}

/* The contributions of dynamics.PARTS for one sample, out[part * 6 + leg]. */
int sw_parts_sample(const double *p, const double q[6], const double qd[6],
                    const double qdd[6], sw_ws *ws, double out[36])
{
    static const int kk[4] = {0, 1, 2, 3}, slot[4] = {0, 1, 2, 4};
    double total[6];
    int status = sw_inverse_sample(p, q, qd, qdd, ws, total), has_legs, m, i, j, k, ok = 1;
    if (status != STEWART_OK)
        return status;
    has_legs = P(HAS_LEGS) != 0.0;
    for (m = 0; m < 4; ++m) {
        double *o = out + 6 * slot[m];
        if ((slot[m] == 1 || slot[m] == 2) && !has_legs) {  /* absent: no solve */
            for (j = 0; j < 6; ++j)
                o[j] = 0.0;
            continue;
        }
        for (j = 0; j < 6; ++j)
            ws->rhs[j] = -ws->gen[6 * kk[m] + ws->order[j]];
        sw_solve_jt(p, ws, ws->rhs);
        for (j = 0; j < 6; ++j)
            o[j] = ws->rhs[j];
    }
    for (i = 0; i < 6; ++i) {
        out[18 + i] = drive_force(p, i, ws->leg[3 * i + 2]);
        out[30 + i] = friction(p, i, ws->leg[3 * i + 1]);
        for (k = 0; k < 6; ++k)
            ok = ok && isfinite(out[6 * k + i]);
    }
    return ok ? STEWART_OK : STEWART_OVERFLOW;
}

/* (M_nu + J^T [m_d] J) nudot = J^T (sigma - mu - [m_d] lddot_0) + K*_0 + K_g, then Euler
   rates. */
int sw_forward_sample(const double *p, const double q[6], const double qd[6],
                      const double sigma[6], sw_ws *ws, double out[6])
{
    int status, k, i;
    double net[6], a[3], c, res[6];
    const double *gen = ws->gen;
    sw_orientation(q, qd, SW_ZERO6, ws->R, ws->om, ws->al, ws->trig);  /* al = Edot thd */
    status = sw_twist_forces(p, q, qd, SW_ZERO6, SW_ZERO6, ws);
    if (status != STEWART_OK)
        return status;
    sw_twist_mass_matrix(p, ws, 0);  /* the Cholesky solve reads the lower triangle */
    c = P(CHAR_LENGTH);
    for (i = 0; i < 6; ++i)
        net[i] = sigma[i] - friction(p, i, ws->leg[3 * i + 1]) - drive_force(p, i, ws->leg[3 * i + 2]);
    for (k = 0; k < 6; ++k) {
        double s = 0.0;
        int j;
        for (i = 0; i < 6; ++i)
            s += ws->JT[k * 6 + i] * net[i];
        /* Row k of JT is row order[k] of J^T, its moment rows scaled by 1/c: undo that. */
        j = ws->order[k];
        ws->rhs[j] = gen[j] + gen[6 + j] + gen[12 + j] + gen[18 + j] + (j < 3 ? s : s * c);
    }
    if (!(sw_lu_factor(ws->JT, ws->order) >= STEWART_SINGULAR_PIVOT))
        return STEWART_SINGULAR;
    if (!sw_cholesky_solve(ws->Mt, ws->rhs))
        return STEWART_SINGULAR;
    if (!sw_solve_rate_trig(ws->trig, ws->rhs[3] - ws->al[0], ws->rhs[4] - ws->al[1],
                            ws->rhs[5] - ws->al[2], a))
        return STEWART_GIMBAL;
    res[0] = ws->rhs[0];
    res[1] = ws->rhs[1];
    res[2] = ws->rhs[2];
    res[3] = a[0];
    res[4] = a[1];
    res[5] = a[2];
    for (k = 0; k < 6; ++k)
        out[k] = res[k];
    return finite6(res) ? STEWART_OK : STEWART_OVERFLOW;
}

int stewart_inverse_dynamics(const double *params, const double q[6], const double qd[6],
                             const double qdd[6], double sigma[6])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    st = sw_inverse_sample(params, q, qd, qdd, &ws, sigma);
    return st == STEWART_OK ? st : sw_classify(st, q, qd, qdd);
}

int stewart_inverse_dynamics_parts(const double *params, const double q[6], const double qd[6],
                                   const double qdd[6], double parts[36])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    st = sw_parts_sample(params, q, qd, qdd, &ws, parts);
    return st == STEWART_OK ? st : sw_classify(st, q, qd, qdd);
}

int stewart_forward_dynamics(const double *params, const double q[6], const double qd[6],
                             const double sigma[6], double qdd[6])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    st = sw_forward_sample(params, q, qd, sigma, &ws, qdd);
    return st == STEWART_OK ? st : sw_classify(st, q, qd, sigma);
}

/* One per-sample function over N samples (rows of 6): the index of the first bad sample and its
 * classified status, or -1. */
long sw_batch(sw_sample_fn sample, int out_size, const double *params, long n,
                     const double *A, const double *B, const double *C, double *out, int *status)
{
    sw_ws ws;
    long k;
    sw_ws_init(&ws);
    for (k = 0; k < n; ++k) {
        const double *a = A + 6 * k, *b = B + 6 * k, *c = C + 6 * k;
        int st = sample(params, a, b, c, &ws, out + (long)out_size * k);
        if (st != STEWART_OK) {
            *status = sw_classify(st, a, b, c);
            return k;
        }
    }
    *status = STEWART_OK;
    return -1;
}

long stewart_inverse_dynamics_batch(const double *params, long n, const double *Q,
                                    const double *QD, const double *QDD, double *sigma,
                                    int *status)
{
    return sw_batch(sw_inverse_sample, 6, params, n, Q, QD, QDD, sigma, status);
}

long stewart_inverse_dynamics_parts_batch(const double *params, long n, const double *Q,
                                          const double *QD, const double *QDD, double *parts,
                                          int *status)
{
    return sw_batch(sw_parts_sample, 36, params, n, Q, QD, QDD, parts, status);
}

long stewart_forward_dynamics_batch(const double *params, long n, const double *Q,
                                    const double *QD, const double *SIGMA, double *QDD,
                                    int *status)
{
    return sw_batch(sw_forward_sample, 6, params, n, Q, QD, SIGMA, QDD, status);
}
