/* stiffness.c -- the Cartesian stiffness of the platform on its elastic legs at a pose, its
   compliance at a point, and the small oscillations about the static equilibrium there
   (stewart_fmu/stiffness.py). The stiffness is the Hessian of the potential energy in the twist
   coordinates chi = (dx, dtheta) at the equilibrium, term by term: each leg's spring and its
   parts' weight are functions f(L) of the leg vector L = x + exp([dtheta]x) r - a (r = R p), whose
   Hessian is A^T H A + sym(g r^T) - (g . r) I on the rotation block, with g = df/dL, H = d2f/dL2
   and A = dL/dchi = [I, -[r]x]; the second term is the geometric stiffness of the static load
   turning with the platform (Griffis and Duffy); the payload's weight is such a term with H = 0. */
#include <math.h>
#include "internal.h"

#define P(k) p[STEWART_P_##k]
#define E(k) e[STEWART_E_##k]

static int finite_n(const double *a, int n)
{
    int k;
    for (k = 0; k < n; ++k)
        if (!isfinite(a[k]))
            return 0;
    return 1;
}

/* K += sym(g r^T) - (g . r) I on the rotation block: a static load with gradient g (dV/dpoint)
   applied at lever r, turning with the platform. */
static void add_geometric(double K[36], const double g[3], const double r[3])
{
    const double gr = g[0] * r[0] + g[1] * r[1] + g[2] * r[2];
    int a, b;
    for (a = 0; a < 3; ++a)
        for (b = 0; b < 3; ++b)
            K[(3 + a) * 6 + 3 + b] += 0.5 * (g[a] * r[b] + r[a] * g[b]) - (a == b ? gr : 0.0);
}

/* K += B^T c B for a 3x6 map B (row-major). */
static void add_quadratic(double K[36], const double B[18], const double H[9])
{
    double HB[18];
    int a, b, k;
    for (a = 0; a < 3; ++a)
        for (b = 0; b < 6; ++b)
            HB[a * 6 + b] = H[a * 3] * B[b] + H[a * 3 + 1] * B[6 + b] + H[a * 3 + 2] * B[12 + b];
    for (a = 0; a < 6; ++a)
        for (b = 0; b < 6; ++b) {
            double s = 0.0;
            for (k = 0; k < 3; ++k)
                s += B[k * 6 + a] * HB[k * 6 + b];
            K[a * 6 + b] += s;
        }
}

/* The leg's axial spring rate: the strut, in series with the transmission's when the motor side
   is held. */
static double leg_rate(const double *p, const double *e, int i)
{
    const double k = e[STEWART_E_LEG + i];
    if (P(HAS_TRANSMISSION) == 0.0)
        return k;
    return k * P(STIFFNESS) / (k + P(STIFFNESS));
}

/* One leg's terms: its spring about the length that carries sigma, its parts' weight, its two
   joints' bending and torsion. */
