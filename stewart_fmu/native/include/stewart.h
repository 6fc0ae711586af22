/*
 * stewart.h -- the numerical core of the Stewart-platform plant in plain C99 (libm only).
 *
 * Python reaches it through cffi (stewart_fmu/native/core.py); the FMU compiles it with the FMI
 * layer (stewart_fmu/native/fmi). Equation numbers refer to the paper (Kane's method for the
 * Stewart platform), as the Python docstrings do.
 *
 * Conventions (docs/conventions.md): SI units; pose q = (x, y, z, thx, thy, thz) with
 * R = Rz(thz) Ry(thy) Rx(thx); qd, qdd are the Euler-angle RATES and their derivatives;
 * sigma is the force at the rack, including m_d lddot when the model has a [drive] (Eq. 12).
 *
 * Reentrant: no global mutable state. The model is the const packed parameter vector
 * `params` (STEWART_N_PARAMS doubles in the layout of stewart_table.h, built by Model.params of
 * stewart_fmu/model.py); per-run state (y, energy terms, dopri5 step guess) belongs to the
 * caller (stewart_data is a ready-made holder). No function allocates memory; scratch space is
 * on the stack.
 *
 * Plant state y: 12 doubles (q, qd), or 24 (q, qd, s, sd) when the model has a compliant
 * transmission (params[STEWART_P_HAS_TRANSMISSION] != 0; see stewart_fmu/transmission.py).
 */
#ifndef STEWART_H
#define STEWART_H

#include "stewart_table.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- packed parameters: STEWART_PARAMS of stewart_table.h ------------------------------- */
/* STEWART_P_<NAME>: the offset of each entry; STEWART_N_PARAMS: the vector's length. */
#define STEWART_X_OFFSET(NAME, ...) STEWART_P_##NAME = STEWART_OFFSET(NAME),
enum { STEWART_PARAMS(STEWART_X_OFFSET) STEWART_N_PARAMS = (int)(sizeof(stewart_param_layout) / sizeof(double)) };

/* STEWART_S_<NAME>: the regressor's first column of each standard parameter (STEWART_STANDARD
   of stewart_table.h); STEWART_N_STANDARD: its number of columns. */
#define STEWART_X_STANDARD(NAME, ...) STEWART_S_##NAME = STEWART_STANDARD_OFFSET(NAME),
enum { STEWART_STANDARD(STEWART_X_STANDARD) STEWART_N_STANDARD = (int)(sizeof(stewart_standard_layout) / sizeof(double)) };

/* STEWART_E_<NAME>: the offset of each entry of the elastic vector (STEWART_ELASTIC of
   stewart_table.h); STEWART_N_ELASTIC: its length. */
#define STEWART_X_ELASTIC(NAME, ...) STEWART_E_##NAME = STEWART_ELASTIC_OFFSET(NAME),
enum { STEWART_ELASTIC(STEWART_X_ELASTIC) STEWART_N_ELASTIC = (int)(sizeof(stewart_elastic_layout) / sizeof(double)) };

/* The tables compiled into the core (src/table.c), for the Python side. */
typedef struct {
    const char *name;         /* NAME of STEWART_PARAMS: STEWART_P_<name> */
    int offset, count;
    const char *source;       /* the ID of the FMU scene variable it holds, or "COMPUTED" */
    const char *unit, *description;
} stewart_param_info;
typedef struct {
    const char *id;           /* ID of STEWART_FMU_*: VR_<id> of fmi/model.h */
    const char *name;         /* the variable's (group's) name in the model description */
    int vr, count, shape, bound;
    double min, max;          /* the bounds of a parameter's values (BOUND_ANY: -inf, inf) */
    int scene;                /* 1: a scene key of the plant tables (STEWART_FMU_SCENE) */
    int fmi3_only;            /* 1: an FMI 3.0 array only (STEWART_FMU_OUTPUT_ARRAYS) */
    const char *causality, *unit, *description;
} stewart_variable_info;
typedef struct {
    const char *id;           /* ID of STEWART_FMU_INPUTS */
    int vr, count;            /* the group's first value reference and its values */
    double min, max;          /* its declared range (STEWART_FMU_INPUT_RANGES) */
} stewart_input_range;
extern const stewart_input_range stewart_input_range_table[];
extern const int stewart_input_range_table_size;
typedef struct {
    const char *name;         /* NAME of STEWART_STANDARD: STEWART_S_<name> */
    int column, count;
    const char *key, *unit, *description;
} stewart_standard_info;
extern const stewart_standard_info stewart_standard_table[];
extern const int stewart_standard_table_size;
typedef struct {
    const char *name;         /* NAME of STEWART_ELASTIC (STEWART_E_<name>) or of STEWART_PAYLOAD_KEYS */
    const char *key;          /* the scene key ("" for a computed entry) */
    int in_params;            /* 1: packed in params (STEWART_P_PAYLOAD_<name>), 0: in elastic */
    int offset, count, shape, bound;
    double min, max;          /* the bounds of each value */
    const char *unit, *description;
} stewart_elastic_info;
extern const stewart_elastic_info stewart_elastic_table[];
extern const int stewart_elastic_table_size;
extern const stewart_param_info stewart_param_table[];
extern const int stewart_param_table_size;
extern const stewart_variable_info stewart_variable_table[];
extern const int stewart_variable_table_size;

