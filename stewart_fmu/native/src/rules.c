/* rules.c -- the rules between a scene's keys, written once: the scene reader
   (stewart_fmu/scene.py) and the FMU's validation (fmi/model.c) both call them on the packed
   parameters and a pose, and report the first broken rule with the key it names (the value
   reference of its FMU variable group, whose name is the scene key) and the reason. The
   per-key rules (finite, bounds, shapes) are the table's and are checked before these. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"

#define PARAM_VR(ID) STEWART_VR(PARAMETERS, stewart_fmu_parameters, ID)

/* "[a, b, c]" with each value as Python's repr writes it (the scene's messages were Python's). */
static void list(char *out, size_t size, const double *v, int n) {
    char num[32];
    size_t pos = 0;
    int k;
    for (k = 0; k < n && pos < size; k++) {
        int w;
        stewart_format_double(num, v[k]);
        w = snprintf(out + pos, size - pos, "%s%s%s", k ? ", " : "[", num, k == n - 1 ? "]" : "");
        if (w > 0) pos += (size_t)w;
    }
}

static int fail(stewart_rule_break *out, int rule, int vr, int element, const char *fmt, ...) {
    va_list ap;
    out->rule = rule;
    out->vr = vr;
    out->element = element;
    va_start(ap, fmt);
    vsnprintf(out->reason, sizeof out->reason, fmt, ap);
    va_end(ap);
    return rule;
}

static void clear(stewart_rule_break *out) {
    memset(out, 0, sizeof *out);
    out->element = -1;
}

/* The derived quantities of stewart_table.h, by ID: their names, units and bounds. */
#define DERIVED_ID(ID, ...) D_##ID,
enum { STEWART_DERIVED(DERIVED_ID) N_DERIVED };
#define DERIVED_ROW(ID, NAME, UNIT, BOUND, MIN, MAX) {NAME, UNIT, STEWART_BOUND_##BOUND, MIN, MAX},
static const struct { const char *name, *unit; int bound; double min, max; } DERIVED[] = {
    STEWART_DERIVED(DERIVED_ROW)};

/* A derived quantity's value checked finite and within its bounds: else STEWART_RULE_DERIVED
   naming the key vr and, in the reason, the quantity and the keys it comes from (`from`). */
static int derived(stewart_rule_break *out, int id, double value, int vr, const char *from) {
    char v[32];
    int low = DERIVED[id].bound == STEWART_BOUND_OPEN ? !(value > DERIVED[id].min) : !(value >= DERIVED[id].min);
    if (isfinite(value) && !low && value <= DERIVED[id].max) return STEWART_RULE_OK;
    stewart_format_double(v, value);
    return fail(out, STEWART_RULE_DERIVED, vr, -1, "gives %s = %s %s (%s): must be %s %g and <= %g %s",
                DERIVED[id].name, v, DERIVED[id].unit, from,
                DERIVED[id].bound == STEWART_BOUND_OPEN ? ">" : ">=", DERIVED[id].min, DERIVED[id].max,
                DERIVED[id].unit);
}

int stewart_check_drive(double zeta, double r, const double I[6], stewart_rule_break *out) {
    char from[256], a[32], b[32], c[32];
    int i;
    clear(out);
    stewart_format_double(a, zeta);
    stewart_format_double(b, r);
    snprintf(from, sizeof from, "drive.gear_ratio %s / drive.pinion_radius %s", a, b);
    if (derived(out, D_RACK_RATIO, zeta / r, PARAM_VR(GEAR_RATIO), from)) return out->rule;
    for (i = 0; i < 6; i++) {
        stewart_format_double(c, I[i]);
        snprintf(from, sizeof from, "leg %d: drive.gear_ratio %s, drive.rotor_inertia %s, drive.pinion_radius %s",
                 i + 1, a, c, b);
        if (derived(out, D_DRIVE_MASS, zeta * zeta * I[i] / (r * r), PARAM_VR(GEAR_RATIO), from)) return out->rule;
    }
    return STEWART_RULE_OK;
}

