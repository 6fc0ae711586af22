/* The six axis controllers as an FMU (see model.h): parameters and their checks, held inputs,
 * outputs from axis.c's axis_step, whole-period steps, FMU states. The life cycle and its
 * call-sequence rules are the component's (stewart_fmu/native/src/component.c), as in the
 * plant's FMU: a call out of order, an unknown value reference, a write to an output, a
 * non-finite value, an input outside its declared range or a step that is not a whole number of
 * controller periods is fmiError with a logged message and changes nothing; a step whose state
 * would not be finite is fmiDiscard, and an output that is not finite is never read as fmiOK. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

/* ---- names of value references ------------------------------------------------------------ */

typedef struct { unsigned vr, count; const char *name; } Group;

#define GROUP(ID, NAME, COUNT, ...) {VR_##ID, COUNT, NAME},
static const Group GROUPS[] = {AXIS_FMU_PARAMETERS(GROUP) AXIS_FMU_INPUTS(GROUP) AXIS_FMU_OUTPUTS(GROUP)};

static const char *vr_name(unsigned vr, char buf[64]) {
    size_t k;
    for (k = 0; k < sizeof GROUPS / sizeof GROUPS[0]; k++) {
        const Group *g = &GROUPS[k];
        if (vr >= g->vr && vr < g->vr + g->count) {
            if (g->count == 1)
                snprintf(buf, 64, "%s", g->name);
            else
                snprintf(buf, 64, "%s[%u]", g->name, vr - g->vr + 1);
            return buf;
        }
    }
    snprintf(buf, 64, "?");
    return buf;
}

enum { K_UNKNOWN, K_PARAM, K_INPUT, K_OUTPUT, K_TIME };

static int vr_kind(unsigned vr) {
    if (vr == VR_TIME) return K_TIME;
    if (vr >= AXIS_VR_PARAMETERS && vr < AXIS_VR_PARAMETERS + N_PAR) return K_PARAM;
    if (vr >= AXIS_VR_INPUTS && vr < AXIS_VR_INPUTS + N_IN) return K_INPUT;
    if (vr >= AXIS_VR_OUTPUTS && vr < AXIS_VR_OUTPUTS + N_OUT) return K_OUTPUT;
    return K_UNKNOWN;
}

#define PAR(ID) (c->d.par[VR_##ID - AXIS_VR_PARAMETERS])
#define IN(ID) (c->d.in + (VR_##ID - AXIS_VR_INPUTS))

/* ---- life cycle ----------------------------------------------------------------------------- */

void model_reset(Instance *c) {
    static const double zero[12] = {0};
    memset(&c->d, 0, sizeof c->d);
    memcpy(c->d.par, AXIS_START, sizeof c->d.par);
    memcpy(c->d.in, AXIS_START_INPUTS, sizeof c->d.in);
    stewart_component_reset(&c->d.s, NULL, zero, zero, 1.0);
    c->have_out = c->discarded = 0;
}

int model_init(Instance *c, const char *name, const char *token) {
    if (glue_instantiate(c, name, token, AXIS_MODEL_TOKEN)) return M_ERROR;
    model_reset(c);
    return M_OK;
}

int model_setup(Instance *c, int tolerance_defined, double tolerance, double start_time) {
    (void)tolerance_defined, (void)tolerance;  /* no integrator: the controller is exact */
    if (!isfinite(start_time)) {
        model_log(c, M_ERROR, "setup: startTime must be finite, got %g", start_time);
        return M_ERROR;
    }
    return stewart_component_setup(&c->d.s, start_time) == STEWART_OK ? M_OK : M_ERROR;
}

int model_enter_init(Instance *c) {
    c->have_out = 0;
    return stewart_component_enter_init(&c->d.s) == STEWART_OK ? M_OK : M_ERROR;
}