static void add_leg(const double *p, const double *e, const sw_ws *ws, int i, double sigma,
                    double K[36])
{
    const double *u = ws->U + 3 * i, *r = ws->Rr + 3 * i;
    const double l = ws->leg[3 * i], il = 1.0 / l, k = leg_rate(p, e, i);
    const double kb = E(BENDING), kt = E(TORSION);
    const double *G = p + STEWART_P_GRAVITY;
    double H[9], g[3], A[18], B[18], Pu[9], X[9];
    int a, b, c;
    for (a = 0; a < 3; ++a)
        for (b = 0; b < 3; ++b)
            Pu[a * 3 + b] = (a == b ? 1.0 : 0.0) - u[a] * u[b];
    /* the spring: V = k (l - l0)^2 / 2 with k (l - l0) = -sigma; the base joint's bending,
       k_b |P dL|^2 / (2 l^2) */
    for (a = 0; a < 3; ++a) {
        g[a] = -sigma * u[a];
        for (b = 0; b < 3; ++b)
            H[a * 3 + b] = k * u[a] * u[b] + (kb * il * il - sigma * il) * Pu[a * 3 + b];
    }
    if (P(HAS_LEGS) != 0.0) {
        /* the parts' weight: V = -mu g.u - m_B g.L, mu = m_A c_A - m_B c_B */
        const double mu = P(LOWER) * p[STEWART_P_LOWER + 1] - P(UPPER) * p[STEWART_P_UPPER + 1];
        const double mB = P(UPPER), gu = G[0] * u[0] + G[1] * u[1] + G[2] * u[2];
        const double s = -mu * il * il;
        for (a = 0; a < 3; ++a) {
            g[a] += -mu * il * (G[a] - gu * u[a]) - mB * G[a];
            for (b = 0; b < 3; ++b)
                H[a * 3 + b] += s * (-(G[a] * u[b] + u[a] * G[b]) - (a == b ? gu : 0.0)
                                     + 3.0 * gu * u[a] * u[b]);
        }
    }
    /* A = [I, -[r]x] */
    for (a = 0; a < 18; ++a)
        A[a] = 0.0;
    A[0] = A[7] = A[14] = 1.0;
    A[4] = r[2];  A[5] = -r[1];
    A[9] = -r[2]; A[11] = r[0];
    A[15] = r[1]; A[16] = -r[0];
    add_quadratic(K, A, H);
    add_geometric(K, g, r);
    if (kb != 0.0) {
        /* the platform joint: the leg's rotation against the platform across the leg,
           phi = [u]x A chi / l - P dtheta; energy k_b |phi|^2 / 2 */
        const double ux[9] = {0.0, -u[2], u[1], u[2], 0.0, -u[0], -u[1], u[0], 0.0};
        for (a = 0; a < 3; ++a)
            for (b = 0; b < 6; ++b) {
                double s = 0.0;
                for (c = 0; c < 3; ++c)
                    s += ux[a * 3 + c] * A[c * 6 + b];
                B[a * 6 + b] = s * il - (b >= 3 ? Pu[a * 3 + b - 3] : 0.0);
            }
        for (a = 0; a < 9; ++a)
            X[a] = (a % 4 == 0) ? kb : 0.0;
        add_quadratic(K, B, X);
    }
    if (kt != 0.0)   /* the two joints' torsion in series about the leg */
        for (a = 0; a < 3; ++a)
            for (b = 0; b < 3; ++b)
                K[(3 + a) * 6 + 3 + b] += 0.5 * kt * u[a] * u[b];
}

/* The static leg forces at q: those that hold the platform, the payload and the leg parts
   against gravity (the inverse dynamics at rest); ws keeps the pose's kinematics (R, U, Rr,
   leg). */
static int static_sample(const double *p, const double q[6], sw_ws *ws, double sigma[6])
{
    int st, k;
    if (!finite_n(q, 6))
        return STEWART_NONFINITE;
    sw_orientation(q, SW_ZERO6, SW_ZERO6, ws->R, ws->om, ws->al, ws->trig);
    st = sw_twist_forces(p, q, SW_ZERO6, SW_ZERO6, ws->al, ws);
    if (st != STEWART_OK)
        return st;
    if (!(sw_lu_factor(ws->JT, ws->order) >= STEWART_SINGULAR_PIVOT))
        return STEWART_SINGULAR;
    for (k = 0; k < 6; ++k)   /* at rest the generalized forces are gravity's alone */
        ws->rhs[k] = -ws->gen[18 + ws->order[k]];
    sw_solve_jt(p, ws, ws->rhs);
    for (k = 0; k < 6; ++k)
        sigma[k] = ws->rhs[k];
    return finite_n(sigma, 6) ? STEWART_OK : STEWART_SINGULAR;
}

int stewart_static_forces(const double *params, const double q[6], double sigma[6])
{
    sw_ws ws;
    sw_ws_init(&ws);
    return static_sample(params, q, &ws, sigma);
}

/* The static leg forces and the stiffness at q; ws keeps the pose's kinematics (R, U, Rr, leg)
   for the mass matrix. */