int stewart_check_params(const double *p, stewart_rule_break *out) {
    static const int joints[2] = {STEWART_P_BASE, STEWART_P_PLATFORM};
    static const int joint_vr[2] = {PARAM_VR(BASE), PARAM_VR(PLATFORM)};
    static const int part[2] = {STEWART_P_LOWER, STEWART_P_UPPER};
    static const int part_vr[2] = {PARAM_VR(LOWER_INERTIA), PARAM_VR(UPPER_INERTIA)};
    const double *I = p + STEWART_P_INERTIA;
    char a[96], b[32], c[32];
    int i, j, k;
    clear(out);
    for (k = 0; k < 2; k++) {  /* no two joints of a ring at one point (relative to its size) */
        const double *x = p + joints[k];
        double scale = 0.0;
        for (i = 0; i < 18; i++) scale = fmax(scale, fabs(x[i]));
        scale = fmax(scale, 1e-300);
        for (i = 0; i < 6; i++)
            for (j = i + 1; j < 6; j++) {
                const double *u = x + 3 * i, *w = x + 3 * j;
                double d = sqrt((u[0] - w[0]) * (u[0] - w[0]) + (u[1] - w[1]) * (u[1] - w[1]) +
                                (u[2] - w[2]) * (u[2] - w[2]));
                if (d <= 1e-9 * scale) {
                    list(a, sizeof a, u, 3);
                    return fail(out, STEWART_RULE_JOINTS, joint_vr[k], 3 * j,
                                "makes joints %d and %d coincide at %s", i + 1, j + 1, a);
                }
            }
    }
    if (p[STEWART_P_LEG_MIN] >= p[STEWART_P_LEG_MAX]) {  /* 0 and inf when a scene has none */
        stewart_format_double(b, p[STEWART_P_LEG_MAX]);
        stewart_format_double(c, p[STEWART_P_LEG_MIN]);
        return fail(out, STEWART_RULE_STROKE, PARAM_VR(LEG_MAX), -1, "must exceed leg_min (%s <= %s)", b, c);
    }
    list(a, sizeof a, I, 3);
    for (i = 0; i < 3; i++)
        if (!(I[i] > 0))
            return fail(out, STEWART_RULE_INERTIA_POSITIVE, PARAM_VR(INERTIA), i,
                        "is not positive definite: principal moments %s must be > 0", a);
    if (I[0] + I[1] < I[2] || I[1] + I[2] < I[0] || I[0] + I[2] < I[1])
        return fail(out, STEWART_RULE_INERTIA_TRIANGLE, PARAM_VR(INERTIA), -1,
                    "breaks the triangle inequality with moments %s: no rigid body has them", a);
    for (k = 0; k < 2; k++) {  /* [transverse, axial]: zeros without [legs] */
        double transverse = p[part[k] + 2], axial = p[part[k] + 3];
        if (axial > 2 * transverse) {
            stewart_format_double(b, axial);
            stewart_format_double(c, transverse);
            return fail(out, STEWART_RULE_LEG_INERTIA, part_vr[k], 1,
                        "has an axial moment %s that exceeds twice the transverse %s: no rigid body has it", b, c);
        }
    }
    stewart_format_double(a, p[STEWART_P_MASS]);
    stewart_format_double(b, p[STEWART_P_LOWER]);
    stewart_format_double(c, p[STEWART_P_UPPER]);
    {
        char from[256];
        snprintf(from, sizeof from, "platform.mass %s + 6 (legs.lower_mass %s + legs.upper_mass %s)", a, b, c);
        if (derived(out, D_MOVING_MASS, p[STEWART_P_MASS] + 6.0 * (p[STEWART_P_LOWER] + p[STEWART_P_UPPER]),
                    PARAM_VR(MASS), from))
            return out->rule;
    }
    return STEWART_RULE_OK;
}

int stewart_check_pose(const double *p, const double q[6], int vr, stewart_rule_break *out) {
    double l[6], ld[6], om[3], cond = 0.0, lo = p[STEWART_P_LEG_MIN], hi = p[STEWART_P_LEG_MAX];
    char legs[32] = "[", lengths[200], pose[200], slo[32], shi[32];
    size_t n = 1;
    int i, first = -1;
    clear(out);
    stewart_leg_state(p, q, SW_ZERO6, l, ld, om);
    for (i = 0; i < 6; i++)
        if (!(l[i] >= lo && l[i] <= hi) || !isfinite(l[i]) || l[i] == 0.0) {
            n += (size_t)snprintf(legs + n, sizeof legs - n, "%s%d", first < 0 ? "" : ", ", i + 1);
            if (first < 0) first = i;
        }
    list(pose, sizeof pose, q, 6);
    if (first >= 0) {
        snprintf(legs + n, sizeof legs - n, "]");
        list(lengths, sizeof lengths, l, 6);
        stewart_format_double(slo, lo);
        stewart_format_double(shi, hi);
        return fail(out, STEWART_RULE_POSE_STROKE, vr, -1,
                    "puts leg(s) %s outside the stroke [%s, %s] m: lengths %s m at pose %s", legs, slo,
                    shi, lengths, pose);
    }
    stewart_condition_number(p, q, &cond);
    if (!(cond < STEWART_COND_LIMIT))
        return fail(out, STEWART_RULE_POSE_SINGULAR, vr, -1,
                    "is near-singular: the Jacobian's cond = %.3g > %.0e at pose %s", cond,
                    STEWART_COND_LIMIT, pose);
    return STEWART_RULE_OK;
}

int stewart_check_rules(const double *p, const double home[6], stewart_rule_break *out) {
    int rule = stewart_check_params(p, out);
    return rule != STEWART_RULE_OK ? rule : stewart_check_pose(p, home, PARAM_VR(HOME), out);
}