#define STEWART_MAX_STATE 24          /* longest plant state y */
#define STEWART_N_ENERGY 9            /* energy terms: T, V_g, V_s, d_1..d_6 (energy.KINETIC ...) */
#define STEWART_ENERGY_KINETIC 0      /* energy.KINETIC */
#define STEWART_ENERGY_POTENTIAL 1    /* energy.POTENTIAL */
#define STEWART_ENERGY_SPRING 2       /* energy.SPRING */
#define STEWART_ENERGY_DRIVEN 3       /* energy.DRIVEN: 6 driven coordinates (l_i, or s_i) */
#define STEWART_N_PARTS 6             /* dynamics.PARTS */

/* Parts of inverse_dynamics_parts, rows of its (6 parts x 6 legs) output (dynamics.PARTS). */
enum { STEWART_PART_PLATFORM = 0, STEWART_PART_LOWER_LEGS = 1, STEWART_PART_UPPER_LEGS = 2,
       STEWART_PART_DRIVES = 3, STEWART_PART_GRAVITY = 4, STEWART_PART_FRICTION = 5 };

/* ---- status codes: stewart_fmu/status.py reads them ----------------------------------------- */
enum {
    STEWART_OK = 0,              /* status.OK */
    STEWART_NONFINITE = 1,       /* status.NONFINITE: a non-finite input */
    STEWART_STROKE = 2,          /* status.STROKE: a leg outside [leg_min, leg_max] */
    STEWART_SINGULAR = 3,        /* status.SINGULAR: J^T LU pivot < SINGULAR_PIVOT, or the
                                    twist mass matrix not positive definite */
    STEWART_GIMBAL = 4,          /* status.GIMBAL: |cos thy| < GIMBAL_LIMIT */
    STEWART_OVERFLOW = 5,        /* status.OVERFLOW: a non-finite output from finite inputs
                                    (batch/single calls report it as SINGULAR, as Python does) */
    STEWART_TOO_MANY_STEPS = 100,/* status.TOO_MANY_STEPS */
    STEWART_STEP_TOO_SMALL = 101,/* status.STEP_TOO_SMALL */
    STEWART_UNSTABLE = 102,      /* status.ENERGY_GAIN: the step gained energy beyond the rack
                                    forces' work (power balance of stewart_step_energy) */
    STEWART_STATE_NONFINITE = 103 /* status.STATE_NONFINITE: stewart_step's check found the
                                    integrated state not finite */
};

/* ---- limits ------------------------------------------------------------------------------ */
#define STEWART_SINGULAR_PIVOT 1e-10  /* smallest LU pivot of a regular J^T */
#define STEWART_GIMBAL_LIMIT 1e-9     /* rotations.GIMBAL_LIMIT */
#define STEWART_COND_LIMIT 1e10       /* kinematics.COND_LIMIT */
#define STEWART_ENERGY_TOL 1e-3       /* stability.ENERGY_TOL */

/* ---- integrator options (integrators.IntegratorOptions) --------------------------------- */
typedef enum { STEWART_RK4 = 0, STEWART_EULER = 1, STEWART_DOPRI5 = 2 } stewart_method;

typedef struct {
    stewart_method method; /* rk4 and euler: fixed internal step h / n, n = ceil(h/max_step) */
    double rtol, atol;     /* dopri5 error control (defaults 1e-8, 1e-10) */
    double max_step;       /* internal step cap (s), default 1e-3 */
    long max_steps;        /* bound of internal steps per advance, every method (10000) */
    double energy_tol;     /* power-balance tolerance of stewart_step (STEWART_ENERGY_TOL) */
} stewart_options;

/* The defaults of IntegratorOptions() and stability.ENERGY_TOL. */
stewart_options stewart_default_options(void);

/* The compiled methods' names, "rk4", "euler", "dopri5" by stewart_method (the one spelling
   the FMU's solver.method, integrators.COMPILED and the messages take); NULL outside
   [0, STEWART_N_METHODS). */
#define STEWART_N_METHODS 3
const char *stewart_method_name(int method);

/* ---- model ------------------------------------------------------------------------------- */
/* Length of the plant state y: 12, or 24 with a compliant transmission. */
int stewart_state_size(const double *params);

/* The leg side of a compliant transmission: params with
   P_HAS_DRIVE cleared when P_HAS_TRANSMISSION is set, else a plain copy. */
void stewart_leg_side_params(const double *params, double out[STEWART_N_PARAMS]);

/* ---- kinematics (stewart_fmu/kinematics.py, rotations.py) ------------------------------- */
/* R = Rz Ry Rx (row-major 3x3), omega = E thd and alpha = E thdd + Edot thd in N. qdd may be
   NULL (zero). */
void stewart_orientation(const double q[6], const double qd[6], const double *qdd,
                         double R[9], double omega[3], double alpha[3]);

/* Leg lengths l, rates ldot and the platform angular velocity omega (dynamics.leg_state).
   Returns STEWART_OK or STEWART_STROKE (outputs are filled either way). */
int stewart_leg_state(const double *params, const double q[6], const double qd[6],
                      double l[6], double ldot[6], double omega[3]);

/* The leg Jacobian J (row-major 6x6), ldot = J (v, omega), rows [u_i, (R p_i) x u_i];
   `scaled` != 0 divides the rotational columns by the characteristic length
   (the scaling of kinematics.condition_number). Returns OK or STROKE (J filled either way). */
int stewart_jacobian(const double *params, const double q[6], int scaled, double J[36]);

