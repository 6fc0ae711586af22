/* linalg.c -- small dense 6x6 solves, the singular values and condition number of a 6x6
   (cond(J): kinematics.condition_number, the feasibility engine) and a symmetric
   eigen-solver (stiffness.c). No allocation; row-major. */
#include <float.h>
#include <math.h>
#include "internal.h"

/* LU of a 6x6 with partial pivoting in place; returns min |pivot| (0 when
   singular). order[k] names the row stored in row k, order[6 + r] is where row r is stored;
   ties of |pivot| go to the smaller row name, so the factors do not depend on the storage. */
double sw_lu_factor(double A[36], int order[12])
{
    double pmin = HUGE_VAL;
    int k, i, j;
    for (k = 0; k < 6; ++k) {
        int p = k;
        double best = fabs(A[k * 6 + k]), inv;
        for (i = k + 1; i < 6; ++i) {
            double a = fabs(A[i * 6 + k]);
            if (a > best || (a == best && order[i] < order[p])) {
                p = i;
                best = a;
            }
        }
        if (p != k) {
            int t = order[k];
            order[k] = order[p];
            order[p] = t;
            order[6 + order[k]] = k;
            order[6 + order[p]] = p;
            for (j = 0; j < 6; ++j) {
                double s = A[k * 6 + j];
                A[k * 6 + j] = A[p * 6 + j];
                A[p * 6 + j] = s;
            }
        }
        pmin = PY_MIN(pmin, best);
        if (best == 0.0)
            return 0.0;
        inv = 1.0 / A[k * 6 + k];
        for (i = k + 1; i < 6; ++i) {
            double f = A[i * 6 + k] * inv;
            A[i * 6 + k] = f;
            for (j = k + 1; j < 6; ++j)
                A[i * 6 + j] -= f * A[k * 6 + j];
        }
    }
    return pmin;
}

/* Solve in place with the factors of sw_lu_factor: b[k] is the entry of row
   order[k]; the solution comes in the natural order. */
void sw_lu_solve(const double LU[36], double b[6])
{
    int i, j;
    for (i = 0; i < 6; ++i) {
        double s = b[i];
        for (j = 0; j < i; ++j)
            s -= LU[i * 6 + j] * b[j];
        b[i] = s;
    }
    for (i = 5; i >= 0; --i) {
        double s = b[i];
        for (j = i + 1; j < 6; ++j)
            s -= LU[i * 6 + j] * b[j];
        b[i] = s / LU[i * 6 + i];
    }
}

/* Cholesky factor of a symmetric positive-definite 6x6 in place: its lower triangle becomes L
   (A = L L^T; the upper triangle is left as it was); 0 if A is not SPD. */
int sw_cholesky_factor(double A[36])
{
    int i, j, k;
    for (j = 0; j < 6; ++j) {
        double d = A[j * 6 + j];
        for (k = 0; k < j; ++k)
            d -= A[j * 6 + k] * A[j * 6 + k];
        if (!(d > 0.0))
            return 0;
        d = sqrt(d);
        A[j * 6 + j] = d;
        for (i = j + 1; i < 6; ++i) {
            double s = A[i * 6 + j];
            for (k = 0; k < j; ++k)
                s -= A[i * 6 + k] * A[j * 6 + k];
            A[i * 6 + j] = s / d;
        }
    }
    return 1;
}

/* b <- L^-1 b (forward substitution with the factor of sw_cholesky_factor). */
void sw_cholesky_forward(const double L[36], double b[6])
{
    int i, k;
    for (i = 0; i < 6; ++i) {
        double s = b[i];
        for (k = 0; k < i; ++k)
            s -= L[i * 6 + k] * b[k];
        b[i] = s / L[i * 6 + i];
    }
}

/* b <- L^-T b (back substitution with the factor of sw_cholesky_factor). */
void sw_cholesky_back(const double L[36], double b[6])
{
    int i, k;
    for (i = 5; i >= 0; --i) {
        double s = b[i];
        for (k = i + 1; k < 6; ++k)
            s -= L[k * 6 + i] * b[k];
        b[i] = s / L[i * 6 + i];
    }
}

