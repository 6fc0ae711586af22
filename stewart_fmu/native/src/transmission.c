/* transmission.c -- the plant's right-hand side y' = f(y, F) (integrators.derivative) and the
   compliant transmission (transmission.py): each drive's inertia m_d on its own coordinate s_i,
   sprung to its leg, f_i = k (s_i - l_i) + c (sd_i - ld_i), m_d sdd_i = F_i - f_i; the legs
   and platform move under f as under sigma of a drive-less model. */
#include "internal.h"

#define P(k) p[STEWART_P_##k]

void stewart_leg_side_params(const double *params, double out[STEWART_N_PARAMS])
{
    int k;
    for (k = 0; k < STEWART_N_PARAMS; ++k)
        out[k] = params[k];
    if (params[STEWART_P_HAS_TRANSMISSION] != 0.0)
        out[STEWART_P_HAS_DRIVE] = 0.0;
}

/* R, omega, U, Rr and the leg rows (l, ld) at y's pose and rates. */
int sw_leg_kinematics(const double *pl, const double *y, sw_ws *ws)
{
    sw_orientation(y, y + 6, SW_ZERO6, ws->R, ws->om, ws->al, ws->trig);
    return sw_twist_forces(pl, y, y + 6, SW_ZERO6, ws->al, ws);
}

static double spring(const double *p, const double *y, const sw_ws *ws, int i)
{
    return P(STIFFNESS) * (y[12 + i] - ws->leg[3 * i]) + P(DAMPING) * (y[18 + i] - ws->leg[3 * i + 1]);
}

/* dy = (qd, qdd, sd, sdd) of the 24-state plant. */
static int compliant_derivative(const double *p, const double *pl, const double *y,
                                const double F[6], sw_ws *ws, double *dy)
{
    double f[6];
    int i, status;
    sw_leg_kinematics(pl, y, ws);
    for (i = 0; i < 6; ++i)
        f[i] = spring(p, y, ws, i);
    status = sw_forward_sample(pl, y, y + 6, f, ws, dy + 6);
    for (i = 0; i < 6; ++i) {
        dy[i] = y[6 + i];
        dy[12 + i] = y[18 + i];
        dy[18 + i] = (F[i] - f[i]) / p[STEWART_P_DRIVE_MASS + i];
    }
    return status;
}

/* y' at y with the rack force F; pl: the leg-side parameters (stewart_leg_side_params). */
int sw_derivative(const double *p, const double *pl, const double *y, const double F[6],
                  sw_ws *ws, double *dy)
{
    int status, k;
    if (P(HAS_TRANSMISSION) != 0.0)
        return compliant_derivative(p, pl, y, F, ws, dy);
    status = sw_forward_sample(p, y, y + 6, F, ws, dy + 6);
    for (k = 0; k < 6; ++k)
        dy[k] = y[6 + k];
    return status;
}

int stewart_derivative(const double *params, const double *y, const double rack[6], double *dy)
{
    double pl[STEWART_N_PARAMS];
    sw_ws ws;
    sw_ws_init(&ws);
    stewart_leg_side_params(params, pl);
    return sw_derivative(params, pl, y, rack, &ws, dy);
}

int stewart_spring_forces(const double *params, const double *y, double f[6])
{
    double pl[STEWART_N_PARAMS];
    sw_ws ws;
    int st, i;
    sw_ws_init(&ws);
    stewart_leg_side_params(params, pl);
    st = sw_leg_kinematics(pl, y, &ws);
    for (i = 0; i < 6; ++i)
        f[i] = spring(params, y, &ws, i);
    return st;
}

int stewart_plant_parts(const double *params, const double *y, const double rack[6], double parts[36])
{
    double dy[STEWART_MAX_STATE], pl[STEWART_N_PARAMS];
    int st, i;
    for (i = 0; i < 36; ++i)
        parts[i] = 0.0;
    if (params[STEWART_P_HAS_TRANSMISSION] == 0.0) {
        st = stewart_forward_dynamics(params, y, y + 6, rack, dy + 6);
        return st != STEWART_OK ? st : stewart_inverse_dynamics_parts(params, y, y + 6, dy + 6, parts);
    }
    /* the legs move under the spring forces as a drive-less model: its parts at the legs'
       accelerations, and the drives' own m_d sdd */
    stewart_leg_side_params(params, pl);
    st = stewart_derivative(params, y, rack, dy);
    if (st != STEWART_OK)
        return st;
    st = stewart_inverse_dynamics_parts(pl, y, y + 6, dy + 6, parts);
    for (i = 0; i < 6; ++i)
        parts[STEWART_PART_DRIVES * 6 + i] = params[STEWART_P_DRIVE_MASS + i] * dy[18 + i];
    return st;
}

int stewart_state_size(const double *params)
{
    return params[STEWART_P_HAS_TRANSMISSION] != 0.0 ? 24 : 12;
}

int stewart_initial_state(const double *params, const double q[6], const double qd[6],
                          const double *rack, double *y)
{
    int i;
    for (i = 0; i < 6; ++i) {
        y[i] = q[i];
        y[6 + i] = qd[i];
    }
    if (params[STEWART_P_HAS_TRANSMISSION] == 0.0)
        return 12;
    {
        double l[6], ld[6], om[3];
        stewart_leg_state(params, q, qd, l, ld, om);
        for (i = 0; i < 6; ++i) {
            y[12 + i] = l[i] + (rack ? rack[i] : 0.0) / params[STEWART_P_STIFFNESS];
            y[18 + i] = ld[i];
        }
    }
    return 24;
}
