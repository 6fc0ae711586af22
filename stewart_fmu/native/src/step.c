/* step.c -- THE plant step (component.c's do_step without its call-sequence checks): the
   integrator's advance, then the finiteness and power-balance check of stewart_step_energy.
   Also the default options and a caller-owned per-run state (stewart_data). */
#include "internal.h"

const char *stewart_method_name(int method)
{
    static const char *const NAMES[STEWART_N_METHODS] = {"rk4", "euler", "dopri5"};
    return method >= 0 && method < STEWART_N_METHODS ? NAMES[method] : 0;
}

stewart_options stewart_default_options(void)
{
    stewart_options o;
    o.method = STEWART_RK4;
    o.rtol = 1e-8;
    o.atol = 1e-10;
    o.max_step = 1e-3;
    o.max_steps = 10000;
    o.energy_tol = STEWART_ENERGY_TOL;
    return o;
}

int stewart_step(const double *params, const stewart_options *o, const double *y0, double *y1,
                 const double rack[6], double h, double *step_guess, long *evaluations,
                 const double e0[STEWART_N_ENERGY], double e1[STEWART_N_ENERGY],
                 double *excess, double *allowed)
{
    double ex = 0.0, al = 0.0;
    int status = stewart_advance(params, o, y0, y1, rack, h, step_guess, evaluations);
    if (status == STEWART_OK) {
        if (!stewart_step_energy(params, y1, e0, e1, rack, o->energy_tol, h, &ex, &al))
            status = STEWART_STATE_NONFINITE;
        else if (!(ex <= al))
            status = STEWART_UNSTABLE;
    }
    if (excess)
        *excess = ex;
    if (allowed)
        *allowed = al;
    return status;
}

void stewart_data_init(const double *params, const stewart_options *o, const double q[6],
                       const double qd[6], const double *rack, double t, stewart_data *d)
{
    int i;
    for (i = 0; i < STEWART_MAX_STATE; ++i)
        d->y[i] = 0.0;
    d->n = stewart_initial_state(params, q, qd, rack, d->y);
    stewart_energy_terms(params, d->y, d->energy);
    d->t = t;
    d->step_guess = o->max_step;
    d->evaluations = 0;
    d->excess = d->allowed = 0.0;
}

int stewart_data_step(const double *params, const stewart_options *o, stewart_data *d,
                      const double rack[6], double h)
{
    double y1[STEWART_MAX_STATE], e1[STEWART_N_ENERGY];
    long evals = 0;
    int i, status = stewart_step(params, o, d->y, y1, rack, h, &d->step_guess, &evals,
                                 d->energy, e1, &d->excess, &d->allowed);
    d->evaluations += evals;
    if (status == STEWART_OK) {
        for (i = 0; i < d->n; ++i)
            d->y[i] = y1[i];
        for (i = 0; i < STEWART_N_ENERGY; ++i)
            d->energy[i] = e1[i];
        d->t += h;
    }
    return status;
}

int stewart_data_run(const double *params, const stewart_options *o, stewart_data *d,
                     const double rack[6], double h, long n, long *done)
{
    long k;
    int status = STEWART_OK;
    for (k = 0; k < n; ++k) {
        status = stewart_data_step(params, o, d, rack, h);
        if (status != STEWART_OK)
            break;
    }
    if (done)
        *done = k;
    return status;
}
