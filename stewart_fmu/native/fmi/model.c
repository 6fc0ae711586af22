/* The Stewart-platform plant as an FMU (see model.h): parameters and their validation, inputs,
 * outputs computed on demand, FMU states. The life cycle, its call-sequence rules, the state,
 * the step and its refusal message, and the serialized form are the component's
 * (native/src/component.c, which stewart_fmu.plant.Plant wraps too).
 *
 * The physics is the C core (stewart.h); this file only keeps the FMI semantics, as the
 * Modelica Association's Reference FMUs do: a call out of order, an unknown value reference, a
 * write to an output, a non-finite value or a bad step is fmiError with a logged message and
 * changes nothing; a step the plant cannot take (stroke, singular pose, failed power balance,
 * too many internal steps) is fmiDiscard with the state left at the start of the step. */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"



/* ---- names of value references ------------------------------------------------------------ */

typedef struct { unsigned vr, count; int shape; const char *name; } Group;

#define GROUP(ID, NAME, COUNT, SHAPE, ...) {VR_##ID, COUNT, SHAPE, NAME},
#define STRING_GROUP(ID, NAME, WHAT) {VR_##ID, 1, STEWART_STRING, NAME},
static const Group GROUPS[] = {
    STEWART_FMU_SCENE(GROUP) STEWART_FMU_SETTINGS(GROUP) STEWART_FMU_STRINGS(STRING_GROUP)
    STEWART_FMU_INPUTS(GROUP) STEWART_FMU_OUTPUTS(GROUP) STEWART_FMU_OUTPUT_ARRAYS(GROUP)
};

static int has(unsigned vr);

/* The variable's name in the model description ("?" for none). */
static const char *vr_name(unsigned vr, char buf[64]) {
    size_t k;
    for (k = 0; k < sizeof GROUPS / sizeof GROUPS[0]; k++) {
        const Group *g = &GROUPS[k];
        if (vr >= g->vr && vr < g->vr + g->count) {
            unsigned i = vr - g->vr;
            /* a per-leg parameter given once for all legs has the group's plain name */
            if (g->count == 1 || (g->shape == STEWART_PER_LEG && g->vr < VR_N_PAR && !has(g->vr + 1)))
                snprintf(buf, 64, "%s", g->name);
            else if (g->shape > 0)
                snprintf(buf, 64, "%s[%u,%u]", g->name, i / (unsigned)g->shape + 1, i % (unsigned)g->shape + 1);
            else
                snprintf(buf, 64, "%s[%u]", g->name, i + 1);
            return buf;
        }
    }
    snprintf(buf, 64, "?");
    return buf;
}

/* ---- which value references this FMU declares ---------------------------------------------- */

enum { K_UNKNOWN, K_PARAM, K_METHOD, K_INPUT, K_OUTPUT, K_TIME };

/* How many values a declared value reference holds (0: not a value reference of this FMU). */
static unsigned values_at(unsigned vr) { return vr < VR_END ? STEWART_VALUES[vr] : 0u; }

/* A value is present at vr: vr lies in a declared variable (a scalar, or an FMI 3.0 array whose
 * elements follow its value reference). */
static int has(unsigned vr) {
    unsigned v = vr < VR_END ? vr + 1 : 0u;
    while (v-- > 0)
        if (values_at(v)) return vr - v < values_at(v);
    return 0;
}
static int has_legs(void) { return has(VR_LOWER_MASS); }
static int has_drive(void) { return has(VR_GEAR_RATIO); }
static int has_friction(void) { return has(VR_VISCOUS); }
static int has_transmission(void) { return has(VR_STIFFNESS); }

static int part_present(int part) {
    switch (part) {
    case STEWART_PART_LOWER_LEGS:
    case STEWART_PART_UPPER_LEGS: return has_legs();
    case STEWART_PART_DRIVES: return has_drive();
    case STEWART_PART_FRICTION: return has_friction();
    default: return 1;
    }
}

static int vr_kind(unsigned vr) {
    if (vr == 0) return has(0) ? K_TIME : K_UNKNOWN;  /* FMI 3.0: the independent variable */
    if (vr >= 1 && vr < VR_N_PAR) return has(vr) ? K_PARAM : K_UNKNOWN;
    if (vr == VR_METHOD) return K_METHOD;
    if (vr >= VR_SIGMA && vr < VR_SIGMA + 6) return K_INPUT;
    if (vr >= VR_TAU && vr < VR_TAU + 6) return has_drive() ? K_INPUT : K_UNKNOWN;
    if (vr >= VR_L && vr < VR_FORCE_PLATFORM) return K_OUTPUT;
    if (vr >= VR_FORCE_PLATFORM && vr < VR_Q) return part_present((int)((vr - VR_FORCE_PLATFORM) / 6)) ? K_OUTPUT : K_UNKNOWN;
    if (vr >= VR_Q && vr < VR_END) return K_OUTPUT;
    return K_UNKNOWN;
}

/* The kind of a value reference an importer passes: only declared ones are known (an FMI 3.0
 * array's element value references are not). */