/* cond(J) of the scaled Jacobian (kinematics.condition_number): ratio of the extreme singular
   values (Householder bidiagonal, then dqds and Laguerre), inf when J is singular or
   non-finite. Returns OK, or NONFINITE for a non-finite q. The pose counts as singular when
   cond >= STEWART_COND_LIMIT. */
int stewart_condition_number(const double *params, const double q[6], double *cond);

/* ---- Kane's equations (src/kane.c; stewart_fmu/kane_terms.py is their term-by-term form) -- */
/* Generalized inertia (Eqs. 3-7) and gravity (Eq. 8) forces reduced to the platform twist, by
   body group: gen rows 0 platform inertia, 1 lower legs, 2 upper legs, 3 gravity (4x6,
   row-major); also the leg rows (l, ldot, lddot) as leg[6*3]. Returns OK or STROKE. */
int stewart_twist_forces(const double *params, const double q[6], const double qd[6],
                         const double qdd[6], double gen[24], double leg[18]);

/* Twist-space mass matrix M_nu, 6x6 row-major, at pose q.
   Returns OK or STROKE (filled either way). */
int stewart_mass_matrix(const double *params, const double q[6], double M[36]);

/* ---- dynamics (stewart_fmu/dynamics.py) --------------------------------------------------- */
/* Rack forces sigma (Eq. 12): sigma = J^-T (-K*_nu - K_g,nu) + mu + m_d lddot (Eqs. 9-12).
   Status: OK, NONFINITE, STROKE, SINGULAR. */
int stewart_inverse_dynamics(const double *params, const double q[6], const double qd[6],
                             const double qdd[6], double sigma[6]);

/* The contributions of dynamics.PARTS (platform, lower_legs, upper_legs, drives, gravity,
   friction), parts[part*6 + leg], summing to sigma; absent effects are zeros. */
int stewart_inverse_dynamics_parts(const double *params, const double q[6], const double qd[6],
                                   const double qdd[6], double parts[36]);

/* Pose accelerations qdd from rack forces sigma: (M_nu + J^T [m_d] J) nudot = J^T (sigma - mu -
   [m_d] lddot_0) + K*_0 + K_g, then Euler rates ([m_d] = diag(m_d,i), mu per leg). Status: OK, NONFINITE, STROKE, SINGULAR, GIMBAL. */
int stewart_forward_dynamics(const double *params, const double q[6], const double qd[6],
                             const double sigma[6], double qdd[6]);

/* Batch variants over n samples (row-major (n, 6) inputs, outputs (n, 6) or (n, 6, 6) for
   parts). Return the index of the first bad sample (then *status is its code, as the single
   calls classify it; rows after it are not computed), or -1 with *status = OK. */
long stewart_inverse_dynamics_batch(const double *params, long n, const double *Q,
                                    const double *QD, const double *QDD, double *sigma,
                                    int *status);
long stewart_inverse_dynamics_parts_batch(const double *params, long n, const double *Q,
                                          const double *QD, const double *QDD, double *parts,
                                          int *status);
long stewart_forward_dynamics_batch(const double *params, long n, const double *Q,
                                    const double *QD, const double *SIGMA, double *QDD,
                                    int *status);

/* The regressor of the inverse dynamics (src/regressor.c): Y (6 x STEWART_N_STANDARD, row
   major, row i leg i) with sigma = Y pi for pi the standard parameters of STEWART_STANDARD. It
   holds every column whatever effects params declares (a column of an effect the scene lacks
   multiplies a zero of pi). Status as stewart_inverse_dynamics. */
int stewart_regressor(const double *params, const double q[6], const double qd[6],
                      const double qdd[6], double Y[]);
long stewart_regressor_batch(const double *params, long n, const double *Q, const double *QD,
                             const double *QDD, double *Y, int *status);

/* ---- plant (stewart_fmu/transmission.py, integrators.py) --------------------------------- */
/* dy = y' at y with the rack forces held (integrators.derivative); y of stewart_state_size.
   Status of the forward kernel: OK, STROKE, SINGULAR, GIMBAL, OVERFLOW (not classified). */
int stewart_derivative(const double *params, const double *y, const double rack[6], double *dy);

/* The transmission forces f_i = k (s_i - l_i) + c (sd_i - ld_i) on the legs (24-state y). */
int stewart_spring_forces(const double *params, const double *y, double f[6]);

/* How the rack forces split at the plant state y (dynamics.PARTS rows, parts[part*6 + leg]):
   without a transmission the parts at forward_dynamics' qdd, summing to the rack forces; with
   one, the leg side's parts (the model without its drive: stewart_leg_side_params) at the legs'
   accelerations from y', summing to the spring forces, and drives = m_d sdd. The one definition
   of the leg side's force breakdown (Plant's outputs and the FMU's force.<part>). Status: that of
   the forward kernel or of the inverse parts; parts are zero where not computed. */
int stewart_plant_parts(const double *params, const double *y, const double rack[6], double parts[36]);

/* The plant state at pose q and rates qd (transmission.initial_state): (q, qd), and with a
   transmission s = l + rack / k, sd = ldot (rack may be NULL: zero). Returns the state size. */
int stewart_initial_state(const double *params, const double q[6], const double qd[6],
                          const double *rack, double *y);

