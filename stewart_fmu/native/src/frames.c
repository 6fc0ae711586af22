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

/* ---- motions: a pose with its rates and accelerations (Euler-angle rates) ---------------------
   The tool point p = x + R t moves with v_p = v + w x r, a_p = a + alpha x r + w x (w x r)
   (r = R t, w and alpha of C in N, rotations.c); the frame's angular velocity and
   acceleration in W are Rw^T w and Rw^T alpha (T_M and T_W are constant), and its Euler rates
   solve E(th) thd = w, E(th) thdd = alpha - Edot thd. */

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* The velocity (w x r) and acceleration (alpha x r + w x (w x r)) of the point r (in N, from
   C's origin) beyond those of the origin. */
static void point_motion(const double om[3], const double al[3], const double r[3],
                         double dv[3], double da[3])
{
    double wr[3], wwr[3], ar[3];
    int k;
    cross(om, r, wr);
    cross(om, wr, wwr);
    cross(al, r, ar);
    for (k = 0; k < 3; ++k) {
        dv[k] = wr[k];
        da[k] = ar[k] + wwr[k];
    }
}

/* Euler rates thd and accelerations thdd of the angles of pose p (p[3..5]) that turn with
   angular velocity om and acceleration al (in the frame the angles are measured in).
   0 at gimbal lock. */
static int euler_rates(const double p[6], const double om[3], const double al[3], double thd[3],
                       double thdd[3])
{
    double R[9], w0[3], e[3], trig[4], rates[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    sw_orientation(p, SW_ZERO6, SW_ZERO6, R, w0, e, trig);
    if (!sw_solve_rate_trig(trig, om[0], om[1], om[2], thd))
        return 0;
    rates[3] = thd[0];
    rates[4] = thd[1];
    rates[5] = thd[2];
    sw_orientation(p, rates, SW_ZERO6, R, w0, e, 0);     /* e = Edot thd */
    return sw_solve_rate_trig(trig, al[0] - e[0], al[1] - e[1], al[2] - e[2], thdd);
}

static int motion_from_platform(const double mov[6], const double fix[6], const double Rt[9],
                                const double Rw[9], const double q[6], const double qd[6],
                                const double qdd[6], double f[6], double fd[6], double fdd[6])
{
    double R[9], om[3], al[3], r[3], dv[3], da[3], vp[3], ap[3], omf[3], alf[3];
    int k;
    from_platform(mov, fix, Rt, Rw, q, f);
    sw_orientation(q, qd, qdd, R, om, al, 0);
    apply(R, 0, mov, r);
    point_motion(om, al, r, dv, da);
    for (k = 0; k < 3; ++k) {
        vp[k] = qd[k] + dv[k];
        ap[k] = qdd[k] + da[k];
    }
    apply(Rw, 1, vp, fd);
    apply(Rw, 1, ap, fdd);
    if (!rotates(mov) && !rotates(fix)) {     /* the angles pass through, and so their rates */
        for (k = 3; k < 6; ++k) {
            fd[k] = qd[k];
            fdd[k] = qdd[k];
        }
        return 1;
    }
    apply(Rw, 1, om, omf);
    apply(Rw, 1, al, alf);
    return euler_rates(f, omf, alf, fd + 3, fdd + 3);
}

static int motion_to_platform(const double mov[6], const double fix[6], const double Rt[9],
                              const double Rw[9], const double f[6], const double fd[6],
                              const double fdd[6], double q[6], double qd[6], double qdd[6])
{
    double Rf[9], R[9], omf[3], alf[3], om[3], al[3], r[3], dv[3], da[3], vp[3], ap[3];
    int k;
    sw_frame_to_platform(mov, fix, Rt, Rw, f, q);
    sw_orientation(f, fd, fdd, Rf, omf, alf, 0);
    apply(Rw, 0, omf, om);
    apply(Rw, 0, alf, al);
    apply(Rw, 0, fd, vp);
    apply(Rw, 0, fdd, ap);
    rotation(q, R);
    apply(R, 0, mov, r);
    point_motion(om, al, r, dv, da);
    for (k = 0; k < 3; ++k) {
        qd[k] = vp[k] - dv[k];
        qdd[k] = ap[k] - da[k];
    }
    if (!rotates(mov) && !rotates(fix)) {
        for (k = 3; k < 6; ++k) {
            qd[k] = fd[k];
            qdd[k] = fdd[k];
        }
        return 1;
    }
    return euler_rates(q, om, al, qd + 3, qdd + 3);
}

typedef int (*motion_fn)(const double *, const double *, const double *, const double *,
                         const double *, const double *, const double *, double *, double *,
                         double *);

static long motions(motion_fn fn, const double mov[6], const double fix[6], long n,
                    const double *P, const double *Pd, const double *Pdd, double *O, double *Od,
                    double *Odd)
{
    double Rt[9], Rw[9], skip[6];
    long k;
    sw_frame_rotations(mov, fix, Rt, Rw);
    for (k = 0; k < n; ++k)
        if (!fn(mov, fix, Rt, Rw, P + 6 * k, Pd + 6 * k, Pdd ? Pdd + 6 * k : SW_ZERO6,
                O + 6 * k, Od + 6 * k, Odd ? Odd + 6 * k : skip))
            return -(1 + k);
    return n;
}

long stewart_frame_motion_from_platform(const double mov[6], const double fix[6], long n,
                                        const double *Q, const double *Qd, const double *Qdd,
                                        double *F, double *Fd, double *Fdd)
{
    return motions(motion_from_platform, mov, fix, n, Q, Qd, Qdd, F, Fd, Fdd);
}

long stewart_frame_motion_to_platform(const double mov[6], const double fix[6], long n,
                                      const double *F, const double *Fd, const double *Fdd,
                                      double *Q, double *Qd, double *Qdd)
{
    return motions(motion_to_platform, mov, fix, n, F, Fd, Fdd, Q, Qd, Qdd);
}
