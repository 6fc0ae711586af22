/* frames.c -- poses in other frames than C in N: a moving frame M fixed to the platform (given
   in C) seen from a fixed frame W (given in N), f = T_W^-1 T_C(q) T_M, and back. The pivot
   point is an M without rotation; a tool frame an M; a user frame a W. */
#include <math.h>
#include "internal.h"

/* R = Rz Ry Rx of a pose's angles (the core's one rotation, rotations.c). */
static void rotation(const double pose[6], double R[9])
{
    double om[3], al[3];
    sw_orientation(pose, SW_ZERO6, SW_ZERO6, R, om, al, 0);
}

/* The angles of R = Rz(thz) Ry(thy) Rx(thx): thy in [-pi/2, pi/2], thx and thz in (-pi, pi]. */
static void angles(const double R[9], double th[3])
{
    th[0] = atan2(R[7], R[8]);
    th[1] = atan2(-R[6], sqrt(R[0] * R[0] + R[3] * R[3]));
    th[2] = atan2(R[3], R[0]);
}

static int rotates(const double pose[6])
{
    return pose[3] != 0.0 || pose[4] != 0.0 || pose[5] != 0.0;
}

/* C = A B (transpose_a: A^T B) of 3x3 row-major matrices. */
static void product(const double A[9], int transpose_a, const double B[9], int transpose_b,
                    double C[9])
{
    int i, j, k;
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) {
            double s = 0.0;
            for (k = 0; k < 3; ++k)
                s += (transpose_a ? A[3 * k + i] : A[3 * i + k])
                     * (transpose_b ? B[3 * j + k] : B[3 * k + j]);
            C[3 * i + j] = s;
        }
}

/* y = A x (transpose: A^T x). */
static void apply(const double A[9], int transpose, const double x[3], double y[3])
{
    int i;
    for (i = 0; i < 3; ++i)
        y[i] = transpose ? A[i] * x[0] + A[3 + i] * x[1] + A[6 + i] * x[2]
                         : A[3 * i] * x[0] + A[3 * i + 1] * x[1] + A[3 * i + 2] * x[2];
}

static void from_platform(const double mov[6], const double fix[6], const double Rt[9],
                          const double Rw[9], const double q[6], double f[6])
{
    double R[9], Rm[9], Rf[9], t[3], pm[3];
    int k;
    rotation(q, R);
    apply(R, 0, mov, t);
    for (k = 0; k < 3; ++k)
        pm[k] = (q[k] + t[k]) - fix[k];
    apply(Rw, 1, pm, f);
    if (!rotates(mov) && !rotates(fix)) {
        f[3] = q[3];
        f[4] = q[4];
        f[5] = q[5];
        return;
    }
    product(R, 0, Rt, 0, Rm);
    product(Rw, 1, Rm, 0, Rf);
    angles(Rf, f + 3);
}

void sw_frame_rotations(const double mov[6], const double fix[6], double Rt[9], double Rw[9])
{
    rotation(mov, Rt);
    rotation(fix, Rw);
}

void sw_frame_to_platform(const double mov[6], const double fix[6], const double Rt[9],
                          const double Rw[9], const double f[6], double q[6])
{
    double Rf[9], Rm[9], R[9], pm[3], t[3];
    int k;
    if (!rotates(mov) && !rotates(fix)) {
        q[3] = f[3];
        q[4] = f[4];
        q[5] = f[5];
    } else {
        rotation(f, Rf);
        product(Rw, 0, Rf, 0, Rm);
        product(Rm, 0, Rt, 1, R);
        angles(R, q + 3);
    }
    rotation(q, R);   /* the rotation of the angles returned, so that x + R t is the frame's */
    apply(Rw, 0, f, pm);
    apply(R, 0, mov, t);
    for (k = 0; k < 3; ++k)
        q[k] = (pm[k] + fix[k]) - t[k];
}

void stewart_frame_from_platform(const double mov[6], const double fix[6], long n,
                                 const double *Q, double *F)
{
    double Rt[9], Rw[9];
    long k;
    sw_frame_rotations(mov, fix, Rt, Rw);
    for (k = 0; k < n; ++k)
        from_platform(mov, fix, Rt, Rw, Q + 6 * k, F + 6 * k);
}

void stewart_frame_to_platform(const double mov[6], const double fix[6], long n,
                               const double *F, double *Q)
{
    double Rt[9], Rw[9];
    long k;
    sw_frame_rotations(mov, fix, Rt, Rw);
    for (k = 0; k < n; ++k)
        sw_frame_to_platform(mov, fix, Rt, Rw, F + 6 * k, Q + 6 * k);
}