static int declared_kind(unsigned vr) { return values_at(vr) ? vr_kind(vr) : K_UNKNOWN; }

/* ---- life cycle ----------------------------------------------------------------------------- */

static void clear_outputs(Instance *c) {
    c->have_legs = c->have_cond = c->have_parts = c->have_initial = 0;
    c->discarded = 0;
}

static void update_rack(Instance *c) {
    double gain = has_drive() ? c->d.par[VR_GEAR_RATIO] / c->d.par[VR_PINION_RADIUS] : 0.0;
    int i, finite = 1;
    stewart_component_hold(&c->d.s, gain);
    for (i = 0; i < 6; i++)
        finite = finite && isfinite(c->d.s.rack[i]);
    /* Before exitInitializationMode the drive's values are not yet validated: one that gives no
       finite rack force (a zero pinion radius: inf * 0) must not make the FMU's state one its
       own check refuses; validation refuses such values, and the rack is recomputed then. */
    if (!finite)
        stewart_component_hold(&c->d.s, 0.0);
}

/* q0, qd0 of the parameter values, as the component's initial values. */
static const double *initial_values(const Instance *c, double q0[12]) {
    memcpy(q0, c->d.par + VR_Q0, 6 * sizeof(double));
    memcpy(q0 + 6, c->d.par + VR_QD0, 6 * sizeof(double));
    return q0;
}

void model_reset(Instance *c) {
    double q0[12];
    memset(&c->d, 0, sizeof c->d);
    memcpy(c->d.par, STEWART_START, sizeof c->d.par);
    c->d.method = STEWART_START_METHOD;
    stewart_component_reset(&c->d.s, NULL, initial_values(c, q0), STEWART_START_SIGMA, c->d.par[VR_MAX_STEP]);
    clear_outputs(c);
    update_rack(c);
}

int model_init(Instance *c, const char *name, const char *token) {
    if (glue_instantiate(c, name, token, STEWART_MODEL_TOKEN)) return M_ERROR;
    model_reset(c);
    return M_OK;
}

int model_setup(Instance *c, int tolerance_defined, double tolerance, double start_time) {
    if (!isfinite(start_time)) {
        model_log(c, M_ERROR, "setup: startTime must be finite, got %g", start_time);
        return M_ERROR;
    }
    if (tolerance_defined && !(isfinite(tolerance) && tolerance > 0)) {
        model_log(c, M_ERROR, "setup: tolerance must be finite and > 0, got %g", tolerance);
        return M_ERROR;
    }
    c->d.tolerance_defined = tolerance_defined != 0;
    c->d.tolerance = tolerance_defined ? tolerance : 0.0;
    return stewart_component_setup(&c->d.s, start_time) == STEWART_OK ? M_OK : M_ERROR;
}

int model_enter_init(Instance *c) {
    int status = stewart_component_enter_init(&c->d.s);
    clear_outputs(c);
    return status == STEWART_OK ? M_OK : M_ERROR;
}

/* The packed parameter vector from the parameter values (Model.params of stewart_fmu/model.py):
 * the entries of STEWART_PARAMS with a SOURCE copied from their variables when declared, the
 * COMPUTED ones derived here. */
#define VR_COMPUTED VR_TIME  /* never a parameter: marks the COMPUTED entries */
#define PACKED_ROW(NAME, COUNT, SOURCE, ...) {STEWART_P_##NAME, COUNT, VR_##SOURCE},
static const struct { int offset, count; unsigned vr; } PACKED[] = {STEWART_PARAMS(PACKED_ROW)};

static void pack(const double *par, double *p) {
    size_t k;
    int i;
    double sum = 0.0;
    memset(p, 0, STEWART_N_PARAMS * sizeof(double));
    for (k = 0; k < sizeof PACKED / sizeof PACKED[0]; k++) {
        unsigned vr = PACKED[k].vr;
        int once = PACKED[k].count > 1 && !has(vr + 1);  /* a per-leg key given for all legs */
        if (vr == VR_COMPUTED || !has(vr)) continue;
        for (i = 0; i < PACKED[k].count; i++) p[PACKED[k].offset + i] = par[vr + (once ? 0u : (unsigned)i)];
    }
    p[STEWART_P_HAS_LEGS] = has_legs();
    p[STEWART_P_HAS_DRIVE] = has_drive();
    p[STEWART_P_HAS_FRICTION] = has_friction();
    p[STEWART_P_HAS_TRANSMISSION] = has_transmission();
    if (has_drive()) {
        double g = par[VR_GEAR_RATIO], r = par[VR_PINION_RADIUS];
        int once = !has(VR_ROTOR_INERTIA + 1);
        for (i = 0; i < 6; i++)
            p[STEWART_P_DRIVE_MASS + i] = g * g * par[VR_ROTOR_INERTIA + (once ? 0 : i)] / (r * r);
    }
    if (!has(VR_LEG_MAX)) p[STEWART_P_LEG_MAX] = INFINITY;
    for (i = 0; i < 6; i++) {  /* np.mean(np.linalg.norm(platform_joints, axis=1)) */
        const double *pj = par + VR_PLATFORM + 3 * i;
        sum += sqrt(pj[0] * pj[0] + pj[1] * pj[1] + pj[2] * pj[2]);
    }
    p[STEWART_P_CHAR_LENGTH] = sum / 6.0;
}

