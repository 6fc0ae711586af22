/* integrators.c -- one communication step of the plant with the rack forces held
   (integrators.py): classic RK4 and semi-implicit Euler with fixed internal steps, and
   Dormand-Prince 5(4) with error control (FSAL), the same step-size logic and status codes. */
#include <math.h>
#include "internal.h"

/* Dormand-Prince 5(4) tableau (Hairer, Norsett, Wanner: Solving ODEs I, Table 5.2). */
static const double DP_A[7][6] = {
    {0, 0, 0, 0, 0, 0},
    {1.0 / 5, 0, 0, 0, 0, 0},
    {3.0 / 40, 9.0 / 40, 0, 0, 0, 0},
    {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0, 0},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0, 0},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0},
    {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84},
};
static const double DP_E[7] = {71.0 / 57600, 0, -71.0 / 16695, 71.0 / 1920,
                                -17253.0 / 339200, 22.0 / 525, -1.0 / 40};

/* y = y0 advanced over h with n classic RK4 steps. */
static int rk4_advance(const double *p, const double *pl, int ny, const double *y0, double *y,
                       const double F[6], double h, long n)
{
    sw_ws ws;
    double k[4][STEWART_MAX_STATE], tmp[STEWART_MAX_STATE];
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    const double dt = h / (double)n;
    long it;
    int j, s, status;
    sw_ws_init(&ws);
    for (j = 0; j < ny; ++j)
        y[j] = y0[j];
    for (it = 0; it < n; ++it) {
        status = sw_derivative(p, pl, y, F, &ws, k[0]);
        for (s = 1; s < 4 && status == STEWART_OK; ++s) {
            const double a = c[s] * dt;
            for (j = 0; j < ny; ++j)
                tmp[j] = y[j] + a * k[s - 1][j];
            status = sw_derivative(p, pl, tmp, F, &ws, k[s]);
        }
        if (status != STEWART_OK)
            return status;
        for (j = 0; j < ny; ++j)
            y[j] += dt / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
    }
    return STEWART_OK;
}

/* y = y0 advanced over h with n semi-implicit (symplectic) Euler steps: velocities first, then
   positions with the new velocities. */
static int euler_advance(const double *p, const double *pl, int ny, const double *y0,
                         double *y, const double F[6], double h, long n)
{
    sw_ws ws;
    double dy[STEWART_MAX_STATE];
    const double dt = h / (double)n;
    long it;
    int j, b, status;
    sw_ws_init(&ws);
    for (j = 0; j < ny; ++j)
        y[j] = y0[j];
    for (it = 0; it < n; ++it) {
        status = sw_derivative(p, pl, y, F, &ws, dy);
        if (status != STEWART_OK)
            return status;
        for (b = 0; b < ny; b += 12)   /* (q, qd), then (s, sd) with a transmission */
            for (j = 0; j < 6; ++j) {
                y[b + 6 + j] += dt * dy[b + 6 + j];
                y[b + j] += dt * y[b + 6 + j];
            }
    }
    return STEWART_OK;
}

/* y = y0 advanced over h with error-controlled Dormand-Prince 5(4) steps.
   *dt_io: the step to try in, the next one out; *steps,
   *rejected: internal steps taken and rejected. */
