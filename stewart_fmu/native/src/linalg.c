/* linalg.c -- small dense 6x6 solves and the singular values of a 6x6 (for cond(J),
   kinematics.condition_number). No allocation; row-major. */
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

/* Singular values of a 6x6 (unordered) by one-sided Jacobi (Hestenes): plane rotations of
   column pairs until all columns are orthogonal to working precision; the singular values
   are then the column norms. Each value is found to high relative accuracy. */
void sw_singular_values(const double A[36], double s[6])
{
    double W[36];
    int i, j, k, sweep;
    for (i = 0; i < 36; ++i)
        W[i] = A[i];
    for (sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (j = 0; j < 5; ++j) {
            for (k = j + 1; k < 6; ++k) {
                double alpha = 0.0, beta = 0.0, gamma = 0.0, zeta, t, c, sn;
                for (i = 0; i < 6; ++i) {
                    double a = W[i * 6 + j], b = W[i * 6 + k];
                    alpha += a * a;
                    beta += b * b;
                    gamma += a * b;
                }
                if (gamma == 0.0 || fabs(gamma) <= 2.2e-16 * sqrt(alpha * beta))
                    continue;
                rotated = 1;
                zeta = (beta - alpha) / (2.0 * gamma);
                t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                c = 1.0 / sqrt(1.0 + t * t);
                sn = c * t;
                for (i = 0; i < 6; ++i) {
                    double a = W[i * 6 + j], b = W[i * 6 + k];
                    W[i * 6 + j] = c * a - sn * b;
                    W[i * 6 + k] = sn * a + c * b;
                }
            }
        }
        if (!rotated)
            break;
    }
    for (j = 0; j < 6; ++j) {
        double n = 0.0;
        for (i = 0; i < 6; ++i)
            n += W[i * 6 + j] * W[i * 6 + j];
        s[j] = sqrt(n);
    }
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
