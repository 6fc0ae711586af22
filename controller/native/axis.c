/* axis.c -- the axis controllers, the motor currents and the closed loop around the plant's C
   core (controller/axis.py, controller/cosim.py). Compile with -ffp-contract=off (no fused
   multiply-add), as the core: the arithmetic is the same, in the same order, as the Python
   loop's. */
#include <math.h>
#include "axis.h"

/* Python's min(a, b) / max(a, b): the first argument unless the second
   compares smaller (larger), so a NaN first argument passes through. */
#define PY_MIN(a, b) ((b) < (a) ? (b) : (a))
#define PY_MAX(a, b) ((b) > (a) ? (b) : (a))

void pid_voltages(double kp, double ki, double kd, double vmax, double dt, double *integral,
                  const double *l_ref, const double *ldot_ref, const double *l,
                  const double *ldot, const double *v_ff, double *v, unsigned char *sat)
{
    int i;
    for (i = 0; i < 6; ++i) {
        const double e = l_ref[i] - l[i];
        const double u = kp * e + ki * integral[i] + kd * (ldot_ref[i] - ldot[i]) + v_ff[i];
        const double out = PY_MIN(PY_MAX(u, -vmax), vmax);
        v[i] = out;
        sat[i] = out != u;
        if (!(sat[i] && (e > 0) == (u > 0) && e != 0.0))
            integral[i] += e * dt;
    }
}

void advance_currents(double R, double Kt, double emf, double ilim, double decay,
                      double mean_decay, double *current, const double *v,
                      const double *ldot, double *torque, unsigned char *limited)
{
    int i;
    for (i = 0; i < 6; ++i) {
        const double steady = (v[i] - emf * ldot[i]) / R;
        const double gap = current[i] - steady;
        const double mean = steady + gap * mean_decay;
        const double end = steady + gap * decay;
        limited[i] = fabs(mean) > ilim;
        current[i] = PY_MIN(PY_MAX(end, -ilim), ilim);
        torque[i] = Kt * PY_MIN(PY_MAX(mean, -ilim), ilim);
    }
}

void axis_step(const axis_loop *c, double *integral, double *current, const double *l_ref,
               const double *ldot_ref, const double *l, const double *ldot, const double *v_ff,
               double *v, double *torque, unsigned char *sat)
{
    unsigned char vsat[6], limited[6];
    int i;
    pid_voltages(c->kp, c->ki, c->kd, c->vmax, c->dt, integral, l_ref, ldot_ref, l, ldot, v_ff,
                 v, vsat);
    advance_currents(c->R, c->Kt, c->emf, c->ilim, c->decay, c->mean_decay, current, v, ldot,
                     torque, limited);
    for (i = 0; i < 6; ++i)
        sat[i] = vsat[i] || limited[i];
}

int closed_loop_run(const double *params, const stewart_options *o, const axis_loop *c,
                    stewart_data *d, double *integral, double *current, const double *t,
                    long n, const double *l_ref, const double *ldot_ref, const double *v_ff,
                    long k0, long k1, double *held, const axis_records *rec, long *k_fail)
{
    double l[6], ldot[6], om[3], v[6], torque[6], rack[6];
    unsigned char sat[6];
    long k;
    int i, status;
    for (k = k0; k < k1; ++k) {
        const long r = 6 * k;
        int diverged = 0;
        stewart_leg_state(params, d->y, d->y + 6, l, ldot, om);
        axis_step(c, integral, current, l_ref + r, ldot_ref + r, l, ldot, v_ff + r, v, torque,
                  sat);
        for (i = 0; i < 6; ++i) {
            const double err = fabs(l_ref[r + i] - l[i]);
            rec->l[r + i] = l[i];
            rec->ldot[r + i] = ldot[i];
            rec->q[r + i] = d->y[i];
            rec->v[r + i] = v[i];
            rec->i[r + i] = current[i];
            rec->tau[r + i] = torque[i];
            rec->sat[r + i] = sat[i];
            if (!(err <= c->bound))
                diverged = 1;
        }
        if (diverged) {
            *k_fail = k;
            return AXIS_DIVERGED;
        }
        if (k + 1 < n) {
            /* the torque over this period: this sample's, or (one period of delay) the one
               latched at the last sample; this sample's is latched after the step, so that a
               failed step leaves in held the torque it was given */
            const double *applied = held ? held : torque;
            for (i = 0; i < 6; ++i)
                rack[i] = 0.0 + c->gain * applied[i]; /* the rack force: sigma (0) + zeta/r tau */
            status = stewart_data_step(params, o, d, rack, t[k + 1] - t[k]);
            if (status != STEWART_OK) {
                *k_fail = k;
                return status;
            }
            if (held)
                for (i = 0; i < 6; ++i)
                    held[i] = torque[i];
        }
    }
    *k_fail = -1;
    return 0;
}