/* Solve A x = b in place for symmetric positive-definite A (overwritten); 0 if not SPD. */
int sw_cholesky_solve(double A[36], double b[6])
{
    if (!sw_cholesky_factor(A))
        return 0;
    sw_cholesky_forward(A, b);
    sw_cholesky_back(A, b);
    return 1;
}

/* The 15 column pairs of a 6x6 in five rounds of three disjoint pairs (a round-robin): the
   three rotations of a round are independent, so they overlap in the processor's pipeline. */
static const int JACOBI_PAIRS[15][2] = {{0, 1}, {2, 3}, {4, 5}, {0, 2}, {1, 4}, {3, 5},
                                        {0, 3}, {1, 5}, {2, 4}, {0, 4}, {1, 3}, {2, 5},
                                        {0, 5}, {1, 2}, {3, 4}};

/* A pair counts as orthogonal when gamma^2 <= (6 eps)^2 alpha beta: 6 eps bounds the rounding
   of the computed 6-term product gamma, so a rotation below it would only turn noise (and
   moves each singular value by less than 6 eps relative). */
#define JACOBI_TOL2 (36.0 * 2.220446049250313e-16 * 2.220446049250313e-16)

/* x . y summed in pairs: three independent products deep, not six. */
static double dot6(const double *x, const double *y)
{
    return (x[0] * y[0] + x[1] * y[1]) + (x[2] * y[2] + x[3] * y[3])
           + (x[4] * y[4] + x[5] * y[5]);
}

/* The rotation (c, s) that makes two columns of squared norms alpha, beta and product g
   orthogonal (Rutishauser's smaller angle, t = s / c = sign(d) 2g / (|d| + r) with d = beta -
   alpha, r = sqrt(d^2 + 4 g^2)); *tg = t g, the change of the squared norms. As
   1 + t^2 = 2 r / (|d| + r), c = (|d| + r) / w and s = sign(d) 2g / w with w = sqrt(2 r (|d| + r)):
   two square roots and one division in a row. For a small angle (|d| > 2e5 |g|) the series
   t = h (1 - h^2), h = g / d, c = 1 - t^2 / 2, whose dropped terms are below 1e-20 relative. The
   caller keeps the squares finite (scale_exponent). */
static void jacobi_rotation(double alpha, double beta, double g, double *c, double *s,
                            double *tg)
{
    const double d = beta - alpha, ad = fabs(d);
    if (ad > 2e5 * fabs(g)) {
        const double h = g / d, t = h * (1.0 - h * h);
        *c = 1.0 - 0.5 * t * t;
        *s = *c * t;
        *tg = t * g;
    } else {
        const double r = sqrt(d * d + 4.0 * g * g), u = ad + r, w = sqrt(2.0 * r * u);
        const double sg = d >= 0.0 ? 2.0 * g : -2.0 * g, iw = 1.0 / w;
        *c = u * iw;
        *s = sg * iw;
        *tg = sg * g / u;
    }
}

/* The exponent e for A 2^-e to have its largest entry in [1/2, 1) (0 for a zero A). Scaling by
   a power of two is exact; the squares and products of squares in sw_singular_range's
   methods (and the Jacobi's squared norms) then neither overflow nor, but for columns and
   singular values far below the largest, underflow. */
static int scale_exponent(const double A[36])
{
    double amax = 0.0;
    int i, e = 0;
    for (i = 0; i < 36; ++i)
        amax = PY_MAX(amax, fabs(A[i]));
    if (amax > 0.0)
        (void)frexp(amax, &e);
    return e;
}

/* W = A 2^-e, exactly (but for subnormal results): one product by the power of two where it
   is a normal number, else ldexp per entry. */