/* ---- energy (stewart_fmu/energy.py, stability.py) ---------------------------------------------- */
/* out = (T, V_g, V_s, d_1..d_6) at y (energy.energy_terms). */
void stewart_energy_terms(const double *params, const double *y, double out[STEWART_N_ENERGY]);

/* The power balance of a step of length h (stewart_step's check): returns 0 if y1 is
   non-finite, else 1 with e1 = energy terms of y1, *excess = dE - F.(d1 - d0) and
   *allowed = tol * (energy exchanged) + sum_i coulomb_i (|d1_i - d0_i| + h |ldot_i(y1)|) (the
   h |ldot_i| terms only when a leg has Coulomb friction). The step is unstable when !(excess <= allowed). */
int stewart_step_energy(const double *params, const double *y1, const double e0[9],
                        double e1[9], const double rack[6], double tol, double h,
                        double *excess, double *allowed);

/* ---- integration (stewart_fmu/integrators.py) --------------------------------------------- */
/* y1 = y0 advanced over h with the rack forces held (zero-order hold); y0 is not modified.
   rk4 / euler: n = max(1, ceil(h / max_step - 1e-9)) fixed sub-steps (TOO_MANY_STEPS if
   n > max_steps); dopri5: error-controlled steps starting from *step_guess, which returns the
   next step to try (unused by fixed-step methods, may be NULL then). *evaluations (may be
   NULL) is set to the right-hand-side evaluations of this call. Status: OK, STROKE, SINGULAR,
   GIMBAL, OVERFLOW, TOO_MANY_STEPS, STEP_TOO_SMALL (never NONFINITE); -1 for an unknown
   method. */
int stewart_advance(const double *params, const stewart_options *o, const double *y0,
                    double *y1, const double rack[6], double h, double *step_guess,
                    long *evaluations);

/* THE plant step (plant.Plant.do_step without the call-sequence checks): stewart_advance, then the
   finiteness and power-balance check of stewart_step_energy with o->energy_tol. e0: energy
   terms of y0 (stewart_energy_terms, or the e1 of the previous accepted step); e1 receives
   those of y1. excess / allowed may be NULL. Status: that of stewart_advance, else
   STATE_NONFINITE (y1 not finite) or UNSTABLE (excess > allowed), else OK. On any status but OK the caller
   keeps y0 (and e0) as the state. */
int stewart_step(const double *params, const stewart_options *o, const double *y0, double *y1,
                 const double rack[6], double h, double *step_guess, long *evaluations,
                 const double e0[STEWART_N_ENERGY], double e1[STEWART_N_ENERGY],
                 double *excess, double *allowed);

/* ---- a ready-made per-run state (mjData style; the caller owns it) ----------------------- */
typedef struct {
    double t;                          /* time (s) */
    int n;                             /* state size, 12 or 24 */
    double y[STEWART_MAX_STATE];       /* plant state */
    double energy[STEWART_N_ENERGY];   /* energy terms of y */
    double step_guess;                 /* dopri5's next internal step (s) */
    long evaluations;                  /* right-hand-side evaluations so far */
    double excess, allowed;            /* power balance of the last step */
} stewart_data;

/* d at pose q, rates qd (stewart_initial_state with rack), time t, step_guess = o->max_step. */
void stewart_data_init(const double *params, const stewart_options *o, const double q[6],
                       const double qd[6], const double *rack, double t, stewart_data *d);

/* One stewart_step of d over h; on OK d advances (y, energy, t). step_guess, evaluations,
   excess and allowed are updated whatever the status (as Plant does); on any status but OK
   y, energy and t are kept (the step is rejected, the state is the step's start). */
int stewart_data_step(const double *params, const stewart_options *o, stewart_data *d,
                      const double rack[6], double h);

/* n stewart_data_steps of h with the rack forces held (a constant-input run, and a timing loop
   without per-step call overhead); stops at the first status but OK and returns it, with
   *done (may be NULL) the steps completed. */
int stewart_data_run(const double *params, const stewart_options *o, stewart_data *d,
                     const double rack[6], double h, long n, long *done);

/* ==== stiffness and modes (src/stiffness.c; stewart_fmu/stiffness.py) ===================== */
/* elastic: the STEWART_N_ELASTIC doubles of STEWART_ELASTIC (Model.elastic). Coordinates: the
   platform twist chi = (dx, dtheta) about C's origin in N (a point p of C moves by
   dx + dtheta x R p), wrenches (force, moment about C's origin) in N. The legs are springs about
   the lengths that hold the pose in static equilibrium under gravity (platform, leg parts,
   payload: the payload is the model's, params' PAYLOAD_*); with a [transmission] the motor side is held and its spring is in series with the
   leg's, and the drive's inertia stays out of the mass matrix. */

/* The static leg forces sigma (N): those that hold the pose against gravity on the platform,
   the leg parts and the payload (stewart_inverse_dynamics at rest, with the payload's weight);
   Status: OK, NONFINITE, STROKE, SINGULAR. */
int stewart_static_forces(const double *params, const double q[6], double sigma[6]);

/* The static leg forces sigma (as stewart_static_forces) and the 6x6 Cartesian stiffness K = -dW/dchi (row-major, symmetric): the legs'
   J^T k J, the joints' bending and torsion, and the geometric term of the loads (Griffis and
   Duffy): the leg forces turning with the legs, the leg parts' and the payload's weight turning
   with the platform. Status: OK, NONFINITE, STROKE, SINGULAR (J), or SINGULAR when elastic has
   no [stiffness]. */