static int stiffness_sample(const double *p, const double *e, const double q[6], sw_ws *ws,
                            double K[36], double sigma[6])
{
    const double *G = p + STEWART_P_GRAVITY;
    double rho[3], gp[3];
    int st, k;
    if (E(HAS_STIFFNESS) == 0.0)
        return finite_n(q, 6) ? STEWART_SINGULAR : STEWART_NONFINITE;
    st = static_sample(p, q, ws, sigma);
    if (st != STEWART_OK)
        return st;
    for (k = 0; k < 36; ++k)
        K[k] = 0.0;
    for (k = 0; k < 6; ++k)
        add_leg(p, e, ws, k, sigma[k], K);
    if (P(HAS_PAYLOAD) != 0.0) {   /* the payload's weight turning with the platform */
        sw_payload_lever(p, ws->R, rho);
        for (k = 0; k < 3; ++k)
            gp[k] = -P(PAYLOAD_MASS) * G[k];
        add_geometric(K, gp, rho);
    }
    for (k = 0; k < 6; ++k) {   /* symmetric to the last bit */
        int j;
        for (j = 0; j < k; ++j)
            K[k * 6 + j] = K[j * 6 + k] = 0.5 * (K[k * 6 + j] + K[j * 6 + k]);
    }
    return finite_n(K, 36) ? STEWART_OK : STEWART_SINGULAR;
}

int stewart_stiffness(const double *params, const double *elastic, const double q[6],
                      double K[36], double sigma[6])
{
    sw_ws ws;
    sw_ws_init(&ws);
    return stiffness_sample(params, elastic, q, &ws, K, sigma);
}

/* Cp = T^T K^-1 T at the pivot (K overwritten by its factor). */
static int compliance_of(double K[36], const double R[9], const double pivot[3], double Cp[36])
{
    double C[36], c[6], rho[3];
    int a, b;
    if (!sw_cholesky_factor(K))
        return STEWART_SINGULAR;
    for (b = 0; b < 6; ++b) {
        for (a = 0; a < 6; ++a)
            c[a] = a == b ? 1.0 : 0.0;
        sw_cholesky_forward(K, c);
        sw_cholesky_back(K, c);
        for (a = 0; a < 6; ++a)
            C[a * 6 + b] = c[a];
    }
    for (a = 0; a < 3; ++a)
        rho[a] = R[3 * a] * pivot[0] + R[3 * a + 1] * pivot[1] + R[3 * a + 2] * pivot[2];
    /* T = [[I, 0], [X, I]], X = [rho]x: Cp = T^T C T; first C T (columns 0-2 gain C[:, 3:] X) */
    for (a = 0; a < 6; ++a) {
        const double c3 = C[a * 6 + 3], c4 = C[a * 6 + 4], c5 = C[a * 6 + 5];
        C[a * 6 + 0] += rho[2] * c4 - rho[1] * c5;
        C[a * 6 + 1] += -rho[2] * c3 + rho[0] * c5;
        C[a * 6 + 2] += rho[1] * c3 - rho[0] * c4;
    }
    for (b = 0; b < 6; ++b) {   /* then T^T: rows 0-2 gain X^T C[3:, :] */
        const double c3 = C[18 + b], c4 = C[24 + b], c5 = C[30 + b];
        C[0 * 6 + b] += rho[2] * c4 - rho[1] * c5;
        C[1 * 6 + b] += -rho[2] * c3 + rho[0] * c5;
        C[2 * 6 + b] += rho[1] * c3 - rho[0] * c4;
    }
    for (a = 0; a < 36; ++a)
        Cp[a] = C[a];
    return STEWART_OK;
}

int stewart_compliance(const double *params, const double *elastic, const double q[6],
                       const double pivot[3], double Cp[36])
{
    sw_ws ws;
    double K[36], sigma[6];
    int st;
    sw_ws_init(&ws);
    st = stiffness_sample(params, elastic, q, &ws, K, sigma);
    return st != STEWART_OK ? st : compliance_of(K, ws.R, pivot, Cp);
}

/* The mass matrix of the modes at the kinematics of ws: the leg side's (the drive's inertia
   out with a [transmission]; the payload's in). */
static void modes_mass(const double *p, sw_ws *ws, double M[36])
{
    double pl[STEWART_N_PARAMS];
    int k;
    stewart_leg_side_params(p, pl);
    sw_twist_mass_matrix(pl, ws, 1);
    for (k = 0; k < 36; ++k)
        M[k] = ws->Mt[k];
}