static int dopri5_advance(const double *p, const double *pl, int ny, const double *y0,
                          double *y, const double F[6], double h, double *dt_io, double rtol,
                          double atol, double max_step, long max_steps, long *steps_out,
                          long *rejected_out)
{
    sw_ws ws;
    double K[7][STEWART_MAX_STATE], ytmp[STEWART_MAX_STATE], ynew[STEWART_MAX_STATE];
    double t = 0.0, dt = PY_MIN(PY_MIN(*dt_io, max_step), h);
    long steps = 0, rejected = 0;
    int cause = STEWART_OK, status, j, s, m;
    sw_ws_init(&ws);
    for (j = 0; j < ny; ++j)
        y[j] = y0[j];
    status = sw_derivative(p, pl, y, F, &ws, K[0]);
    while (status == STEWART_OK && t < h) {
        int last;
        double step, err, factor;
        if (steps + rejected >= max_steps) {
            status = cause != STEWART_OK ? cause : STEWART_TOO_MANY_STEPS;
            goto done;
        }
        last = t + dt >= h * (1.0 - 1e-12);
        step = last ? h - t : dt;
        for (s = 1; s < 7; ++s) {
            for (j = 0; j < ny; ++j) {
                double acc = 0.0;
                for (m = 0; m < s; ++m)
                    acc += DP_A[s][m] * K[m][j];
                ytmp[j] = y[j] + step * acc;
            }
            status = sw_derivative(p, pl, ytmp, F, &ws, K[s]);
            if (status != STEWART_OK)
                break;
        }
        if (status != STEWART_OK) {  /* a stage left the workspace: retry smaller */
            if (step < 1e-14 * h)
                goto done;
            cause = status;
            dt = 0.25 * step;
            rejected += 1;
            status = sw_derivative(p, pl, y, F, &ws, K[0]);
            continue;
        }
        err = 0.0;
        for (j = 0; j < ny; ++j) {
            double e = 0.0, sc, r;
            ynew[j] = ytmp[j];  /* stage 7 is the 5th-order solution (FSAL) */
            for (s = 0; s < 7; ++s)
                e += DP_E[s] * K[s][j];
            sc = atol + rtol * PY_MAX(fabs(y[j]), fabs(ynew[j]));
            r = step * e / sc;
            err += r * r;
        }
        err = sqrt(err / (double)ny);
        factor = err > 0 ? PY_MIN(5.0, PY_MAX(0.2, 0.9 * pow(err, -0.2))) : 5.0;
        if (err <= 1.0) {
            for (j = 0; j < ny; ++j) {
                y[j] = ynew[j];
                K[0][j] = K[6][j];
            }
            t = last ? h : t + step;
            steps += 1;
            if (!last)
                dt = PY_MIN(step * factor, max_step);
        } else {
            rejected += 1;
            dt = step * PY_MAX(0.2, factor);
            if (dt < 1e-14 * PY_MAX(h, 1e-300)) {
                status = cause != STEWART_OK ? cause : STEWART_STEP_TOO_SMALL;
                goto done;
            }
        }
    }
done:
    *dt_io = dt;
    *steps_out = steps;
    *rejected_out = rejected;
    return status;
}

int stewart_advance(const double *params, const stewart_options *o, const double *y0,
                    double *y1, const double rack[6], double h, double *step_guess,
                    long *evaluations)
{
    double pl[STEWART_N_PARAMS];
    const int ny = stewart_state_size(params);
    long evals = 0;
    int status;
    stewart_leg_side_params(params, pl);
    if (o->method == STEWART_RK4 || o->method == STEWART_EULER) {
        /* n = max(1, ceil(h / max_step - 1e-9)) as stability.internal_step; refused beyond max_steps */
        const double nf = ceil(h / o->max_step - 1e-9);
        long n;
        if (!(nf <= (double)o->max_steps)) {
            if (evaluations)
                *evaluations = 0;
            return STEWART_TOO_MANY_STEPS;
        }
        n = nf < 1.0 ? 1 : (long)nf;
        if (o->method == STEWART_RK4) {
            evals = 4 * n;
            status = rk4_advance(params, pl, ny, y0, y1, rack, h, n);
        } else {
            evals = n;
            status = euler_advance(params, pl, ny, y0, y1, rack, h, n);
        }
    } else if (o->method == STEWART_DOPRI5) {
        long steps = 0, rejected = 0;
        double dt = step_guess ? *step_guess : o->max_step;
        status = dopri5_advance(params, pl, ny, y0, y1, rack, h, &dt, o->rtol, o->atol,
                                o->max_step, o->max_steps, &steps, &rejected);
        if (step_guess)
            *step_guess = dt;
        evals = 1 + 6 * (steps + rejected);
    } else {
        status = -1;  /* unknown method */
    }
    if (evaluations)
        *evaluations = evals;
    return status;
}