/* The parameters' bounds (AXIS_FMU_PARAMETER_RANGES, the model description's min and max). */
#define PARAM_ROW(ID, BOUND, MIN, MAX) \
    {VR_##ID, (unsigned)(sizeof(((axis_fmu_parameters *)0)->ID) / sizeof(double)), BOUND, MIN, MAX},
static const struct { unsigned vr, count; int bound; double min, max; } PARAM_RANGES[] = {
    AXIS_FMU_PARAMETER_RANGES(PARAM_ROW)};

/* 0 when every bounded parameter is finite and within its bounds; else logs the first that is
 * not, naming it and the bound, and returns M_ERROR. */
static int check_bounds(Instance *c, const char *call) {
    char name[64];
    size_t k;
    unsigned i;
    for (k = 0; k < sizeof PARAM_RANGES / sizeof PARAM_RANGES[0]; k++)
        for (i = 0; i < PARAM_RANGES[k].count; i++) {
            const unsigned vr = PARAM_RANGES[k].vr + i;
            const double x = c->d.par[vr - AXIS_VR_PARAMETERS], lo = PARAM_RANGES[k].min;
            const int open = PARAM_RANGES[k].bound == AXIS_BOUND_OPEN;
            if (!isfinite(x) || !(open ? x > lo : x >= lo)) {
                model_log(c, M_ERROR, "%s: parameter %s must be a finite number %s %g, got %g", call,
                          vr_name(vr, name), open ? ">" : ">=", lo, x);
                return M_ERROR;
            }
            if (!(x <= PARAM_RANGES[k].max)) {
                model_log(c, M_ERROR, "%s: parameter %s must be <= %g, got %g", call,
                          vr_name(vr, name), PARAM_RANGES[k].max, x);
                return M_ERROR;
            }
        }
    return M_OK;
}

/* The parameters' rules (their bounds; delay and reference 0 or 1), then axis_step's constants
 * as controller/axis.py derives them (MotorCurrents: the current's decay over a period and its
 * mean). */
static int loop_of(Instance *c, const char *call, axis_loop *loop) {
    double dt, R, L;
    if (check_bounds(c, call)) return M_ERROR;
    if (!(PAR(DELAY) == 0.0 || PAR(DELAY) == 1.0)) {
        model_log(c, M_ERROR, "%s: parameter delay must be 0 (the sample at the current point) or 1 "
                  "(the last step's), got %g", call, PAR(DELAY));
        return M_ERROR;
    }
    if (!(PAR(REFERENCE) == 0.0 || (PAR(REFERENCE) == 1.0 && AXIS_REF_N > 0))) {
        model_log(c, M_ERROR, "%s: parameter reference must be 0 (the inputs)%s, got %g", call,
                  AXIS_REF_N > 0 ? " or 1 (the move this FMU carries)" : ": this FMU carries no move",
                  PAR(REFERENCE));
        return M_ERROR;
    }
    dt = 1.0 / PAR(RATE);
    R = PAR(RESISTANCE);
    L = PAR(INDUCTANCE);
    loop->kp = PAR(KP);
    loop->ki = PAR(KI);
    loop->kd = PAR(KD);
    loop->vmax = PAR(VOLTAGE_LIMIT);
    loop->dt = dt;
    loop->R = R;
    loop->Kt = PAR(TORQUE_CONSTANT);
    loop->emf = PAR(EMF_CONSTANT);
    loop->ilim = PAR(CURRENT_LIMIT);
    loop->decay = exp(-R * dt / L);
    loop->mean_decay = (1.0 - loop->decay) * L / (R * dt);  /* mean of exp(-t R / L) over dt */
    loop->gain = PAR(FORCE_PER_TORQUE);
    loop->bound = INFINITY;   /* unused: the master judges divergence */
    return M_OK;
}

/* The outputs of delay = 1 before any step: the drives' start, holding (current0). */
static void start_sample(const Instance *c, double *out) {
    axis_fmu_outputs o;
    int i;
    for (i = 0; i < 6; i++) {
        const double i0 = c->d.par[VR_CURRENT0 - AXIS_VR_PARAMETERS + i];
        o.TAU[i] = c->d.par[VR_TORQUE_CONSTANT - AXIS_VR_PARAMETERS] * i0;
        o.FORCE[i] = 0.0 + c->d.par[VR_FORCE_PER_TORQUE - AXIS_VR_PARAMETERS] * o.TAU[i];
        o.VOLTAGE[i] = c->d.par[VR_RESISTANCE - AXIS_VR_PARAMETERS] * i0;
        o.CURRENT[i] = i0;
        o.SATURATED[i] = 0.0;
    }
    memcpy(out, &o, sizeof o);
}

int model_exit_init(Instance *c) {
    ControllerData *d = &c->d;
    if (loop_of(c, "exitInitializationMode", &d->loop)) {
        stewart_component_fail(&d->s);
        c->have_out = 0;
        return M_ERROR;
    }
    memcpy(d->integral, d->par + (VR_INTEGRAL0 - AXIS_VR_PARAMETERS), sizeof d->integral);
    memcpy(d->current, d->par + (VR_CURRENT0 - AXIS_VR_PARAMETERS), sizeof d->current);
    start_sample(c, d->last);
    stewart_component_exit_init(&d->s, NULL);
    c->have_out = 0;
    model_log(c, M_OK, "exitInitializationMode: six axes at %g Hz from t = %.17g s", PAR(RATE), d->s.time);
    return M_OK;
}

int model_terminate(Instance *c) {
    return stewart_component_terminate(&c->d.s) == STEWART_OK ? M_OK : M_ERROR;
}

/* ---- the sample ---------------------------------------------------------------------------- */

/* references() hands axis_step l_ref, ldot_ref and v_ff as one row of 18: so are the inputs. */
typedef char inputs_are_one_row[offsetof(axis_fmu_inputs, V_FF) == 12 * sizeof(double) &&
                                offsetof(axis_fmu_inputs, LDOT_REF) == 6 * sizeof(double) ? 1 : -1];

/* The references of the sample at `time`: the inputs, or with parameter reference = 1 the
 * carried move's sample nearest to it (k = (time - startTime) rate, clamped to the move). */
static const double *references(Instance *c, double time) {
    double k;
    long i;
    if (PAR(REFERENCE) != 1.0) return IN(L_REF);  /* l_ref, ldot_ref, v_ff: consecutive inputs */
    k = floor((time - c->d.s.start_time) * PAR(RATE) + 0.5);
    i = k < 0 ? 0 : (k > (double)(AXIS_REF_N - 1) ? AXIS_REF_N - 1 : (long)k);
    return AXIS_REF + 18 * i;
}

/* One controller period at `time` from the held measurements: axis_step on integral and current. */
static void sample(const axis_loop *loop, Instance *c, double time, double *integral, double *current,
                   double *out) {
    axis_fmu_outputs o;
    unsigned char sat[6];
    const double *ref = references(c, time);
    int i;
    axis_step(loop, integral, current, ref, ref + 6, IN(L), IN(LDOT), ref + 12, o.VOLTAGE, o.TAU, sat);
    for (i = 0; i < 6; i++) {
        o.FORCE[i] = 0.0 + loop->gain * o.TAU[i];  /* as closed_loop_run: sigma (0) + zeta/r tau */
        o.CURRENT[i] = current[i];
        o.SATURATED[i] = sat[i] ? 1.0 : 0.0;
    }
    memcpy(out, &o, sizeof o);
}

#define MAX_PERIODS 1e7   /* controller periods one doStep takes at most (2.8 h at 1 kHz) */

int model_do_step(Instance *c, double t, double h, double *last_time) {
    ControllerData *d = &c->d;
    double periods, before[12], last[N_OUT];
    long n, k;
    if (last_time) *last_time = d->s.time;
    if (model_require(c, "doStep", STEWART_CALL_DO_STEP)) return M_ERROR;
    if (!(isfinite(h) && h > 0)) {
        model_log(c, M_ERROR, "doStep: communicationStepSize must be finite and > 0, got %.17g", h);
        return M_ERROR;
    }
    if (!(fabs(t - d->s.time) <= 1e-9 * fmax(1.0, fabs(d->s.time)))) {
        model_log(c, M_ERROR, "doStep: currentCommunicationPoint %.17g is not this FMU's time %.17g", t, d->s.time);
        return M_ERROR;
    }
    periods = h * PAR(RATE);
    if (!(periods <= MAX_PERIODS + 0.5)) {  /* bounded work per call (and a count a long holds) */
        model_log(c, M_ERROR, "doStep: communicationStepSize %.17g s is %g controller periods, more than the %g "
                  "one step takes: step in parts", h, periods, MAX_PERIODS);
        return M_ERROR;
    }
    n = (long)floor(periods + 0.5);
    if (n < 1 || fabs(periods - (double)n) > 1e-9 * (double)n) {
        model_log(c, M_ERROR, "doStep: communicationStepSize %.17g s is not a whole number of controller "
                  "periods (1 / rate = %.17g s): the controller samples at its rate only", h, d->loop.dt);
        return M_ERROR;
    }
    if (!isfinite(t + h)) {
        model_log(c, M_ERROR, "doStep: currentCommunicationPoint %.17g + communicationStepSize %.17g is not finite", t, h);
        return M_ERROR;
    }
    memcpy(before, d->integral, sizeof d->integral);
    memcpy(before + 6, d->current, sizeof d->current);
    memcpy(last, d->last, sizeof last);
    for (k = 0; k < n; k++)  /* the inputs held over the step */
        sample(&d->loop, c, t + (double)k * d->loop.dt, d->integral, d->current, d->last);
    for (k = 0; k < 12; k++)  /* one finiteness pass: a non-finite state is never kept */
        if (!isfinite(k < 6 ? d->integral[k] : d->current[k - 6])) break;
    if (k < 12) {
        model_log(c, M_DISCARD, "doStep at t = %.17g s, h = %.17g s: the %s of axis %ld would not be finite: "
                  "discarded, the state stays at the start of the step", t, h, k < 6 ? "PID integral" : "motor current",
                  k % 6 + 1);
        memcpy(d->integral, before, sizeof d->integral);
        memcpy(d->current, before + 6, sizeof d->current);
        memcpy(d->last, last, sizeof last);
        c->have_out = 0;
        c->discarded = 1;
        return M_DISCARD;
    }
    c->discarded = 0;
    d->s.time = t + h;
    if (last_time) *last_time = d->s.time;
    c->have_out = 0;
    return M_OK;
}

/* ---- outputs ---------------------------------------------------------------------------------- */

/* delay 0: the sample at the current point on copies of the state (nothing advances), before
 * exitInitializationMode from integral0, current0 and the parameters set so far; delay 1: the
 * last period's sample. */
static int outputs(Instance *c) {
    double integral[6], current[6];
    axis_loop loop;
    ControllerData *d = &c->d;
    int running = d->s.phase == STEWART_PH_STEPPING || d->s.phase == STEWART_PH_TERMINATED;
    if (c->have_out) return M_OK;
    if (d->s.phase == STEWART_PH_FAILED) {
        model_log(c, M_ERROR, "getReal: no outputs: initialization failed (see the log)");
        return M_ERROR;
    }
    if (!running && loop_of(c, "getReal", &loop)) return M_ERROR;
    if (PAR(DELAY) == 1.0) {
        if (running)
            memcpy(c->out, d->last, sizeof c->out);
        else
            start_sample(c, c->out);
        c->have_out = 1;
        return M_OK;
    }
    if (running) {
        loop = d->loop;
        memcpy(integral, d->integral, sizeof integral);
        memcpy(current, d->current, sizeof current);
    } else {
        memcpy(integral, d->par + (VR_INTEGRAL0 - AXIS_VR_PARAMETERS), sizeof integral);
        memcpy(current, d->par + (VR_CURRENT0 - AXIS_VR_PARAMETERS), sizeof current);
    }
    sample(&loop, c, d->s.time, integral, current, c->out);
    c->have_out = 1;
    return M_OK;
}

/* ---- get / set -------------------------------------------------------------------------------- */

static int check_args(Instance *c, const char *call, const void *vr, size_t n, const void *value,
                      size_t nvalues) {
    if (n > 0 && (!vr || !value)) {
        model_log(c, M_ERROR, "%s: NULL array with %lu value references", call, (unsigned long)n);
        return M_ERROR;
    }
    if (nvalues != n) {
        model_log(c, M_ERROR, "%s: %lu values for %lu value references: every variable of the "
                  "controller is a scalar", call, (unsigned long)nvalues, (unsigned long)n);
        return M_ERROR;
    }
    return M_OK;
}

int model_get_real(Instance *c, const unsigned vr[], size_t n, double value[], size_t nvalues) {
    size_t k;
    if (check_args(c, "getReal", vr, n, value, nvalues)) return M_ERROR;
    for (k = 0; k < n; k++) {
        switch (vr_kind(vr[k])) {
        case K_PARAM: value[k] = c->d.par[vr[k] - AXIS_VR_PARAMETERS]; break;
        case K_INPUT: value[k] = c->d.in[vr[k] - AXIS_VR_INPUTS]; break;
        case K_TIME: value[k] = c->d.s.time; break;
        case K_OUTPUT:
            if (outputs(c)) return M_ERROR;
            value[k] = c->out[vr[k] - AXIS_VR_OUTPUTS];
            if (!isfinite(value[k])) {  /* never an OK with a NaN or an infinity */
                char name[64];
                model_log(c, M_ERROR, "getReal: output %s at t = %.17g s is not finite (%g): no value",
                          vr_name(vr[k], name), c->d.s.time, value[k]);
                return M_ERROR;
            }
            break;
        default:
            model_log(c, M_ERROR, "getReal: unknown value reference %u", vr[k]);
            return M_ERROR;
        }
    }
    return M_OK;
}

/* The inputs' declared ranges (AXIS_FMU_INPUT_RANGES, the model description's min and max). */
#define RANGE_ROW(ID, MIN, MAX) {VR_##ID, (unsigned)(sizeof(((axis_fmu_inputs *)0)->ID) / sizeof(double)), MIN, MAX},
static const struct { unsigned vr, count; double min, max; } RANGES[] = {AXIS_FMU_INPUT_RANGES(RANGE_ROW)};

/* x lies in the declared range of input v (x finite). */
static int in_range(unsigned v, double x, double *min, double *max) {
    size_t k;
    for (k = 0; k < sizeof RANGES / sizeof RANGES[0]; k++)
        if (v >= RANGES[k].vr && v < RANGES[k].vr + RANGES[k].count) {
            *min = RANGES[k].min;
            *max = RANGES[k].max;
            return x >= *min && x <= *max;
        }
    return 1;
}

int model_set_real(Instance *c, const unsigned vr[], size_t n, const double value[], size_t nvalues) {
    int phase = c->d.s.phase;
    size_t k;
    double lo, hi;
    char name[64];
    if (check_args(c, "setReal", vr, n, value, nvalues)) return M_ERROR;
    for (k = 0; k < n; k++) {  /* every value checked first: an Error changes nothing */
        int kind = vr_kind(vr[k]);
        if (kind == K_UNKNOWN) {
            model_log(c, M_ERROR, "setReal: unknown value reference %u", vr[k]);
            return M_ERROR;
        }
        if (kind == K_OUTPUT || kind == K_TIME) {
            model_log(c, M_ERROR, "setReal: %s (value reference %u) is %s: it cannot be set",
                      kind == K_TIME ? "time" : vr_name(vr[k], name), vr[k],
                      kind == K_TIME ? "the independent variable" : "an output");
            return M_ERROR;
        }
        if (kind == K_PARAM && !stewart_allowed(STEWART_CALL_SET_PARAMETER, phase)) {
            model_log(c, M_ERROR, "setReal: parameter %s is fixed: it can only be set before exitInitializationMode "
                      "(now in %s)", vr_name(vr[k], name), stewart_phase_name(phase));
            return M_ERROR;
        }
        if (kind == K_INPUT && !stewart_allowed(STEWART_CALL_SET_INPUT, phase)) {
            model_log(c, M_ERROR, "setReal: input %s cannot be set in %s", vr_name(vr[k], name),
                      stewart_phase_name(phase));
            return M_ERROR;
        }
        if (!isfinite(value[k])) {
            model_log(c, M_ERROR, "setReal: %s = %g at t = %.17g s is not finite: rejected",
                      vr_name(vr[k], name), value[k], c->d.s.time);
            return M_ERROR;
        }
        if (kind == K_INPUT && !in_range(vr[k], value[k], &lo, &hi)) {
            model_log(c, M_ERROR, "setReal: input %s = %g at t = %.17g s is outside its declared range [%g, %g]: "
                      "rejected", vr_name(vr[k], name), value[k], c->d.s.time, lo, hi);
            return M_ERROR;
        }
    }
    for (k = 0; k < n; k++) {
        if (vr_kind(vr[k]) == K_PARAM)
            c->d.par[vr[k] - AXIS_VR_PARAMETERS] = value[k];
        else
            c->d.in[vr[k] - AXIS_VR_INPUTS] = value[k];
    }
    if (n) c->have_out = 0;
    return M_OK;
}

int model_wrong_type(Instance *c, const char *call, const unsigned vr[], size_t n) {
    char name[64];
    if (n == 0) return M_OK;
    if (!vr) return check_args(c, call, vr, n, NULL, n);
    if (vr_kind(vr[0]) == K_UNKNOWN)
        model_log(c, M_ERROR, "%s: unknown value reference %u", call, vr[0]);
    else
        model_log(c, M_ERROR, "%s: %s (value reference %u) is not of this type", call, vr_name(vr[0], name), vr[0]);
    return M_ERROR;
}

int model_get_string(Instance *c, const unsigned vr[], size_t n, const char *value[]) {
    if (check_args(c, "getString", vr, n, value, n)) return M_ERROR;
    return model_wrong_type(c, "getString", vr, n);
}

int model_set_string(Instance *c, const unsigned vr[], size_t n, const char *const value[]) {
    if (check_args(c, "setString", vr, n, value, n)) return M_ERROR;
    return model_wrong_type(c, "setString", vr, n);
}

/* ---- FMU states ------------------------------------------------------------------------------- */

#define STATE_MAGIC 0x53544143u   /* "STAC" */

typedef struct {
    unsigned magic;
    ControllerData d;
} State;

int model_get_state(Instance *c, void **state) {
    State *s = glue_state_block(c, "getFMUstate", state, STATE_MAGIC, sizeof *s);
    if (!s) return M_ERROR;
    s->d = c->d;
    return M_OK;
}

int model_set_state(Instance *c, const void *state) {
    const State *s = glue_state_of(c, "setFMUstate", state, STATE_MAGIC);
    if (!s) return M_ERROR;
    c->d = s->d;
    c->have_out = 0;
    return M_OK;
}

int model_free_state(Instance *c, void **state) {
    (void)c;
    return glue_free_state(state);
}

size_t model_serialized_size(void) { return 0; }

int model_serialize(Instance *c, const void *state, unsigned char *out, size_t size) {
    (void)state, (void)out, (void)size;
    model_log(c, M_ERROR, "serializeFMUstate: not provided (canSerializeFMUstate = false)");
    return M_ERROR;
}

int model_deserialize(Instance *c, const unsigned char *in, size_t size, void **state) {
    (void)in, (void)size, (void)state;
    model_log(c, M_ERROR, "deserializeFMUstate: not provided (canSerializeFMUstate = false)");
    return M_ERROR;
}