static void scaled_copy(const double A[36], int e, double W[36])
{
    int i;
    if (e > -1000 && e < 1000) {
        const double scale = ldexp(1.0, -e);
        for (i = 0; i < 36; ++i)
            W[i] = A[i] * scale;
    } else {
        for (i = 0; i < 36; ++i)
            W[i] = ldexp(A[i], -e);
    }
}

/* The singular values of A 2^-e (unordered; e from scale_exponent) by one-sided Jacobi
   (Hestenes): plane rotations of column pairs until all columns are orthogonal to working
   precision; the singular values are then the column norms, each to high relative accuracy.
   The columns are kept as rows of W (contiguous), their squared norms recomputed each sweep
   and updated by each rotation; a rotation's parameters are computed only for the pairs that
   rotate (the last sweep, which finds every pair orthogonal, computes products only). */
static void jacobi_singular_values(const double A[36], int e, double s[6])
{
    double W[36], n[6];
    int i, j, m, r, sweep;
    scaled_copy(A, e, W);
    for (i = 0; i < 6; ++i)   /* the columns as rows */
        for (j = i + 1; j < 6; ++j) {
            const double t = W[i * 6 + j];
            W[i * 6 + j] = W[j * 6 + i];
            W[j * 6 + i] = t;
        }
    for (sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (j = 0; j < 6; ++j)
            n[j] = dot6(W + 6 * j, W + 6 * j);
        for (r = 0; r < 15; r += 3) {   /* the round's three rotations, then their work */
            double g[3], c[3], sn[3], tg[3];
            int on[3];
            for (m = 0; m < 3; ++m)
                g[m] = dot6(W + 6 * JACOBI_PAIRS[r + m][0], W + 6 * JACOBI_PAIRS[r + m][1]);
            for (m = 0; m < 3; ++m) {
                const double na = n[JACOBI_PAIRS[r + m][0]], nb = n[JACOBI_PAIRS[r + m][1]];
                on[m] = g[m] * g[m] > JACOBI_TOL2 * (na * nb);
                if (on[m])
                    jacobi_rotation(na, nb, g[m], c + m, sn + m, tg + m);
            }
            for (m = 0; m < 3; ++m) {
                const int a = JACOBI_PAIRS[r + m][0], b = JACOBI_PAIRS[r + m][1];
                double *x = W + 6 * a, *y = W + 6 * b;
                if (!on[m])
                    continue;
                rotated = 1;
                for (i = 0; i < 6; ++i) {
                    const double xa = x[i], yb = y[i];
                    x[i] = c[m] * xa - sn[m] * yb;
                    y[i] = sn[m] * xa + c[m] * yb;
                }
                n[a] -= tg[m];
                n[b] += tg[m];
            }
        }
        if (!rotated)
            break;
    }
    for (j = 0; j < 6; ++j)
        s[j] = sqrt(dot6(W + 6 * j, W + 6 * j));
}

/* The upper bidiagonal of A 2^-e by Householder reflections from both sides (Golub-Kahan,
   without the reflections' vectors): d[6] its diagonal, f[5] its superdiagonal. The
   reflections are orthogonal, so the bidiagonal's singular values are those of A 2^-e less a
   backward error of a few eps ||A||: s_min to a few eps cond relative, as the Jacobi's. */