/* A broken rule between keys (native/src/rules.c), logged naming its parameter: the element at
 * fault ("geometry.base_joints[4,1]") or the key ("geometry.home"). */
static int rule_broken(Instance *c, const char *call, const stewart_rule_break *b) {
    char name[64];
    size_t k;
    if (b->element >= 0) {
        vr_name((unsigned)(b->vr + b->element), name);
    } else {
        snprintf(name, sizeof name, "?");
        for (k = 0; k < sizeof GROUPS / sizeof GROUPS[0]; k++)
            if (GROUPS[k].vr == (unsigned)b->vr) snprintf(name, sizeof name, "%s", GROUPS[k].name);
    }
    model_log(c, M_ERROR, "%s: parameter %s %s", call, name, b->reason);
    return M_ERROR;
}

/* The initial pose q0: within the stroke and away from singularities (stewart_check_pose). */
static int check_q0(Instance *c, const char *call, const double *p) {
    stewart_rule_break b;
    if (stewart_check_pose(p, c->d.par + VR_Q0, VR_Q0, &b) == STEWART_RULE_OK) return M_OK;
    return rule_broken(c, call, &b);
}

/* The per-key bounds of the table (BOUND, MIN, MAX of STEWART_FMU_SCENE and _SETTINGS). */
#define BOUND_ROW(ID, NAME, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, ...) \
    {VR_##ID, COUNT, STEWART_BOUND_##BOUND, MIN, MAX, UNIT},
static const struct { unsigned vr, count; int bound; double min, max; const char *unit; } BOUNDS[] = {
    STEWART_FMU_SCENE(BOUND_ROW) STEWART_FMU_SETTINGS(BOUND_ROW)
};

/* " m" after a bound: the unit as the scene reader words it (stewart_fmu/table.py unit_text). */
static const char *unit_text(const char *unit, char buf[32]) {
    if (strcmp(unit, "pose") == 0) return " (m, rad)";
    if (strcmp(unit, "rate") == 0) return " (m/s, rad/s)";
    snprintf(buf, 32, "%s%s", *unit && strcmp(unit, "1") != 0 ? " " : "", strcmp(unit, "1") ? unit : "");
    return buf;
}

/* The rules of a scene, as stewart_fmu/scene.py checks them, naming the parameter that breaks
 * one: finite values, the per-key bounds of the table, the drive's derived quantities, then the
 * rules between keys and the home pose on the packed parameters (native/src/rules.c). */
static int validate(Instance *c, const char *call, const double *v, double *p) {
    char name[64], unit[32], got[32];
    stewart_rule_break broken;
    unsigned vr;
    int k;
#define FAIL(VR, ...)                                                             \
    do {                                                                          \
        char why_[256];                                                           \
        snprintf(why_, sizeof why_, __VA_ARGS__);                                 \
        model_log(c, M_ERROR, "%s: parameter %s %s", call, vr_name(VR, name), why_); \
        return M_ERROR;                                                           \
    } while (0)
    for (vr = 1; vr < VR_N_PAR; vr++)
        if (has(vr) && !isfinite(v[vr])) FAIL(vr, "must be finite, got %g", v[vr]);
    for (k = 0; k < (int)(sizeof BOUNDS / sizeof BOUNDS[0]); k++)  /* the per-key bounds */
        for (vr = BOUNDS[k].vr; vr < BOUNDS[k].vr + BOUNDS[k].count; vr++) {
            int open = BOUNDS[k].bound == STEWART_BOUND_OPEN;
            const char *u = unit_text(BOUNDS[k].unit, unit);
            if (!has(vr)) continue;
            stewart_format_double(got, v[vr]);  /* as the scene reader's repr */
            if (open ? !(v[vr] > BOUNDS[k].min) : !(v[vr] >= BOUNDS[k].min))
                FAIL(vr, "must be %s %g%s, got %s", open ? ">" : ">=", BOUNDS[k].min, BOUNDS[k].min == 0 ? "" : u, got);
            if (!(v[vr] <= BOUNDS[k].max)) FAIL(vr, "must be <= %g%s, got %s", BOUNDS[k].max, u, got);
        }
#undef FAIL
    if (has_drive()) {  /* the rack ratio and m_d, from the keys (rotor inertia given once: all legs) */
        double rotor[6];
        int once = !has(VR_ROTOR_INERTIA + 1);
        for (k = 0; k < 6; k++) rotor[k] = v[VR_ROTOR_INERTIA + (once ? 0 : k)];
        if (stewart_check_drive(v[VR_GEAR_RATIO], v[VR_PINION_RADIUS], rotor, &broken) != STEWART_RULE_OK)
            return rule_broken(c, call, &broken);
    }
    pack(v, p);
    if (stewart_check_rules(p, v + VR_HOME, &broken) != STEWART_RULE_OK) return rule_broken(c, call, &broken);
    return M_OK;
}

static stewart_options options(const Instance *c) {
    stewart_options o = stewart_default_options();
    o.method = (stewart_method)c->d.method;
    o.rtol = c->d.tolerance_defined ? c->d.tolerance : c->d.par[VR_RTOL];
    o.atol = c->d.par[VR_ATOL];
    o.max_step = c->d.par[VR_MAX_STEP];
    return o;  /* max_steps and energy_tol: the core's defaults, as Plant's */
}

int model_exit_init(Instance *c) {
    PlantData *d = &c->d;
    const char *call = "exitInitializationMode";
    if (validate(c, call, d->par, d->p) || check_q0(c, call, d->p)) {
        stewart_component_fail(&d->s);
        clear_outputs(c);
        return M_ERROR;
    }
    update_rack(c);
    initial_values(c, d->s.initial);
    stewart_component_exit_init(&d->s, d->p);
    clear_outputs(c);
    model_log(c, M_OK, "%s: %s at t = %.17g s, %s, max_step %g s", call,
              has_transmission() ? "24 states" : "12 states", d->s.time, stewart_method_name(d->method), d->par[VR_MAX_STEP]);
    return M_OK;
}

int model_terminate(Instance *c) {
    return stewart_component_terminate(&c->d.s) == STEWART_OK ? M_OK : M_ERROR;
}

/* ---- stepping ------------------------------------------------------------------------------- */

int model_do_step(Instance *c, double t, double h, double *last_time) {
    PlantData *d = &c->d;
    stewart_options o = options(c);
    char msg[1024];
    int status;
    if (last_time) *last_time = d->s.time;
    if (isfinite(t) && isfinite(h) && !isfinite(t + h)) {  /* the time after the step would not be finite */
        model_log(c, M_ERROR, "doStep: currentCommunicationPoint %.17g + communicationStepSize %.17g is not finite", t, h);
        return M_ERROR;
    }
    update_rack(c);
    /* on OK the state y is finite: the step refuses a non-finite one (STEWART_STATE_NONFINITE) */
    status = stewart_component_do_step(&d->s, d->p, &o, t, h);
    switch (status) {
    case STEWART_OK:
        if (last_time) *last_time = d->s.time;
        c->have_legs = c->have_cond = c->have_parts = c->discarded = 0;
        return M_OK;
    case STEWART_BAD_CALL: return model_require(c, "doStep", STEWART_CALL_DO_STEP);
    case STEWART_BAD_STEP:
        model_log(c, M_ERROR, "doStep: communicationStepSize %s, got %.17g", stewart_status_why(status), h);
        return M_ERROR;
    case STEWART_BAD_TIME:
        model_log(c, M_ERROR, "doStep: currentCommunicationPoint %.17g %s %.17g", t, stewart_status_why(status),
                  d->s.time);
        return M_ERROR;
    default:  /* a step the plant cannot take: the state stays at its start */
        stewart_component_refusal(msg, sizeof msg, &d->s, d->p, stewart_method_name(d->method), t, h, status);
        model_log(c, M_DISCARD, "%s", msg);
        c->discarded = 1;
        return M_DISCARD;
    }
}

/* ---- outputs ---------------------------------------------------------------------------------- */

/* The packed parameters and state the outputs are computed from: the running plant's, or
 * before exitInitializationMode those of the values set so far (if they are valid). */
static int output_source(Instance *c, const double **p, const double **y) {
    PlantData *d = &c->d;
    if (d->s.phase == STEWART_PH_STEPPING || d->s.phase == STEWART_PH_TERMINATED) {
        *p = d->p;
        *y = d->s.y;
        return M_OK;
    }
    if (d->s.phase == STEWART_PH_FAILED) {
        model_log(c, M_ERROR, "getReal: no outputs: initialization failed (see the log)");
        return M_ERROR;
    }
    if (!c->have_initial) {
        InstanceLogger log = c->log;
        c->log = NULL;  /* quiet check: the values may still be set before exitInitializationMode */
        if (validate(c, "getReal", d->par, c->lp) || check_q0(c, "getReal", c->lp)) {
            c->log = log;
            model_log(c, M_ERROR, "getReal: outputs are undefined: the parameters set so far are not valid "
                      "(exitInitializationMode names the problem)");
            return M_ERROR;
        }
        c->log = log;
        update_rack(c);
        d->s.n = stewart_initial_state(c->lp, d->par + VR_Q0, d->par + VR_QD0, d->s.rack, d->s.y);
        c->have_initial = 1;
        c->have_legs = c->have_cond = c->have_parts = 0;
    }
    *p = c->lp;
    *y = d->s.y;
    return M_OK;
}

/* The leg lengths at the state are the driven coordinates of its energy terms when the
 * component holds them and the plant is rigid (energy.c: every step's power balance computes them
 * at the new state, with stewart_leg_state's arithmetic): an importer that reads only l (a
 * controller's measurement) costs no kinematics per step. */
static int lengths_held(const Instance *c) {
    const stewart_component *s = &c->d.s;
    return s->energy_valid && !has_transmission() &&
           (s->phase == STEWART_PH_STEPPING || s->phase == STEWART_PH_TERMINATED);
}

static int output(Instance *c, unsigned vr, double *value) {
    const double *p, *y;
    if (output_source(c, &p, &y)) return M_ERROR;
    if (vr >= VR_L && vr < VR_LDOT && !c->have_legs && lengths_held(c)) {
        *value = c->d.s.energy[STEWART_ENERGY_DRIVEN + (vr - VR_L)];
    } else if ((vr >= VR_L && vr < VR_Q_X) || (vr >= VR_OMEGA && vr < VR_OMEGA + 3)) {
        if (!c->have_legs) {
            stewart_leg_state(p, y, y + 6, c->l, c->ldot, c->omega);
            c->have_legs = 1;
        }
        *value = vr < VR_LDOT ? c->l[vr - VR_L] : vr < VR_Q_X ? c->ldot[vr - VR_LDOT] : c->omega[vr - VR_OMEGA];
    } else if (vr >= VR_Q_X && vr < VR_Q_X + 12) {
        *value = y[vr - VR_Q_X];
    } else if (vr >= VR_Q && vr < VR_Q + 12) {   /* q then qd: the state's first 12 */
        *value = y[vr - VR_Q];
    } else if (vr >= VR_V && vr < VR_V + 3) {
        *value = y[6 + vr - VR_V];
    } else if (vr == VR_COND) {
        if (!c->have_cond) {
            stewart_condition_number(p, y, &c->cond);
            c->have_cond = 1;
        }
        *value = c->cond;
    } else if (vr >= VR_RACK && vr < VR_RACK + 6) {
        update_rack(c);
        *value = c->d.s.rack[vr - VR_RACK];
    } else {
        if (!c->have_parts) {
            update_rack(c);
            stewart_plant_parts(p, y, c->d.s.rack, c->parts);  /* zeros where not computed */
            c->have_parts = 1;
        }
        *value = c->parts[vr - VR_FORCE_PLATFORM];
    }
    if (!isfinite(*value)) {  /* never an OK with a NaN or an infinity */
        char name[64];
        model_log(c, M_ERROR, "getReal: output %s at t = %.17g s is not finite (%g): no value", vr_name(vr, name),
                  c->d.s.time, *value);
        return M_ERROR;
    }
    return M_OK;
}

/* ---- get / set -------------------------------------------------------------------------------- */

static int check_args(Instance *c, const char *call, const void *vr, size_t n, const void *value) {
    if (n > 0 && (!vr || !value)) {
        model_log(c, M_ERROR, "%s: NULL array with %lu value references", call, (unsigned long)n);
        return M_ERROR;
    }
    return M_OK;
}

/* The values vr[0..nvr) hold, each an array's elements or one scalar: M_ERROR, logged, for an
 * unknown value reference or when they are not nvalues (so that nothing is read or written past
 * the importer's array). */
static int count_values(Instance *c, const char *call, const unsigned vr[], size_t nvr, size_t nvalues) {
    size_t k, total = 0;
    for (k = 0; k < nvr; k++) {
        if (!values_at(vr[k])) {
            model_log(c, M_ERROR, "%s: unknown value reference %u", call, vr[k]);
            return M_ERROR;
        }
        total += values_at(vr[k]);   /* at most 255 each: no overflow for any nvr in memory */
    }
    if (total == nvalues) return M_OK;
    model_log(c, M_ERROR, "%s: %lu values for %lu value references holding %lu (an array's elements "
              "in row-major order)", call, (unsigned long)nvalues, (unsigned long)nvr, (unsigned long)total);
    return M_ERROR;
}

/* Element j of the importer's values, and its value reference: vr[k] + e, e the element of
 * vr[k]'s array (0 for a scalar); loops over every value of vr[0..nvr). */
#define FOR_EACH_VALUE(vr, nvr, k, e, j) \
    for (k = 0, j = 0; k < nvr; k++)     \
        for (e = 0; e < values_at(vr[k]); e++, j++)

int model_get_real(Instance *c, const unsigned vr[], size_t nvr, double value[], size_t nvalues) {
    size_t k, j;
    unsigned e;
    if (check_args(c, "getReal", vr, nvr, value) || count_values(c, "getReal", vr, nvr, nvalues)) return M_ERROR;
    FOR_EACH_VALUE(vr, nvr, k, e, j) {
        unsigned v = vr[k] + e;
        int kind = vr_kind(v);
        if (kind == K_PARAM) {
            value[j] = c->d.par[v];
        } else if (kind == K_TIME) {
            value[j] = c->d.s.time;
        } else if (kind == K_INPUT) {
            value[j] = v < VR_TAU ? c->d.s.sigma[v - VR_SIGMA] : c->d.s.tau[v - VR_TAU];
        } else if (kind == K_OUTPUT) {
            if (output(c, v, &value[j])) return M_ERROR;
        } else {
            model_log(c, M_ERROR, "getReal: %s value reference %u", kind == K_METHOD ? "not a Real:" : "unknown", v);
            return M_ERROR;
        }
    }
    return M_OK;
}

/* The inputs' declared ranges (STEWART_FMU_INPUT_RANGES, the model description's min and max). */
#define RANGE_ROW(ID, MIN, MAX) {VR_##ID, MIN, MAX},
static const struct { unsigned vr; double min, max; } RANGES[] = {STEWART_FMU_INPUT_RANGES(RANGE_ROW)};

/* The range of input v (a value reference of sigma or tau: six values each). */
static int input_range(unsigned v) {
    int k = 0;
    while (k + 1 < (int)(sizeof RANGES / sizeof RANGES[0]) && !(v >= RANGES[k].vr && v < RANGES[k].vr + 6)) k++;
    return k;
}

int model_set_real(Instance *c, const unsigned vr[], size_t nvr, const double value[], size_t nvalues) {
    int phase = c->d.s.phase;
    size_t k, j;
    unsigned e;
    char name[64];
    if (check_args(c, "setReal", vr, nvr, value) || count_values(c, "setReal", vr, nvr, nvalues)) return M_ERROR;
    /* Check every value first: an Error changes nothing. */
    FOR_EACH_VALUE(vr, nvr, k, e, j) {
        unsigned v = vr[k] + e;
        int kind = vr_kind(v);
        if (kind == K_UNKNOWN || kind == K_METHOD) {
            model_log(c, M_ERROR, "setReal: %s value reference %u", kind == K_METHOD ? "not a Real:" : "unknown", v);
            return M_ERROR;
        }
        if (kind == K_OUTPUT || kind == K_TIME) {
            model_log(c, M_ERROR, "setReal: %s (value reference %u) is %s: it cannot be set",
                      kind == K_TIME ? "time" : vr_name(v, name), vr[k],
                      kind == K_TIME ? "the independent variable" : "an output");
            return M_ERROR;
        }
        if (kind == K_PARAM && !stewart_allowed(STEWART_CALL_SET_PARAMETER, phase)) {
            model_log(c, M_ERROR, "setReal: parameter %s is fixed: it can only be set before exitInitializationMode "
                      "(now in %s)", vr_name(v, name), stewart_phase_name(phase));
            return M_ERROR;
        }
        if (kind == K_INPUT && !stewart_allowed(STEWART_CALL_SET_INPUT, phase)) {
            model_log(c, M_ERROR, "setReal: input %s cannot be set in %s", vr_name(v, name),
                      stewart_phase_name(phase));
            return M_ERROR;
        }
        if (!isfinite(value[j])) {
            model_log(c, M_ERROR, "setReal: %s = %g at t = %.17g s is not finite: rejected, the value stays %.17g",
                      vr_name(v, name), value[j], c->d.s.time,
                      kind == K_PARAM ? c->d.par[v] : (v < VR_TAU ? c->d.s.sigma[v - VR_SIGMA] : c->d.s.tau[v - VR_TAU]));
            return M_ERROR;
        }
        if (kind == K_INPUT) {
            int r = input_range(v);
            if (!(value[j] >= RANGES[r].min && value[j] <= RANGES[r].max)) {
                model_log(c, M_ERROR, "setReal: input %s = %g at t = %.17g s is outside its declared range [%g, %g]: "
                          "rejected, the value stays %.17g", vr_name(v, name), value[j], c->d.s.time, RANGES[r].min,
                          RANGES[r].max, v < VR_TAU ? c->d.s.sigma[v - VR_SIGMA] : c->d.s.tau[v - VR_TAU]);
                return M_ERROR;
            }
        }
    }
    FOR_EACH_VALUE(vr, nvr, k, e, j) {
        unsigned v = vr[k] + e;
        if (vr_kind(v) == K_PARAM) {
            c->d.par[v] = value[j];
            c->have_initial = 0;
        } else if (v < VR_TAU) {
            c->d.s.sigma[v - VR_SIGMA] = value[j];
        } else {
            c->d.s.tau[v - VR_TAU] = value[j];
        }
    }
    if (nvr) {
        c->have_parts = 0;
        c->have_initial = c->have_initial && !has_transmission();  /* the preload follows the inputs */
        update_rack(c);
    }
    return M_OK;
}

int model_get_string(Instance *c, const unsigned vr[], size_t n, const char *value[]) {
    size_t k;
    if (check_args(c, "getString", vr, n, value)) return M_ERROR;
    for (k = 0; k < n; k++) {
        if (vr[k] != VR_METHOD) return model_wrong_type(c, "getString", vr + k, 1);
        value[k] = stewart_method_name(c->d.method);
    }
    return M_OK;
}

int model_set_string(Instance *c, const unsigned vr[], size_t n, const char *const value[]) {
    size_t k;
    int j, method[64];
    if (check_args(c, "setString", vr, n, value)) return M_ERROR;
    if (n > 64) {
        model_log(c, M_ERROR, "setString: %lu values: this FMU has one String variable", (unsigned long)n);
        return M_ERROR;
    }
    for (k = 0; k < n; k++) {
        if (vr[k] != VR_METHOD) return model_wrong_type(c, "setString", vr + k, 1);
        if (model_require(c, "setString(solver.method)", STEWART_CALL_SET_PARAMETER))
            return M_ERROR;
        method[k] = -1;
        for (j = 0; j < STEWART_N_METHODS; j++)
            if (value[k] && strcmp(value[k], stewart_method_name(j)) == 0) method[k] = j;
        if (method[k] < 0) {
            model_log(c, M_ERROR, "setString: integrator '%.100s' unknown: solver.method is one of %s, %s, %s",
                      value[k] ? value[k] : "(null)", stewart_method_name(0), stewart_method_name(1),
                      stewart_method_name(2));
            return M_ERROR;
        }
    }
    for (k = 0; k < n; k++) c->d.method = method[k];
    return M_OK;
}

int model_wrong_type(Instance *c, const char *call, const unsigned vr[], size_t n) {
    char name[64];
    if (n == 0) return M_OK;
    if (!vr) return check_args(c, call, vr, n, NULL);
    if (declared_kind(vr[0]) == K_UNKNOWN)
        model_log(c, M_ERROR, "%s: unknown value reference %u", call, vr[0]);
    else
        model_log(c, M_ERROR, "%s: %s (value reference %u) is not of this type", call, vr_name(vr[0], name), vr[0]);
    return M_ERROR;
}

/* ---- FMU states ------------------------------------------------------------------------------- */

#define STATE_MAGIC 0x53545750u   /* "STWP" */
#define TAIL offsetof(PlantData, method)  /* the FMU's own data after the component's */

typedef struct {
    unsigned magic;
    PlantData d;
} State;

/* The serialized states' key: this FMU's instantiation token. */
static unsigned long long token_key(void) {
    return stewart_hash(STEWART_MODEL_TOKEN, strlen(STEWART_MODEL_TOKEN));
}

int model_get_state(Instance *c, void **state) {
    State *s = glue_state_block(c, "getFMUstate", state, STATE_MAGIC, sizeof *s);
    if (!s) return M_ERROR;
    s->d = c->d;
    return M_OK;
}

/* The inconsistency of a state's content, field by field, written to why ("" when it is usable).
 * A serialized state's checksum detects corruption, not forgery: a state edited with its
 * checksum recomputed reaches this check, so every field is checked before anything is applied:
 * the method, the tolerance, the inputs in their declared ranges (tau 0 without a drive), the
 * parameters finite (those the FMU does not declare at their start values), the component's
 * check (stewart_component_check: phase, state size, times, internal step, counters, finite
 * initial values, rack forces and state); for a running plant the parameters valid and packed
 * as they are, the initial values those of q0, qd0, and the pose inside the workspace: every
 * leg within the stroke widened by the stroke's length (an accepted step checks the stroke at
 * its stages, not at its end point) and the leg rates and angular velocity finite. The rack
 * forces' values are not compared: they are recomputed from the inputs when the state is
 * applied. */
static void inconsistency(Instance *c, const char *call, const PlantData *d, char why[256]) {
    const stewart_component *s = &d->s;
    int running = s->phase == STEWART_PH_STEPPING || s->phase == STEWART_PH_TERMINATED;
    int i, r;
    unsigned vr;
    char name[64];
    why[0] = '\0';
    if (!(d->method >= 0 && d->method < STEWART_N_METHODS)) {
        snprintf(why, 256, "solver.method %d is not a method", d->method);
        return;
    }
    if (!(d->tolerance_defined == 0 ? d->tolerance == 0.0
                                    : d->tolerance_defined == 1 && isfinite(d->tolerance) && d->tolerance > 0)) {
        snprintf(why, 256, "the tolerance %g (defined: %d) is not finite and > 0", d->tolerance, d->tolerance_defined);
        return;
    }
    for (i = 0; i < 12; i++) {
        double x = i < 6 ? s->sigma[i] : s->tau[i - 6];
        vr = (unsigned)(i < 6 ? VR_SIGMA + i : VR_TAU + i - 6);
        r = input_range(vr);
        if (!(x >= RANGES[r].min && x <= RANGES[r].max) || (i >= 6 && !has_drive() && x != 0.0)) {
            snprintf(why, 256, "input %s = %g lies outside its declared range [%g, %g]%s", vr_name(vr, name), x,
                     RANGES[r].min, RANGES[r].max, has_drive() ? "" : " (0: no drive)");
            return;
        }
    }
    for (vr = 1; vr < VR_N_PAR; vr++)
        if (has(vr) ? !isfinite(d->par[vr]) : d->par[vr] != STEWART_START[vr]) {
            snprintf(why, 256, "parameter %s = %g is %s", vr_name(vr, name), d->par[vr],
                     has(vr) ? "not finite" : "not declared: it keeps its start value");
            return;
        }
    if (stewart_component_check(s, running ? d->p : NULL) != STEWART_OK) {
        snprintf(why, 256, "%s: phase %d, %d states, time %g s from %g s, internal step %g s, %lld evaluations, "
                 "or a non-finite initial value, rack force or state", stewart_status_why(STEWART_STATE_INVALID),
                 s->phase, s->n, s->time, s->start_time, s->step_guess, s->evaluations);
        return;
    }
    if (running) {
        double p[STEWART_N_PARAMS], l[6], ld[6], om[3], margin;
        InstanceLogger log = c->log;
        c->log = NULL;
        i = validate(c, call, d->par, p) == M_OK && memcmp(p, d->p, sizeof p) == 0;
        c->log = log;
        if (!i) {
            snprintf(why, 256, "its parameters are not valid, or not packed as they are");
            return;
        }
        if (memcmp(s->initial, d->par + VR_Q0, 6 * sizeof(double)) || memcmp(s->initial + 6, d->par + VR_QD0, 6 * sizeof(double))) {
            snprintf(why, 256, "its initial values are not q0, qd0");
            return;
        }
        stewart_leg_state(d->p, s->y, s->y + 6, l, ld, om);
        margin = d->p[STEWART_P_LEG_MAX] - d->p[STEWART_P_LEG_MIN];   /* inf without a stroke */
        for (i = 0; i < 6; i++)
            if (!(l[i] > 0 && isfinite(l[i]) && isfinite(ld[i]) && l[i] >= d->p[STEWART_P_LEG_MIN] - margin &&
                  l[i] <= d->p[STEWART_P_LEG_MAX] + margin) || !(isfinite(om[i % 3]))) {
                snprintf(why, 256, "its pose puts leg %d at %g m (rate %g m/s), outside the workspace (stroke [%g, %g] m)",
                         i + 1, l[i], ld[i], d->p[STEWART_P_LEG_MIN], d->p[STEWART_P_LEG_MAX]);
                return;
            }
    }
}

/* A state's content is usable (inconsistency); M_ERROR, logged naming the field, if not. */
static int sane(Instance *c, const char *call, const PlantData *d) {
    char why[256];
    inconsistency(c, call, d, why);
    if (!why[0]) return M_OK;
    model_log(c, M_ERROR, "%s: not a valid state of this FMU: %s", call, why);
    return M_ERROR;
}

int model_set_state(Instance *c, const void *state) {
    const State *s = glue_state_of(c, "setFMUstate", state, STATE_MAGIC);
    if (!s) return M_ERROR;
    if (sane(c, "setFMUstate", &s->d)) return M_ERROR;
    stewart_component_load(&c->d.s, &s->d.s, s->d.p);  /* as Plant.set_state */
    memcpy((char *)&c->d + TAIL, (const char *)&s->d + TAIL, sizeof(PlantData) - TAIL);
    clear_outputs(c);
    update_rack(c);
    return M_OK;
}

int model_free_state(Instance *c, void **state) {
    (void)c;
    return glue_free_state(state);
}

size_t model_serialized_size(void) { return stewart_serialized_size(sizeof(PlantData) - TAIL); }

int model_serialize(Instance *c, const void *state, unsigned char *out, size_t size) {
    const State *s = glue_state_of(c, "serializeFMUstate", state, STATE_MAGIC);
    if (!s) return M_ERROR;
    if (!out) {
        model_log(c, M_ERROR, "serializeFMUstate: the buffer is NULL");
        return M_ERROR;
    }
    if (size < model_serialized_size()) {
        model_log(c, M_ERROR, "serializeFMUstate: buffer of %lu bytes, need %lu", (unsigned long)size,
                  (unsigned long)model_serialized_size());
        return M_ERROR;
    }
    stewart_serialize(&s->d.s, (const char *)&s->d + TAIL, sizeof(PlantData) - TAIL, token_key(), out, size);
    return M_OK;
}

int model_deserialize(Instance *c, const unsigned char *in, size_t size, void **state) {
    State *s;
    PlantData d;
    int status;
    if (!in || !state) {
        model_log(c, M_ERROR, "deserializeFMUstate: %s is NULL", !in ? "serializedState" : "FMUstate");
        return M_ERROR;
    }
    if (size != model_serialized_size()) {
        model_log(c, M_ERROR, "deserializeFMUstate: %lu bytes, a state of this FMU has %lu", (unsigned long)size,
                  (unsigned long)model_serialized_size());
        return M_ERROR;
    }
    memset(&d, 0, sizeof d);
    status = stewart_deserialize(in, size, token_key(), &d.s, (char *)&d + TAIL, sizeof(PlantData) - TAIL);
    if (status != STEWART_OK) {
        model_log(c, M_ERROR, "deserializeFMUstate: not a serialized state of this FMU: %s", stewart_status_why(status));
        return M_ERROR;
    }
    if (sane(c, "deserializeFMUstate", &d)) return M_ERROR;
    s = glue_state_block(c, "deserializeFMUstate", state, STATE_MAGIC, sizeof *s);
    if (!s) return M_ERROR;
    s->d = d;
    return M_OK;
}
