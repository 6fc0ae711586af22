/* component.c -- the plant as an FMI co-simulation component: the life cycle and its one
 * table of call-sequence rules, the state as plain data (get / set / check), its one
 * serialized form. fmi/model.c (the exported FMU) and stewart_fmu/plant.py (Plant) wrap it. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"

#define BIT(p) (1u << (p))
#define TIME_EPS 1e-9  /* relative tolerance of the current time against the component's */

static const char *const PHASES[STEWART_N_PHASES] = {"instantiated", "initialization", "stepping",
                                                    "terminated", "failed"};

/* The call-sequence rules: the phases each call is allowed in (FMI 2.0.4 section 4.2.4, FMI 3.0
   section 4.2.1, as the Reference FMUs' MASK_* table). */
static const unsigned RULES[STEWART_N_CALLS] = {
    BIT(STEWART_PH_INSTANTIATED),                                                 /* SETUP */
    BIT(STEWART_PH_INSTANTIATED),                                                 /* ENTER_INIT */
    BIT(STEWART_PH_INITIALIZATION),                                               /* EXIT_INIT */
    BIT(STEWART_PH_INSTANTIATED) | BIT(STEWART_PH_INITIALIZATION),                /* SET_PARAMETER */
    BIT(STEWART_PH_INSTANTIATED) | BIT(STEWART_PH_INITIALIZATION) | BIT(STEWART_PH_STEPPING),
                                                                                  /* SET_INPUT */
    BIT(STEWART_PH_INITIALIZATION) | BIT(STEWART_PH_STEPPING) | BIT(STEWART_PH_TERMINATED) |
        BIT(STEWART_PH_FAILED),                                                   /* GET */
    BIT(STEWART_PH_STEPPING),                                                     /* DO_STEP */
    BIT(STEWART_PH_STEPPING) | BIT(STEWART_PH_TERMINATED),                        /* STATUS */
    BIT(STEWART_PH_STEPPING),                                                     /* TERMINATE */
    BIT(STEWART_N_PHASES) - 1u,                                                   /* ANY */
};

const char *stewart_phase_name(int phase) {
    return phase >= 0 && phase < STEWART_N_PHASES ? PHASES[phase] : "invalid";
}

int stewart_allowed(int call, int phase) {
    return call >= 0 && call < STEWART_N_CALLS && phase >= 0 && phase < STEWART_N_PHASES &&
           (RULES[call] & BIT(phase)) != 0;
}

size_t stewart_call_refusal(char *buf, size_t size, const char *name, int call, int phase) {
    size_t pos;
    int p, w, first = 1;
    if (!buf || size == 0) return 0;
    w = snprintf(buf, size, "%s is not allowed in phase '%s' (allowed in:", name, stewart_phase_name(phase));
    pos = w > 0 ? (size_t)w : 0;
    for (p = 0; p < STEWART_N_PHASES && pos < size; p++) {
        if (!stewart_allowed(call, p)) continue;
        w = snprintf(buf + pos, size - pos, "%s %s", first ? "" : ",", PHASES[p]);
        if (w > 0) pos += (size_t)w;
        first = 0;
    }
    if (pos < size) {
        w = snprintf(buf + pos, size - pos, ")");
        if (w > 0) pos += (size_t)w;
    }
    return pos < size ? pos : size - 1;
}

#define REQUIRE(s, call)                                          \
    do {                                                          \
        if (!stewart_allowed((call), (s)->phase)) return STEWART_BAD_CALL; \
    } while (0)

