/* energy.c -- mechanical energy of the plant state and the power balance of a step
   (stewart_energy_terms, stewart_step_energy). E = T + V_g + V_s with T = nu^T M_nu nu / 2
   (+ m_d,i sd_i^2 / 2 per motor with a transmission), V_g = -sum m g . r, V_s = k (s - l)^2 / 2;
   with the rack forces F held, dE = F . dd - D, D >= 0 the dissipation. */
#include <math.h>
#include "internal.h"

#define P(k) p[STEWART_P_##k]

void sw_energy_terms(const double *p, const double *y, sw_ws *ws, double out[9])
{
    double pl[STEWART_N_PARAMS], nu[6], T = 0.0, V, Vs = 0.0;
    const double gx = P(GRAVITY), gy = p[STEWART_P_GRAVITY + 1], gz = p[STEWART_P_GRAVITY + 2];
    const int compliant = P(HAS_TRANSMISSION) != 0.0;
    int a, b, i;
    stewart_leg_side_params(p, pl);
    sw_leg_kinematics(pl, y, ws);
    sw_twist_mass_matrix(pl, ws, 1);
    nu[0] = y[6];
    nu[1] = y[7];
    nu[2] = y[8];
    nu[3] = ws->om[0];
    nu[4] = ws->om[1];
    nu[5] = ws->om[2];
    for (a = 0; a < 6; ++a)
        for (b = 0; b < 6; ++b)
            T += 0.5 * nu[a] * ws->Mt[a * 6 + b] * nu[b];
    V = -P(MASS) * (gx * y[0] + gy * y[1] + gz * y[2]);
    if (P(HAS_PAYLOAD) != 0.0) {   /* its kinetic energy is in M_nu */
        double rho[3];
        sw_payload_lever(p, ws->R, rho);
        V -= P(PAYLOAD_MASS) * (gx * (y[0] + rho[0]) + gy * (y[1] + rho[1]) + gz * (y[2] + rho[2]));
    }
    for (i = 0; i < 6; ++i) {
        const double l = ws->leg[3 * i];
        if (P(HAS_LEGS) != 0.0) {
            const int k = STEWART_P_BASE + 3 * i;
            const double ga = gx * p[k] + gy * p[k + 1] + gz * p[k + 2];
            const double gu = gx * ws->U[3 * i] + gy * ws->U[3 * i + 1] + gz * ws->U[3 * i + 2];
            const double mA = P(LOWER), cA = p[STEWART_P_LOWER + 1];
            const double mB = P(UPPER), cB = p[STEWART_P_UPPER + 1];
            V -= mA * (ga + cA * gu) + mB * (ga + (l - cB) * gu);
        }
        if (compliant) {
            const double sd = y[18 + i], ds = y[12 + i] - l;
            T += 0.5 * p[STEWART_P_DRIVE_MASS + i] * (sd * sd);
            Vs += 0.5 * P(STIFFNESS) * (ds * ds);
            out[STEWART_ENERGY_DRIVEN + i] = y[12 + i];
        } else {
            out[STEWART_ENERGY_DRIVEN + i] = l;
        }
    }
    out[STEWART_ENERGY_KINETIC] = T;
    out[STEWART_ENERGY_POTENTIAL] = V;
    out[STEWART_ENERGY_SPRING] = Vs;
}

void stewart_energy_terms(const double *params, const double *y, double out[9])
{
    sw_ws ws;
    sw_ws_init(&ws);
    sw_energy_terms(params, y, &ws, out);
}

int stewart_step_energy(const double *params, const double *y1, const double e0[9],
                        double e1[9], const double rack[6], double tol, double h,
                        double *excess, double *allowed)
{
    const double *p = params;
    const int n = stewart_state_size(params);
    double work = 0.0, moved[6], coulomb = 0.0, allowance = 0.0, scale;
    sw_ws ws;
    int i;
    for (i = 0; i < n; ++i)
        if (!isfinite(y1[i])) {
            *excess = 0.0;
            *allowed = 0.0;
            return 0;
        }
    sw_ws_init(&ws);
    sw_energy_terms(params, y1, &ws, e1);
    for (i = 0; i < 6; ++i) {
        const double d = e1[STEWART_ENERGY_DRIVEN + i] - e0[STEWART_ENERGY_DRIVEN + i];
        work += rack[i] * d;
        moved[i] = fabs(d);
        coulomb = PY_MAX(coulomb, p[STEWART_P_COULOMB + i]);
    }
    *excess = (e1[0] + e1[1] + e1[2]) - (e0[0] + e0[1] + e0[2]) - work;
    scale = e0[0] + e1[0] + e0[2] + e1[2] + fabs(work) + 1e-9 * (fabs(e0[1]) + fabs(e1[1]));
    if (coulomb > 0.0) {
        /* the friction's sign changes inside the step: its work bound also counts the path
           the legs would cover at their end rates (h |ldot_i|: the leg rows the energy terms
           computed at y1, as stewart_leg_state would) */
        for (i = 0; i < 6; ++i)
            moved[i] += h * fabs(ws.leg[3 * i + 1]);
    }
    for (i = 0; i < 6; ++i)  /* each leg's Coulomb force times its path */
        allowance += p[STEWART_P_COULOMB + i] * moved[i];
    *allowed = tol * scale + allowance;
    return 1;
}