static void bidiagonal(const double A[36], int e, double d[6], double f[5])
{
    double W[36], v[6];
    int i, j, k;
    scaled_copy(A, e, W);
    for (k = 0; k < 6; ++k) {
        double nrm = 0.0, alpha, h;
        for (i = k; i < 6; ++i)   /* left: column k below the diagonal to zero */
            nrm += W[i * 6 + k] * W[i * 6 + k];
        nrm = sqrt(nrm);
        alpha = W[k * 6 + k] > 0.0 ? -nrm : nrm;
        d[k] = alpha;
        if (nrm > 0.0) {
            h = 1.0 / (nrm * (nrm + fabs(W[k * 6 + k])));   /* 2 / v.v */
            for (i = k; i < 6; ++i)
                v[i] = W[i * 6 + k];
            v[k] -= alpha;
            for (j = k + 1; j < 6; ++j) {
                double t = 0.0;
                for (i = k; i < 6; ++i)
                    t += v[i] * W[i * 6 + j];
                t *= h;
                for (i = k; i < 6; ++i)
                    W[i * 6 + j] -= t * v[i];
            }
        }
        if (k >= 4) {
            if (k == 4)
                f[4] = W[4 * 6 + 5];
            continue;
        }
        nrm = 0.0;   /* right: row k right of the superdiagonal to zero */
        for (j = k + 1; j < 6; ++j)
            nrm += W[k * 6 + j] * W[k * 6 + j];
        nrm = sqrt(nrm);
        alpha = W[k * 6 + k + 1] > 0.0 ? -nrm : nrm;
        f[k] = alpha;
        if (nrm > 0.0) {
            h = 1.0 / (nrm * (nrm + fabs(W[k * 6 + k + 1])));
            for (j = k + 1; j < 6; ++j)
                v[j] = W[k * 6 + j];
            v[k + 1] -= alpha;
            for (i = k + 1; i < 6; ++i) {
                double t = 0.0;
                for (j = k + 1; j < 6; ++j)
                    t += v[j] * W[i * 6 + j];
                t *= h;
                for (j = k + 1; j < 6; ++j)
                    W[i * 6 + j] -= t * v[j];
            }
        }
    }
}

/* Laguerre's step from 0 on det(M - x I), M = B B^T of the bidiagonal B whose squared
   diagonal and superdiagonal are q[6], e[5]: a lower bound of M's least eigenvalue (Laguerre's
   method approaches the least root of a polynomial with real roots from below), exact for a
   sixfold root and to third order for a simple one. G = tr(M^-1) = sum r_i, r_i = (M^-1)_ii
   (r_i = (1 + e_{i-1} r_{i-1}) / q_i); H = tr(M^-2) = sum r_i^2 (1 + 2 S_i), as
   (M^-1)_ij^2 = r_i^2 prod_{m=i}^{j-1} e_m / q_{m+1} for i < j (S_i the sum of those products).
   Lowered by 1e-14 relative for the rounding of the sums; -1 when H overflows. */
static double laguerre_floor(const double q[6], const double e[5])
{
    double iq[6], r[6], G = 0.0, H = 0.0, S = 0.0, w;
    int k;
    for (k = 0; k < 6; ++k)
        iq[k] = 1.0 / q[k];
    r[0] = iq[0];
    for (k = 1; k < 6; ++k)
        r[k] = (1.0 + e[k - 1] * r[k - 1]) * iq[k];
    for (k = 5; k >= 0; --k) {
        if (k < 5)
            S = e[k] * iq[k + 1] * (1.0 + S);
        G += r[k];
        H += r[k] * r[k] * (1.0 + 2.0 * S);
    }
    w = 5.0 * (6.0 * H - G * G);
    if (!isfinite(w))   /* tr(M^-2) beyond the range: s_min below ~1e-77 s_max */
        return -1.0;
    return 6.0 / (G + sqrt(w > 0.0 ? w : 0.0)) * (1.0 - 1e-14);
}

/* The least squared singular value of the bidiagonal (d, f) by dqds (Fernando and Parlett's
   differential qd with shifts: q = d^2, e = f^2 hold B B^T less the shifts taken, sigma; every
   quantity stays positive, which keeps the least eigenvalue to high relative accuracy), each
   shift the Laguerre floor. It stops when that floor and a ceiling (the least diagonal entry
   of B B^T or B^T B, Rayleigh quotients) agree to eps: no deflation is needed. -1 when the
   floor fails or lies above the ceiling, when a transform meets a negative d (the floor
   rounded above the eigenvalue) or after 40 transforms. */
