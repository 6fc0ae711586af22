/*
 * axis.h -- the six axis controllers, their drives and the closed loop around the plant's C
 * core, in plain C99 (libm only). A port of controller/axis.py (pid_voltages,
 * advance_currents) and of controller/cosim.py's compiled in-process loop, with the same
 * arithmetic in the same order.
 *
 * Arrays: double vectors of 6 (one entry per leg); per-sample tables are row-major (n, 6).
 * Flags are one byte per leg (numpy bool_: 0 or 1). Reentrant: no global state, no malloc.
 */
#ifndef STEWART_AXIS_H
#define STEWART_AXIS_H

#include "stewart.h"

#ifdef __cplusplus
extern "C" {
#endif

/* closed_loop_run's status when a leg's tracking error is beyond the bound (or not finite):
   cosim.DIVERGED. Any other non-zero status is the plant step's (stewart_step). */
#define AXIS_DIVERGED (-1)

/* Six discrete PIDs: e = l_ref - l, u = kp e + ki integral + kd (ldot_ref - ldot) + v_ff,
   v = u clipped to [-vmax, vmax], sat = (v != u); the integral advances by e dt unless the
   output is saturated and the error would drive it further (anti-windup). */
void pid_voltages(double kp, double ki, double kd, double vmax, double dt, double *integral,
                  const double *l_ref, const double *ldot_ref, const double *l,
                  const double *ldot, const double *v_ff, double *v, unsigned char *sat);

/* The motor currents over one held step, exact: steady = (v - emf ldot) / R, the gap to it
   decays by `decay` at the step's end and by `mean_decay` on average over it; current = the
   end value clamped to +-ilim, torque = Kt * (the mean clamped to +-ilim), limited = |mean| >
   ilim. */
void advance_currents(double R, double Kt, double emf, double ilim, double decay,
                      double mean_decay, double *current, const double *v,
                      const double *ldot, double *torque, unsigned char *limited);

/* The constants of the loop: PID gains and limits, motor, rack force per torque, bound. */
typedef struct {
    double kp, ki, kd, vmax, dt;            /* pid_voltages */
    double R, Kt, emf, ilim, decay, mean_decay; /* advance_currents */
    double gain;                            /* zeta / r: rack force = gain * torque */
    double bound;                           /* divergence: a leg error beyond it stops the run */
} axis_loop;

/* One controller sample of the six axes (the closed loop's and the controller FMU's, one
   implementation): pid_voltages -> advance_currents with c's constants; integral and current
   advance; v the voltages, torque the mean motor torques over the sample, sat voltage saturated
   or current limited. */
void axis_step(const axis_loop *c, double *integral, double *current, const double *l_ref,
               const double *ldot_ref, const double *l, const double *ldot, const double *v_ff,
               double *v, double *torque, unsigned char *sat);

/* Per-sample records (n, 6) each, written at the samples run. */
typedef struct {
    double *l, *ldot, *q, *v, *i, *tau;
    unsigned char *sat;                     /* voltage saturated or current limited */
} axis_records;

/* Samples k0..k1-1 of the closed loop: measure the legs (stewart_leg_state at the plant state
   d->y) -> pid_voltages -> advance_currents -> record -> divergence check -> (unless k is the
   last sample, k + 1 == n) the plant step over t[k+1] - t[k] with the rack forces gain * torque
   (stewart_data_step with options o). held NULL: the torque of sample k drives the step from
   t[k] (no delay); else one period of actuation delay: the step from t[k] takes the torques in
   held (on the first call the drives' start torque), and held then takes sample k's. The state
   carries across calls in d (y, energy terms, step guess, time), integral, current and held,
   so consecutive calls equal one call. Returns 0 with *k_fail = -1 when all samples ran; else
   the status (AXIS_DIVERGED, or the plant step's, the state then is that at the start of the
   failed step, held still the torques it took) with *k_fail = the sample. */
int closed_loop_run(const double *params, const stewart_options *o, const axis_loop *c,
                    stewart_data *d, double *integral, double *current, const double *t,
                    long n, const double *l_ref, const double *ldot_ref, const double *v_ff,
                    long k0, long k1, double *held, const axis_records *rec, long *k_fail);

#ifdef __cplusplus
}
#endif
#endif /* STEWART_AXIS_H */
