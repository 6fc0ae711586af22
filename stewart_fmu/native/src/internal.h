/* internal.h -- shared declarations of the C core (not part of the public API). */
#ifndef STEWART_INTERNAL_H
#define STEWART_INTERNAL_H

#include "../include/stewart.h"

/* Python's builtin min(a, b) / max(a, b): the first argument unless the
   second compares smaller (larger); a NaN in the second argument is never taken. */
#define PY_MIN(a, b) ((b) < (a) ? (b) : (a))
#define PY_MAX(a, b) ((b) > (a) ? (b) : (a))

/* Six zeros: a pose row at rest. */
static const double SW_ZERO6[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};

/* Scratch of one sample: R, omega, alpha, unit vectors U, lever arms
   Rr = R p_i, leg rows (l, ldot, lddot), the rates udot and P uddot of the unit vectors (Ud, Pu:
   the regressor of regressor.c reads them), J^T (scaled, rows stored where order[1] says), the
   generalized forces gen (4 x 6), a right-hand side and the twist mass matrix. order carries
   from sample to sample (see linalg.c, sw_lu_factor). All matrices row-major. */
typedef struct {
    double R[9], om[3], al[3], trig[4];
    double U[18], Rr[18], leg[18], Ud[18], Pu[18];
    double JT[36], gen[24], rhs[6], Mt[36];
    int order[12];          /* order[0..5]: row names at storage rows; order[6..11]: where */
} sw_ws;

void sw_ws_init(sw_ws *ws);

/* rotations.c */
void sw_orientation(const double q[6], const double qd[6], const double qdd[6], double R[9],
                    double om[3], double al[3], double *trig);
int sw_solve_rate_trig(const double trig[4], double w0, double w1, double w2, double x[3]);

/* linalg.c */
double sw_lu_factor(double A[36], int order[12]);
void sw_lu_solve(const double LU[36], double b[6]);
int sw_cholesky_solve(double A[36], double b[6]);
int sw_cholesky_factor(double A[36]);
void sw_cholesky_forward(const double L[36], double b[6]);
void sw_cholesky_back(const double L[36], double b[6]);
void sw_symmetric_eigen(double A[36], double w[6], double V[36]);
void sw_singular_range(const double A[36], double *smax, double *smin);
double sw_condition(const double A[36]);

/* kinematics.c */
void sw_jacobian_rows(const double U[18], const double R[18], double scale, double J[36]);

/* kane.c */
int sw_twist_forces(const double *p, const double x[6], const double v[6], const double acc[6],
                    const double al[3], sw_ws *ws);
void sw_twist_mass_matrix(const double *p, sw_ws *ws, int full);
void sw_payload_lever(const double *p, const double R[9], double rho[3]);
void sw_payload_mass(const double *p, const double R[9], double M[36]);

/* dynamics.c */
int sw_inverse_sample(const double *p, const double q[6], const double qd[6],
                      const double qdd[6], sw_ws *ws, double out[6]);
int sw_parts_sample(const double *p, const double q[6], const double qd[6],
                    const double qdd[6], sw_ws *ws, double out[36]);
int sw_forward_sample(const double *p, const double q[6], const double qd[6],
                      const double sigma[6], sw_ws *ws, double out[6]);
int sw_classify(int status, const double a[6], const double b[6], const double c[6]);
void sw_solve_jt(const double *p, sw_ws *ws, double *rhs);
double sw_friction_sign(double ld);
typedef int (*sw_sample_fn)(const double *, const double *, const double *, const double *,
                            sw_ws *, double *);
long sw_batch(sw_sample_fn sample, int out_size, const double *params, long n, const double *A,
              const double *B, const double *C, double *out, int *status);

/* regressor.c */
int sw_regressor_sample(const double *p, const double q[6], const double qd[6],
                        const double qdd[6], sw_ws *ws, double out[6 * STEWART_N_STANDARD]);

/* transmission.c */
int sw_derivative(const double *p, const double *pl, const double *y, const double F[6],
                  sw_ws *ws, double *dy);
int sw_leg_kinematics(const double *pl, const double *y, sw_ws *ws);

/* energy.c */
void sw_energy_terms(const double *p, const double *y, sw_ws *ws, double out[9]);

/* frames.c: the rotations of a frame change (mov, fix), and one pose f in it back to C's q */
void sw_frame_rotations(const double mov[6], const double fix[6], double Rt[9], double Rw[9]);
void sw_frame_to_platform(const double mov[6], const double fix[6], const double Rt[9],
                          const double Rw[9], const double f[6], double q[6]);

#endif