static double least_eigenvalue(const double d[6], const double f[5])
{
    double q[6], e[5], sigma = 0.0;
    int k, it;
    for (k = 0; k < 6; ++k)
        q[k] = d[k] * d[k];
    for (k = 0; k < 5; ++k)
        e[k] = f[k] * f[k];
    for (it = 0; it < 40; ++it) {
        const double lo = laguerre_floor(q, e);
        double up = PY_MIN(q[0], q[5]), x, qn[6], en[5];
        int ok;
        for (k = 1; k < 5; ++k)
            up = PY_MIN(up, q[k] + PY_MIN(e[k - 1], e[k]));
        if (!(lo >= 0.0 && up - lo >= -DBL_EPSILON * (sigma + lo)))
            return -1.0;   /* a floor above the ceiling beyond rounding */
        if (up - lo <= DBL_EPSILON * (sigma + lo))
            return sigma + lo;
        x = q[0] - lo;   /* the dqds transform by lo */
        ok = x >= 0.0;
        for (k = 0; k < 5; ++k) {
            const double qh = x + e[k], t = q[k + 1] / qh;
            qn[k] = qh;
            en[k] = e[k] * t;
            x = x * t - lo;
            ok &= x >= 0.0;
        }
        if (!ok)
            return -1.0;
        qn[5] = x;
        for (k = 0; k < 5; ++k) {
            q[k] = qn[k];
            e[k] = en[k];
        }
        q[5] = qn[5];
        sigma += lo;
    }
    return -1.0;
}

/* The greatest eigenvalue of T = B^T B for the bidiagonal (d, f), T formed (the greatest is
   well conditioned: eps relative), by Laguerre's method on det(T - x I) (the three-term
   recurrence with its first two derivatives) from Gershgorin's ceiling: the iterates
   decrease to the root, to third order. It stops at a step below eps or once rounding has
   taken x to the root (the determinant, positive above all six roots, no longer is); -1
   when not finite or after 40 steps. */
static double greatest_eigenvalue(const double d[6], const double f[5])
{
    double a[6], c2[5], x = 0.0;
    int k, it;
    for (k = 0; k < 6; ++k)
        a[k] = d[k] * d[k] + (k ? f[k - 1] * f[k - 1] : 0.0);
    for (k = 0; k < 5; ++k)
        c2[k] = d[k] * d[k] * f[k] * f[k];
    for (k = 0; k < 6; ++k)
        x = PY_MAX(x, a[k] + (k ? fabs(d[k - 1] * f[k - 1]) : 0.0)
                          + (k < 5 ? fabs(d[k] * f[k]) : 0.0));
    for (it = 0; it < 40; ++it) {
        double p0 = 1.0, p1 = a[0] - x, dp0 = 0.0, dp1 = -1.0, ddp0 = 0.0, ddp1 = 0.0;
        double G, H, w, step;
        for (k = 1; k < 6; ++k) {
            const double t = a[k] - x, p2 = t * p1 - c2[k - 1] * p0;
            const double dp2 = t * dp1 - c2[k - 1] * dp0 - p1;
            const double ddp2 = t * ddp1 - c2[k - 1] * ddp0 - 2.0 * dp1;
            p0 = p1;
            p1 = p2;
            dp0 = dp1;
            dp1 = dp2;
            ddp0 = ddp1;
            ddp1 = ddp2;
        }
        if (!(p1 > 0.0))
            return isfinite(p1) ? x : -1.0;
        G = dp1 / p1;   /* sum 1 / (x - l_i) > 0 above the roots */
        H = G * G - ddp1 / p1;
        w = 5.0 * (6.0 * H - G * G);
        step = -6.0 / (G + sqrt(w > 0.0 ? w : 0.0));
        if (!isfinite(step))
            return -1.0;
        if (!(step < 0.0) || -step <= DBL_EPSILON * x)
            return x + PY_MIN(step, 0.0);
        x += step;
    }
    return -1.0;
}

/* The greatest and least singular values of a 6x6: the bidiagonal's greatest_eigenvalue and
   least_eigenvalue, scaled back (*smin = 0 when the bidiagonal has a zero on its diagonal: A
   singular to rounding); the one-sided Jacobi (jacobi_singular_values) where either fails.
   The one SVD of the core (sw_condition, reach.c's travel). */