int stewart_stiffness(const double *params, const double *elastic, const double q[6],
                      double K[36], double sigma[6]);

/* The compliance at a point of the platform (pivot, in C): Cp (6x6, row-major) maps a force
   and a moment applied there (N) to the point's displacement and the platform's rotation,
   Cp = T^T K^-1 T with T = [[I, 0], [[R pivot]x, I]]. Status of stewart_stiffness, or SINGULAR
   when K is not positive definite (the loads buckle the pose). */
int stewart_compliance(const double *params, const double *elastic, const double q[6],
                       const double pivot[3], double Cp[36]);

/* The mass matrix of the modes (twist, 6x6 row-major): the model's at rest (platform, payload,
   leg parts, drives; the leg side's with a [transmission]). Status as stewart_mass_matrix. */
int stewart_modes_mass(const double *params, const double q[6], double M[36]);

/* The small oscillations about the static equilibrium at q: K v = w2 M v. w2 (rad^2/s^2,
   ascending; a value <= 0 is an unstable direction), shapes (row-major, row j the mode j's
   twist, mass-normalised v^T M v = 1, its largest entry positive). Status of
   stewart_stiffness, or SINGULAR when M is not positive definite. */
int stewart_modes(const double *params, const double *elastic, const double q[6], double w2[6],
                  double shapes[36]);

/* Over n poses (row-major (n, 6)): w2 (n, 6) and the compliance at the pivot Cp (n, 36) (may be
   NULL). Returns the index of the first failed pose (*status its code; the rows after it are not
   computed), or -1 with *status = OK. */
long stewart_modes_batch(const double *params, const double *elastic, long n, const double *Q,
                         const double pivot[3], double *W2, double *Cp, int *status);

/* ==== words: status names, what they mean, the refusal of a step (status.c) ============== */
#include <stddef.h>

/* Status codes of the component (component.c) and of its serialized state, after the core's. */
enum {
    STEWART_BAD_CALL = 110,      /* a call the component's phase does not allow */
    STEWART_BAD_STEP = 111,      /* a step size that is not finite and > 0 */
    STEWART_BAD_TIME = 112,      /* a current time that is not the component's */
    STEWART_BAD_STATE = 113,     /* serialized state: wrong size, magic or version */
    STEWART_STATE_FOREIGN = 114, /* serialized state of another model (its key differs) */
    STEWART_STATE_CORRUPT = 115, /* serialized state: checksum mismatch */
    STEWART_STATE_INVALID = 116  /* a state whose values are out of range or not finite */
};

/* The status's name ("STROKE") and what it means to a user ("a leg left its stroke"); NULL
   for a code that is not a status. */
const char *stewart_status_name(int status);
const char *stewart_status_why(int status);

/* x as Python's repr writes a float (shortest round trip), into out. */
void stewart_format_double(char out[32], double x);

/* THE message of a refused step, for every caller (the FMU's log, Plant's StepRejected and
   IntegrationError): "doStep from t = T s by H s discarded (METHOD): WHY; state kept at the
   start of the step: q = (...), qd = (...), leg lengths = (...) m (stroke [lo, hi] m), rack
   force = (...) N", with "(by X J, allowed Y J)" after WHY for STEWART_UNSTABLE. y: the state
   at the start of the step, rack: the held rack forces. Writes at most size bytes (always
   terminated) and returns the length written. */
size_t stewart_refusal(char *buf, size_t size, const double *params, const char *method, double t,
                       double h, int status, const double *y, const double rack[6], double excess,
                       double allowed);

/* ==== the rules between a scene's keys (rules.c) ======================================== */
/* The one check of the rules that relate keys (the per-key ones, finite values and the bounds
   of stewart_table.h, come first, in the scene reader and the FMU): scene.py raises the
   SceneError of a broken one, the FMU's exitInitializationMode logs it. */
enum {  /* numbered from 0 in this order (they are not status codes) */
    STEWART_RULE_OK,
    STEWART_RULE_JOINTS,            /* two base (platform) joints at one point */
    STEWART_RULE_STROKE,            /* leg_min >= leg_max */
    STEWART_RULE_INERTIA_POSITIVE,  /* a principal moment of the platform <= 0 */
    STEWART_RULE_INERTIA_TRIANGLE,  /* the platform's moments break the triangle inequality */
    STEWART_RULE_LEG_INERTIA,       /* a leg part's axial moment above twice its transverse */
    STEWART_RULE_POSE_STROKE,       /* the pose puts a leg outside [leg_min, leg_max] */
    STEWART_RULE_POSE_SINGULAR,     /* the pose's cond(J) >= STEWART_COND_LIMIT */
    STEWART_RULE_DERIVED            /* a STEWART_DERIVED quantity non-finite or beyond its bounds */
};

/* The first broken rule: vr the first value reference of the FMU variable group at fault (in
   stewart_variable_table; a scene group's name is the scene key), element the offset of the
   value at fault in that group (-1: the key as a whole), reason what is wrong, written to
   follow the key's name ("must exceed leg_min (0.19 <= 0.19)"). */
typedef struct {
    int rule;           /* STEWART_RULE_* */
    int vr, element;
    char reason[512];
} stewart_rule_break;

/* The drive's derived quantities (STEWART_DERIVED of stewart_table.h: the rack ratio zeta / r,
   then each leg's m_d = zeta^2 I_i / r^2 of the keys drive.gear_ratio, drive.rotor_inertia (six
   values, one per leg) and drive.pinion_radius), computed and checked finite and within their
   bounds: STEWART_RULE_DERIVED naming drive.gear_ratio, or STEWART_RULE_OK. */
