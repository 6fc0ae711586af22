/* kinematics.c -- leg state, the leg Jacobian and its condition number (wrapped by
   kinematics.py and dynamics.leg_state). ldot = J nu, row i = [u_i, (R p_i) x u_i]. */
#include <math.h>
#include "internal.h"

int stewart_leg_state(const double *params, const double q[6], const double qd[6],
                      double l[6], double ldot[6], double omega[3])
{
    sw_ws ws;
    int st, i;
    sw_ws_init(&ws);
    sw_orientation(q, qd, SW_ZERO6, ws.R, ws.om, ws.al, 0);
    st = sw_twist_forces(params, q, qd, SW_ZERO6, ws.al, &ws);
    for (i = 0; i < 6; ++i) {
        l[i] = ws.leg[3 * i];
        ldot[i] = ws.leg[3 * i + 1];
    }
    for (i = 0; i < 3; ++i)
        omega[i] = ws.om[i];
    return st;
}

/* J rows [u_i, scale (r_i x u_i)] from the legs' unit vectors U and the platform joints'
   arms R (both 6 x 3): the one Jacobian of the core (kinematics and reach.c). */
void sw_jacobian_rows(const double U[18], const double R[18], double scale, double J[36])
{
    int i;
    for (i = 0; i < 6; ++i) {
        const double u0 = U[3 * i], u1 = U[3 * i + 1], u2 = U[3 * i + 2];
        const double r0 = R[3 * i], r1 = R[3 * i + 1], r2 = R[3 * i + 2];
        J[6 * i] = u0;
        J[6 * i + 1] = u1;
        J[6 * i + 2] = u2;
        J[6 * i + 3] = scale * (r1 * u2 - r2 * u1);
        J[6 * i + 4] = scale * (r2 * u0 - r0 * u2);
        J[6 * i + 5] = scale * (r0 * u1 - r1 * u0);
    }
}

int stewart_jacobian(const double *params, const double q[6], int scaled, double J[36])
{
    sw_ws ws;
    int st;
    sw_ws_init(&ws);
    sw_orientation(q, SW_ZERO6, SW_ZERO6, ws.R, ws.om, ws.al, 0);
    st = sw_twist_forces(params, q, SW_ZERO6, SW_ZERO6, ws.al, &ws);
    sw_jacobian_rows(ws.U, ws.Rr, scaled ? 1.0 / params[STEWART_P_CHAR_LENGTH] : 1.0, J);
    return st;
}

/* cond(J) = s_max / s_min of the scaled Jacobian, as numpy.linalg.cond (2-norm). */
int stewart_condition_number(const double *params, const double q[6], double *cond)
{
    double J[36];
    int i;
    for (i = 0; i < 6; ++i)
        if (!isfinite(q[i])) {
            *cond = HUGE_VAL;
            return STEWART_NONFINITE;
        }
    stewart_jacobian(params, q, 1, J);
    *cond = sw_condition(J);
    return STEWART_OK;
}