void sw_singular_range(const double A[36], double *smax, double *smin)
{
    const int e = scale_exponent(A);
    double d[6], f[5], lmin = 0.0, lmax, s[6];
    int i, singular = 0;
    bidiagonal(A, e, d, f);
    for (i = 0; i < 6; ++i)
        singular |= d[i] == 0.0;
    lmax = greatest_eigenvalue(d, f);
    if (!singular)
        lmin = least_eigenvalue(d, f);
    if (lmin >= 0.0 && lmax >= 0.0) {
        *smax = ldexp(sqrt(lmax), e);
        *smin = ldexp(sqrt(lmin), e);
        return;
    }
    jacobi_singular_values(A, e, s);
    *smax = 0.0;
    *smin = HUGE_VAL;
    for (i = 0; i < 6; ++i) {
        *smax = PY_MAX(*smax, s[i]);
        *smin = PY_MIN(*smin, s[i]);
    }
    *smax = ldexp(*smax, e);
    *smin = ldexp(*smin, e);
}

/* The 2-norm condition number s_max / s_min of a 6x6 (as numpy.linalg.cond), by
   sw_singular_range; inf when A is singular or not finite. The one cond(J) of the core
   (kinematics.c, reach.c). */
double sw_condition(const double A[36])
{
    double smax, smin, cond;
    int i;
    for (i = 0; i < 36; ++i)
        if (!isfinite(A[i]))
            return HUGE_VAL;
    sw_singular_range(A, &smax, &smin);
    cond = smax / smin;
    return smin > 0.0 && isfinite(cond) ? cond : HUGE_VAL;
}

/* Eigenvalues w and eigenvectors (columns of V) of a symmetric 6x6 by cyclic Jacobi rotations
   (A is overwritten, its off-diagonal driven to zero), unordered. A rotation is skipped when
   its entry is below 1e-18 of the geometric mean of its two diagonal entries: the eigenvalues
   then hold to high relative accuracy, also a small one beside a large one. */
void sw_symmetric_eigen(double A[36], double w[6], double V[36])
{
    int i, p, q, k, sweep;
    for (i = 0; i < 36; ++i)
        V[i] = (i % 7 == 0) ? 1.0 : 0.0;
    for (sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (p = 0; p < 5; ++p)
            for (q = p + 1; q < 6; ++q) {
                const double apq = A[p * 6 + q], app = A[p * 6 + p], aqq = A[q * 6 + q];
                double theta, t, c, s;
                if (apq == 0.0)
                    continue;
                if (fabs(apq) <= 1e-18 * sqrt(fabs(app * aqq))) {
                    A[p * 6 + q] = A[q * 6 + p] = 0.0;
                    continue;
                }
                rotated = 1;
                theta = (aqq - app) / (2.0 * apq);
                t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                s = t * c;
                for (k = 0; k < 6; ++k) {   /* columns: A P */
                    const double akp = A[k * 6 + p], akq = A[k * 6 + q];
                    A[k * 6 + p] = c * akp - s * akq;
                    A[k * 6 + q] = s * akp + c * akq;
                }
                for (k = 0; k < 6; ++k) {   /* rows: P^T A */
                    const double apk = A[p * 6 + k], aqk = A[q * 6 + k];
                    A[p * 6 + k] = c * apk - s * aqk;
                    A[q * 6 + k] = s * apk + c * aqk;
                }
                A[p * 6 + q] = A[q * 6 + p] = 0.0;
                for (k = 0; k < 6; ++k) {   /* V P */
                    const double vkp = V[k * 6 + p], vkq = V[k * 6 + q];
                    V[k * 6 + p] = c * vkp - s * vkq;
                    V[k * 6 + q] = s * vkp + c * vkq;
                }
            }
        if (!rotated)
            break;
    }
    for (i = 0; i < 6; ++i)
        w[i] = A[i * 7];
}