int stewart_check_drive(double gear_ratio, double pinion_radius, const double rotor_inertia[6],
                        stewart_rule_break *out);
/* The rules between the packed parameters (STEWART_RULE_JOINTS .. LEG_INERTIA, in that order,
   then the moving mass of STEWART_DERIVED): returns the first broken one (out filled) or
   STEWART_RULE_OK. */
int stewart_check_params(const double *params, stewart_rule_break *out);
/* A pose the plant may start from: within the stroke, then cond(J) < STEWART_COND_LIMIT;
   vr names the pose's variable (the home, the FMU's q0). */
int stewart_check_pose(const double *params, const double q[6], int vr, stewart_rule_break *out);
/* stewart_check_params, then stewart_check_pose of the scene's home pose (geometry.home). */
int stewart_check_rules(const double *params, const double home[6], stewart_rule_break *out);

/* ==== the component: the FMI life cycle, its state as plain data, one serialized form ====== */
/* component.c: what the exported FMU (fmi/model.c) and stewart_fmu.plant.Plant both wrap. The
   phases and the call-sequence rules are those of the FMI 2.0 / 3.0 co-simulation state
   machines (as the Reference FMUs' MASK_* table states them); a call in a phase its rule does not
   allow returns STEWART_BAD_CALL and changes nothing. */
typedef enum { STEWART_PH_INSTANTIATED = 0, STEWART_PH_INITIALIZATION = 1, STEWART_PH_STEPPING = 2,
               STEWART_PH_TERMINATED = 3, STEWART_PH_FAILED = 4 } stewart_phase;
#define STEWART_N_PHASES 5

/* The calls the rules name, and the phases each is allowed in. */
typedef enum {
    STEWART_CALL_SETUP = 0,         /* setupExperiment: instantiated */
    STEWART_CALL_ENTER_INIT = 1,    /* enterInitializationMode: instantiated */
    STEWART_CALL_EXIT_INIT = 2,     /* exitInitializationMode: initialization */
    STEWART_CALL_SET_PARAMETER = 3, /* parameters, the initial state, the method: instantiated,
                                       initialization */
    STEWART_CALL_SET_INPUT = 4,     /* rack forces, torques: instantiated, initialization, stepping */
    STEWART_CALL_GET = 5,           /* getters: every phase but instantiated */
    STEWART_CALL_DO_STEP = 6,       /* stepping */
    STEWART_CALL_STATUS = 7,        /* getStatus: stepping, terminated */
    STEWART_CALL_TERMINATE = 8,     /* stepping */
    STEWART_CALL_ANY = 9            /* reset, logging, states: every phase */
} stewart_call;
#define STEWART_N_CALLS 10

/* Everything a rollback restores, as plain data (no pointers, no padding): copied as is into
   saved states and serialized byte for byte. */
typedef struct {
    int phase;                          /* stewart_phase */
    int n;                              /* state size: 12, or 24 with a transmission */
    int energy_valid;                   /* energy holds the terms of y */
    int reserved;                       /* zero (keeps the doubles aligned without padding) */
    long long evaluations;              /* right-hand-side evaluations (kept by a load) */
    double start_time, time;            /* s */
    double step_guess;                  /* dopri5's next internal step (s) */
    double initial[12];                 /* the initial q, qd of this experiment */
    double sigma[6], tau[6];            /* held inputs: rack forces (N), motor torques (N m) */
    double rack[6];                     /* sigma + zeta / r tau (stewart_component_hold) */
    double y[STEWART_MAX_STATE];        /* plant state (n values) */
    double energy[STEWART_N_ENERGY];    /* energy terms of y, when energy_valid */
    double excess, allowed;             /* the last step's power balance (J) */
} stewart_component;

/* The phase's name ("stepping"); "invalid" for a number that is not a phase. */
const char *stewart_phase_name(int phase);

/* 1 if the rules allow call in phase, else 0. */
int stewart_allowed(int call, int phase);

/* The message of a refused call: "NAME is not allowed in phase 'P' (allowed in: A, B)". */
size_t stewart_call_refusal(char *buf, size_t size, const char *name, int call, int phase);

/* Back to right after instantiation: phase instantiated, time 0, tau 0, the given initial
   q, qd (12) and sigma, step_guess = max_step; y the initial state at params (with the rack
   force's preload), or (q, qd) when params is NULL. */
void stewart_component_reset(stewart_component *s, const double *params, const double initial[12],
                             const double sigma[6], double max_step);

/* The life cycle. Each checks its rule first (STEWART_BAD_CALL) and then its arguments
   (STEWART_NONFINITE for a non-finite value); on any status but OK nothing changes. */
int stewart_component_setup(stewart_component *s, double start_time);
int stewart_component_enter_init(stewart_component *s);
/* The initial q and / or qd (either may be NULL: kept); y becomes their initial state. */
int stewart_component_set_initial(stewart_component *s, const double *params, const double *q,
                                  const double *qd);
/* Stepping from the initial state at the start time. The caller has checked the initial pose
   (stroke, singularity) and calls stewart_component_fail instead when it is not valid. */
int stewart_component_exit_init(stewart_component *s, const double *params);
void stewart_component_fail(stewart_component *s);  /* initialization failed: phase failed */
int stewart_component_terminate(stewart_component *s);