static int finite_all(const double *v, int n) {
    int i;
    for (i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* ---- life cycle ------------------------------------------------------------------------ */

static void initial_state(stewart_component *s, const double *params) {
    int i;
    for (i = 0; i < STEWART_MAX_STATE; i++) s->y[i] = 0.0;
    if (params) {
        s->n = stewart_initial_state(params, s->initial, s->initial + 6, s->rack, s->y);
    } else {
        s->n = 12;
        for (i = 0; i < 12; i++) s->y[i] = s->initial[i];
    }
    s->energy_valid = 0;
}

void stewart_component_reset(stewart_component *s, const double *params, const double initial[12],
                             const double sigma[6], double max_step) {
    double q[12], f[6];
    int i;
    memcpy(q, initial, sizeof q);  /* the arguments may be s's own fields */
    memcpy(f, sigma, sizeof f);
    memset(s, 0, sizeof *s);
    s->phase = STEWART_PH_INSTANTIATED;
    memcpy(s->initial, q, sizeof q);
    for (i = 0; i < 6; i++) {
        s->sigma[i] = f[i];
        s->rack[i] = f[i] + 0.0;  /* sigma + gain tau with tau = 0 */
    }
    s->step_guess = max_step;
    initial_state(s, params);
}

int stewart_component_setup(stewart_component *s, double start_time) {
    REQUIRE(s, STEWART_CALL_SETUP);
    if (!isfinite(start_time)) return STEWART_NONFINITE;
    s->start_time = s->time = start_time;
    return STEWART_OK;
}

int stewart_component_enter_init(stewart_component *s) {
    REQUIRE(s, STEWART_CALL_ENTER_INIT);
    s->phase = STEWART_PH_INITIALIZATION;
    return STEWART_OK;
}

int stewart_component_set_initial(stewart_component *s, const double *params, const double *q,
                                  const double *qd) {
    REQUIRE(s, STEWART_CALL_SET_PARAMETER);
    if ((q && !finite_all(q, 6)) || (qd && !finite_all(qd, 6))) return STEWART_NONFINITE;
    if (q) memmove(s->initial, q, 6 * sizeof(double));
    if (qd) memmove(s->initial + 6, qd, 6 * sizeof(double));
    initial_state(s, params);
    return STEWART_OK;
}

int stewart_component_exit_init(stewart_component *s, const double *params) {
    REQUIRE(s, STEWART_CALL_EXIT_INIT);
    initial_state(s, params);
    s->time = s->start_time;
    s->phase = STEWART_PH_STEPPING;
    return STEWART_OK;
}

void stewart_component_fail(stewart_component *s) { s->phase = STEWART_PH_FAILED; }

int stewart_component_terminate(stewart_component *s) {
    REQUIRE(s, STEWART_CALL_TERMINATE);
    s->phase = STEWART_PH_TERMINATED;
    return STEWART_OK;
}

void stewart_component_hold(stewart_component *s, double gain) {
    int i;
    for (i = 0; i < 6; i++) s->rack[i] = s->sigma[i] + gain * s->tau[i];
}

int stewart_component_set_inputs(stewart_component *s, const double *sigma, const double *tau,
                                 double gain) {
    REQUIRE(s, STEWART_CALL_SET_INPUT);
    if ((sigma && !finite_all(sigma, 6)) || (tau && !finite_all(tau, 6))) return STEWART_NONFINITE;
    if (sigma) memmove(s->sigma, sigma, sizeof s->sigma);
    if (tau) memmove(s->tau, tau, sizeof s->tau);
    stewart_component_hold(s, gain);
    return STEWART_OK;
}

/* ---- stepping ------------------------------------------------------------------------- */

int stewart_component_begin_step(stewart_component *s, const double *params, double t, double h) {
    REQUIRE(s, STEWART_CALL_DO_STEP);
    if (!(h > 0 && isfinite(h))) return STEWART_BAD_STEP;
    if (!(fabs(t - s->time) <= TIME_EPS * fmax(1.0, fabs(s->time)))) return STEWART_BAD_TIME;
    if (!s->energy_valid) {
        stewart_energy_terms(params, s->y, s->energy);
        s->energy_valid = 1;
    }
    return STEWART_OK;
}

static void take_step(stewart_component *s, const double *y1, const double *e1, double t, double h) {
    memcpy(s->y, y1, (size_t)s->n * sizeof(double));
    memcpy(s->energy, e1, sizeof s->energy);
    s->time = t + h;
}

int stewart_component_do_step(stewart_component *s, const double *params, const stewart_options *o,
                              double t, double h) {
    double y1[STEWART_MAX_STATE], e1[STEWART_N_ENERGY];
    long evaluations = 0;
    int status = stewart_component_begin_step(s, params, t, h);
    if (status != STEWART_OK) return status;
    status = stewart_step(params, o, s->y, y1, s->rack, h, &s->step_guess, &evaluations, s->energy,
                          e1, &s->excess, &s->allowed);
    s->evaluations += evaluations;
    if (status == STEWART_OK) take_step(s, y1, e1, t, h);
    return status;
}

int stewart_component_end_step(stewart_component *s, const double *params, const double *y1,
                               double t, double h, double tol) {
    double e1[STEWART_N_ENERGY];
    if (!stewart_step_energy(params, y1, s->energy, e1, s->rack, tol, h, &s->excess, &s->allowed))
        return STEWART_STATE_NONFINITE;
    if (!(s->excess <= s->allowed)) return STEWART_UNSTABLE;
    take_step(s, y1, e1, t, h);
    return STEWART_OK;
}

size_t stewart_component_refusal(char *buf, size_t size, const stewart_component *s,
                                 const double *params, const char *method, double t, double h,
                                 int status) {
    return stewart_refusal(buf, size, params, method, t, h, status, s->y, s->rack, s->excess,
                           s->allowed);
}

/* ---- state ------------------------------------------------------------------------------ */

int stewart_component_check(const stewart_component *s, const double *params) {
    int ok = s->phase >= 0 && s->phase < STEWART_N_PHASES && (s->n == 12 || s->n == 24) &&
             (s->energy_valid == 0 || s->energy_valid == 1) && s->reserved == 0 &&
             s->evaluations >= 0 && isfinite(s->start_time) && isfinite(s->time) &&
             s->time >= s->start_time && isfinite(s->step_guess) && s->step_guess > 0 &&
             finite_all(s->initial, 12) && finite_all(s->sigma, 6) &&
             finite_all(s->tau, 6) && finite_all(s->rack, 6);
    if (ok) ok = finite_all(s->y, s->n);
    if (ok && params && (s->phase == STEWART_PH_STEPPING || s->phase == STEWART_PH_TERMINATED))
        ok = s->n == stewart_state_size(params);
    return ok ? STEWART_OK : STEWART_STATE_INVALID;
}

int stewart_component_load(stewart_component *s, const stewart_component *from, const double *params) {
    long long evaluations = s->evaluations;
    if (stewart_component_check(from, params) != STEWART_OK) return STEWART_STATE_INVALID;
    memmove(s, from, sizeof *s);
    s->evaluations = evaluations;
    s->energy_valid = 0;  /* recomputed from y before the next step */
    return STEWART_OK;
}

/* ---- serialized state -------------------------------------------------------------------- */

static const char MAGIC[8] = {'S', 'T', 'W', 'S', 'T', 'A', 'T', 'E'};
enum { H_MAGIC = 0, H_VERSION = 8, H_SIZE = 12, H_KEY = 16, H_CHECKSUM = 24, H_BYTES = 32 };
#define FNV_START 14695981039346656037ull

static unsigned long long fnv1a(const unsigned char *b, size_t n, unsigned long long h) {
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ull;
    }
    return h;
}

unsigned long long stewart_hash(const void *data, size_t n) {
    return fnv1a((const unsigned char *)data, n, FNV_START);
}

size_t stewart_serialized_size(size_t extra_size) {
    return H_BYTES + sizeof(stewart_component) + extra_size;
}

/* The checksum of a serialized state: the header up to the checksum, then the payload. */
static unsigned long long checksum(const unsigned char *b, size_t size) {
    return fnv1a(b + H_BYTES, size - H_BYTES, fnv1a(b, H_CHECKSUM, FNV_START));
}

int stewart_serialize(const stewart_component *s, const void *extra, size_t extra_size,
                      unsigned long long key, void *out, size_t size) {
    unsigned char *b = (unsigned char *)out;
    unsigned version = STEWART_STATE_VERSION, payload;
    unsigned long long sum;
    if (!out || size < stewart_serialized_size(extra_size)) return STEWART_BAD_STATE;
    size = stewart_serialized_size(extra_size);
    payload = (unsigned)(size - H_BYTES);
    memcpy(b + H_MAGIC, MAGIC, 8);
    memcpy(b + H_VERSION, &version, 4);
    memcpy(b + H_SIZE, &payload, 4);
    memcpy(b + H_KEY, &key, 8);
    memcpy(b + H_BYTES, s, sizeof *s);
    if (extra_size) memcpy(b + H_BYTES + sizeof *s, extra, extra_size);
    sum = checksum(b, size);
    memcpy(b + H_CHECKSUM, &sum, 8);
    return STEWART_OK;
}

int stewart_deserialize(const void *in, size_t size, unsigned long long key, stewart_component *s,
                        void *extra, size_t extra_size) {
    const unsigned char *b = (const unsigned char *)in;
    unsigned version, payload;
    unsigned long long k, sum;
    stewart_component c;
    if (!in || size != stewart_serialized_size(extra_size)) return STEWART_BAD_STATE;
    memcpy(&version, b + H_VERSION, 4);
    memcpy(&payload, b + H_SIZE, 4);
    memcpy(&k, b + H_KEY, 8);
    memcpy(&sum, b + H_CHECKSUM, 8);
    if (memcmp(b, MAGIC, 8) != 0 || version != STEWART_STATE_VERSION || payload != size - H_BYTES)
        return STEWART_BAD_STATE;
    if (k != key) return STEWART_STATE_FOREIGN;
    if (sum != checksum(b, size)) return STEWART_STATE_CORRUPT;
    memcpy(&c, b + H_BYTES, sizeof c);
    if (stewart_component_check(&c, NULL) != STEWART_OK) return STEWART_STATE_INVALID;
    *s = c;
    if (extra_size) memcpy(extra, b + H_BYTES + sizeof c, extra_size);
    return STEWART_OK;
}
