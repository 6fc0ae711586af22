/* rotations.c -- R = Rz(thz) Ry(thy) Rx(thx), omega = E thd, alpha = E thdd + Edot thd
   (rotations.euler_motion in numpy), and E^-1 (rotations.solve_rate_matrix). */
#include <math.h>
#include "internal.h"

void sw_orientation(const double q[6], const double qd[6], const double qdd[6], double R[9],
                    double om[3], double al[3], double *trig)
{
    double cx = cos(q[3]), sx = sin(q[3]);
    double cy = cos(q[4]), sy = sin(q[4]);
    double cz = cos(q[5]), sz = sin(q[5]);
    if (trig) {  /* for sw_solve_rate_trig at the same pose */
        trig[0] = cy;
        trig[1] = sy;
        trig[2] = cz;
        trig[3] = sz;
    }
    double t0 = qd[3], t1 = qd[4], t2 = qd[5];
    double e1x, e1y, e1z, e2x, e2y, d1x, d1y, d1z, d2x, d2y;
    R[0] = cz * cy;
    R[1] = cz * sy * sx - sz * cx;
    R[2] = cz * sy * cx + sz * sx;
    R[3] = sz * cy;
    R[4] = sz * sy * sx + cz * cx;
    R[5] = sz * sy * cx - cz * sx;
    R[6] = -sy;
    R[7] = cy * sx;
    R[8] = cy * cx;
    /* Columns of E: Rz Ry e_x, Rz e_y, e_z; and their time derivatives. */
    e1x = cy * cz; e1y = cy * sz; e1z = -sy;
    e2x = -sz; e2y = cz;
    d1x = -sy * t1 * cz - cy * sz * t2;
    d1y = -sy * t1 * sz + cy * cz * t2;
    d1z = -cy * t1;
    d2x = -cz * t2; d2y = -sz * t2;
    om[0] = e1x * t0 + e2x * t1;
    om[1] = e1y * t0 + e2y * t1;
    om[2] = e1z * t0 + t2;
    al[0] = e1x * qdd[3] + e2x * qdd[4] + d1x * t0 + d2x * t1;
    al[1] = e1y * qdd[3] + e2y * qdd[4] + d1y * t0 + d2y * t1;
    al[2] = e1z * qdd[3] + qdd[5] + d1z * t0;
}

/* Euler-angle rates x with E(th) x = w (rotations.solve_rate_matrix), from the cosines and
   sines (cy, sy, cz, sz) of pitch and yaw that sw_orientation returned; 0 at gimbal lock. */
int sw_solve_rate_trig(const double trig[4], double w0, double w1, double w2, double x[3])
{
    const double cy = trig[0], sy = trig[1], cz = trig[2], sz = trig[3];
    double x0;
    if (fabs(cy) < STEWART_GIMBAL_LIMIT) {
        x[0] = x[1] = x[2] = 0.0;
        return 0;
    }
    x0 = (cz * w0 + sz * w1) / cy;
    x[0] = x0;
    x[1] = -sz * w0 + cz * w1;
    x[2] = w2 + sy * x0;
    return 1;
}

void stewart_orientation(const double q[6], const double qd[6], const double *qdd,
                         double R[9], double omega[3], double alpha[3])
{
    static const double zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    sw_orientation(q, qd, qdd ? qdd : zero, R, omega, alpha, 0);
}