/* The held inputs (sigma or tau may be NULL: kept); rack = sigma + gain tau, gain = zeta / r
   (0 without a drive). stewart_component_hold recomputes rack alone (no rule, no check). */
int stewart_component_set_inputs(stewart_component *s, const double *sigma, const double *tau,
                                 double gain);
void stewart_component_hold(stewart_component *s, double gain);

/* THE step of the component: the rule, h finite and > 0, t the component's time (relative
   1e-9), then stewart_step with o from y; on OK y, energy and time = t + h advance, on any
   other status the state stays at the start of the step (step_guess, evaluations, excess and
   allowed follow the attempt). Status: BAD_CALL, BAD_STEP, BAD_TIME, or stewart_step's. */
int stewart_component_do_step(stewart_component *s, const double *params, const stewart_options *o,
                              double t, double h);
/* The same step in two halves, for a method the core does not have (scipy's, integrated by
   the caller from y with the held rack forces): begin checks as do_step does; end runs the
   step's check (finite, power balance with tol) on y1 and accepts it as do_step does. */
int stewart_component_begin_step(stewart_component *s, const double *params, double t, double h);
int stewart_component_end_step(stewart_component *s, const double *params, const double *y1,
                               double t, double h, double tol);

/* stewart_refusal for the component's state at the start of the step. */
size_t stewart_component_refusal(char *buf, size_t size, const stewart_component *s,
                                 const double *params, const char *method, double t, double h,
                                 int status);

/* The sanity of a state: the phase a phase, n 12 or 24 (and, with params, the size of a
   running plant's state), the times finite and time >= start_time, the next internal step
   finite and > 0, inputs, initial values and y finite. OK or
   STEWART_STATE_INVALID. */
int stewart_component_check(const stewart_component *s, const double *params);
/* s = from after stewart_component_check (s's evaluations are kept; energy recomputed). */
int stewart_component_load(stewart_component *s, const stewart_component *from, const double *params);

/* ---- serialized state: header (magic "STWSTATE", version, payload size, key, FNV-1a
   checksum of header and payload), then the component, then `extra` (the caller's own plain
   data: the FMU's parameter values). key names the model the state belongs to. */
#define STEWART_STATE_VERSION 3
unsigned long long stewart_hash(const void *data, size_t n);  /* 64-bit FNV-1a */
size_t stewart_serialized_size(size_t extra_size);
int stewart_serialize(const stewart_component *s, const void *extra, size_t extra_size,
                      unsigned long long key, void *out, size_t size);
/* OK, or BAD_STATE (size, magic, version), STATE_FOREIGN (key), STATE_CORRUPT (checksum),
   STATE_INVALID (stewart_component_check without params); s and extra written on OK only. */
int stewart_deserialize(const void *in, size_t size, unsigned long long key, stewart_component *s,
                        void *extra, size_t extra_size);


/* ==== reach: every limit's margin at a pose (reach.c), frames (frames.c) ================= */
/* STEWART_R_<NAME>: offsets of the packed reach vector (STEWART_REACH_PARAMS of
   stewart_table.h), STEWART_N_REACH its length; STEWART_LIMIT_<ID>: the limits' indices in
   report order (STEWART_LIMITS), STEWART_N_LIMITS their number. */
#define STEWART_X_REACH_OFFSET(NAME, ...) STEWART_R_##NAME = STEWART_REACH_OFFSET(NAME),
enum { STEWART_REACH_PARAMS(STEWART_X_REACH_OFFSET) STEWART_N_REACH = (int)(sizeof(stewart_reach_layout) / sizeof(double)) };
#define STEWART_X_LIMIT_INDEX(ID, ...) STEWART_LIMIT_##ID,
enum { STEWART_LIMITS(STEWART_X_LIMIT_INDEX) STEWART_N_LIMITS };

typedef struct {
    const char *name;         /* NAME of STEWART_REACH_PARAMS: STEWART_R_<name> */
    int offset, count;
    const char *unit, *description;
} stewart_reach_param_info;
typedef struct {
    const char *id, *name;    /* ID and dotted scene key of STEWART_REACH_SCENE */
    int count, bound;
    double min, max;
    const char *unit, *description;
} stewart_reach_key_info;
typedef struct {
    const char *id, *name;    /* ID and NAME of STEWART_LIMITS, index = its row */
    int kind;                 /* STEWART_LIMIT_KIND_* */
    const char *unit, *description;
} stewart_limit_info;
extern const stewart_reach_param_info stewart_reach_param_table[];
extern const int stewart_reach_param_table_size;
extern const stewart_reach_key_info stewart_reach_key_table[];
extern const int stewart_reach_key_table_size;
extern const stewart_limit_info stewart_limit_table[];
extern const int stewart_limit_table_size;

/* Which limits a call computes (present[k] = 1): the stroke's ends the model bounds, the cones
   with [joints], leg clearance with [clearance], obstacles when it has any, cond(J) when its
   limit is finite, speed with rates (has_qd) and acceleration and force with accelerations
   (has_qdd) when their bounds are finite. */
void stewart_reach_present(const double *params, const double *reach, int has_qd, int has_qdd,
                           int *present);