int stewart_modes_mass(const double *params, const double q[6], double M[36])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    if (!finite_n(q, 6))
        return STEWART_NONFINITE;
    sw_orientation(q, SW_ZERO6, SW_ZERO6, ws.R, ws.om, ws.al, ws.trig);
    st = sw_twist_forces(params, q, SW_ZERO6, SW_ZERO6, ws.al, &ws);
    modes_mass(params, &ws, M);
    return st;
}

/* w2 ascending and the mass-normalised shapes (rows) of K v = w2 M v: with M = L L^T, the
   eigenpairs of L^-1 K L^-T, v = L^-T y. M and K are overwritten. */
static int generalized_eigen(double M[36], double K[36], double w2[6], double shapes[36])
{
    double A[36], V[36], w[6], col[6];
    int order[6], a, b, k;
    if (!sw_cholesky_factor(M))
        return STEWART_SINGULAR;
    for (b = 0; b < 6; ++b) {   /* columns of L^-1 K */
        for (a = 0; a < 6; ++a)
            col[a] = K[a * 6 + b];
        sw_cholesky_forward(M, col);
        for (a = 0; a < 6; ++a)
            A[a * 6 + b] = col[a];
    }
    for (a = 0; a < 6; ++a) {   /* rows: (L^-1 (L^-1 K)^T)^T = L^-1 K L^-T, symmetric */
        for (b = 0; b < 6; ++b)
            col[b] = A[a * 6 + b];
        sw_cholesky_forward(M, col);
        for (b = 0; b < 6; ++b)
            K[a * 6 + b] = col[b];
    }
    for (a = 0; a < 6; ++a)
        for (b = 0; b < a; ++b)
            K[a * 6 + b] = K[b * 6 + a] = 0.5 * (K[a * 6 + b] + K[b * 6 + a]);
    sw_symmetric_eigen(K, w, V);
    for (a = 0; a < 6; ++a)
        order[a] = a;
    for (a = 1; a < 6; ++a)   /* insertion sort, ascending */
        for (b = a; b > 0 && w[order[b]] < w[order[b - 1]]; --b) {
            k = order[b];
            order[b] = order[b - 1];
            order[b - 1] = k;
        }
    for (a = 0; a < 6; ++a) {
        const int j = order[a];
        double big = 0.0;
        w2[a] = w[j];
        for (b = 0; b < 6; ++b)
            col[b] = V[b * 6 + j];
        sw_cholesky_back(M, col);
        for (b = 0; b < 6; ++b)
            if (fabs(col[b]) > fabs(big))
                big = col[b];
        for (b = 0; b < 6; ++b)
            shapes[a * 6 + b] = big < 0.0 ? -col[b] : col[b];
    }
    return STEWART_OK;
}

static int modes_sample(const double *p, const double *e, const double q[6], sw_ws *ws,
                        double w2[6], double shapes[36], double *K)
{
    double M[36], sigma[6], Kw[36];
    int st, k;
    st = stiffness_sample(p, e, q, ws, K, sigma);
    if (st != STEWART_OK)
        return st;
    modes_mass(p, ws, M);
    for (k = 0; k < 36; ++k)
        Kw[k] = K[k];
    st = generalized_eigen(M, Kw, w2, shapes);
    if (st == STEWART_OK && !(finite_n(w2, 6) && finite_n(shapes, 36)))
        st = STEWART_SINGULAR;
    return st;
}

int stewart_modes(const double *params, const double *elastic, const double q[6], double w2[6],
                  double shapes[36])
{
    sw_ws ws;
    double K[36];
    sw_ws_init(&ws);
    return modes_sample(params, elastic, q, &ws, w2, shapes, K);
}

long stewart_modes_batch(const double *params, const double *elastic, long n, const double *Q,
                         const double pivot[3], double *W2, double *Cp, int *status)
{
    sw_ws ws;
    double K[36], shapes[36];
    long k;
    sw_ws_init(&ws);
    for (k = 0; k < n; ++k) {
        int st = modes_sample(params, elastic, Q + 6 * k, &ws, W2 + 6 * k, shapes, K);
        if (st == STEWART_OK && Cp != 0)
            st = compliance_of(K, ws.R, pivot, Cp + 36 * k);
        if (st != STEWART_OK) {
            *status = st;
            return k;
        }
    }
    *status = STEWART_OK;
    return -1;
}