/* Every limit's margin at pose q (rates qd and accelerations qdd may be NULL): margin[k] the
   least over the limit's legs, pairs or obstacle-leg pairs (positive inside; +inf for a limit
   not present), where[k] the element that gives it (leg 0..5; pair 0..14 in the order (1,2),
   (1,3) .. (5,6); obstacle o and leg i as 6 o + i; 0 for cond(J)). Returns the binding limit:
   the first in report order whose margin is negative, or -1 when the pose is inside every
   limit; STEWART_N_LIMITS when q (or qd, qdd) is not finite (margins then NaN). */
int stewart_reach_margins(const double *params, const double *reach, const double q[6],
                          const double *qd, const double *qdd, double margin[STEWART_N_LIMITS],
                          int *where);

/* stewart_reach_margins over n poses (row-major (n, 6); QD, QDD may be NULL): margins and
   where (n, STEWART_N_LIMITS), binding (n). Returns the number of poses inside every limit, or
   -(1 + k) for the first pose k that is not finite (rows after it are not computed). */
long stewart_reach_batch(const double *params, const double *reach, long n, const double *Q,
                         const double *QD, const double *QDD, double *margins, int *where,
                         int *binding);

/* The binding limit alone of n poses (row-major (n, 6); -1 inside), as stewart_reach_batch
   finds it, without the margins' values: a margin surely positive is not computed exactly
   (cond(J) below a bound of it, an obstacle beyond its bounding sphere). Returns the number
   inside every limit, or -(1 + k) for the first pose k that is not finite. */
long stewart_reach_binding(const double *params, const double *reach, long n, const double *Q,
                           int *binding);

/* The largest step s in [0, smax] with the pose q0 + t dir inside every geometric limit (and
   cond(J)) for all t in [0, s]; q0 and dir in a frame (frame: 12 doubles, mov then fix of
   stewart_frame_to_platform; NULL: the platform's own pose). Conservative advancement (reach.c,
   travel_probe): each limit's margin over a bound of how fast it can fall along the line is a
   step it surely holds for (steps of at most hmax); the next pose is at the least such end, or
   tol / 2 on where that is nearer, until a pose is outside; a bracket left wider than tol is
   bisected. Guarantee (up to rounding of the margins and singular values): [0, s] is inside
   every limit but for gaps each shorter than tol / 2 at whose start a limit's margin was below
   its rate bound x tol / 2 (a limit grazed, no deeper than that within the gap), and a pose
   within tol past s is outside *limit: the first violation along the line is found to tol,
   however narrow the region outside. *limit, *where: what ends it (-1: nothing within smax).
   Returns 0; 1 when q0 itself is outside a limit (s = 0, *limit the binding one); 2 when the
   line runs within tol / 2 of a limit for 10^6 poses (s the last pose certified, *limit that
   limit, *where 0); -1 when q0, dir or frame is not finite, tol, hmax or smax not > 0, or
   smax / hmax above 156250. */
int stewart_reach_travel(const double *params, const double *reach, const double *frame,
                         const double q0[6], const double dir[6], double hmax, double smax,
                         double tol, double *s, int *limit, int *where);

/* Each leg's direction at pose q: u_i in N (base[3i..]) and R^T u_i in C (platform[3i..]):
   the joints' axes a scene leaves out are these at its home pose. */
void stewart_leg_axes(const double *params, const double q[6], double base[18], double platform[18]);

/* Frames (frames.c). A frame change is a moving frame M given in C (mov: a pose, position in
   C and angles) and a fixed frame W given in N (fix); the pose of M in W is
   T_W^-1 T_C(q) T_M, written f. stewart_frame_from_platform: f from q; stewart_frame_to_platform:
   q from f. A frame whose angles are all zero rotates nothing (its angles pass through
   unchanged). Angles out: thy in [-pi/2, pi/2], thx, thz in (-pi, pi] (a pose whose angles
   lie there comes back to itself). n poses, row-major (n, 6). */
void stewart_frame_from_platform(const double mov[6], const double fix[6], long n,
                                 const double *Q, double *F);
void stewart_frame_to_platform(const double mov[6], const double fix[6], long n,
                               const double *F, double *Q);

/* Motions in frames: the poses of stewart_frame_from/to_platform with their rates and
   accelerations, in the contract's columns (x, y, z and Euler angles; rates and accelerations
   of those, the angles' being Euler-angle rates). The frame's point moves with
   v + w x r and a + alpha x r + w x (w x r) (r: the point from C's origin, in N); its angular
   velocity and acceleration are C's, seen from W; its Euler rates solve E(th) thd = w and
   E(th) thdd = alpha - Edot thd at its angles. A frame whose angles are all zero passes the
   angles' rates and accelerations through unchanged. n samples, each array row-major (n, 6);
   Qdd (Fdd) NULL: accelerations zero in, and none written out (Fdd, Qdd NULL). Returns n, or
   -(1 + k) for the first sample k whose angles out are at gimbal lock
   (|cos thy| < STEWART_GIMBAL_LIMIT: their Euler rates are not defined; that sample's and
   later outputs unspecified; never with a frame that passes the angles through). */
long stewart_frame_motion_from_platform(const double mov[6], const double fix[6], long n,
                                        const double *Q, const double *Qd, const double *Qdd,
                                        double *F, double *Fd, double *Fdd);
long stewart_frame_motion_to_platform(const double mov[6], const double fix[6], long n,
                                      const double *F, const double *Fd, const double *Fdd,
                                      double *Q, double *Qd, double *Qdd);

#ifdef __cplusplus
}
#endif
#endif /* STEWART_H */
