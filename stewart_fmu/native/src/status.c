/* status.c -- what each status code means, and the one message of a refused step.
 *
 * The words are read by every layer: stewart_fmu/status.py builds its WHY table from
 * stewart_status_why, the FMU logs stewart_refusal, Plant raises it (plant.py). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

typedef struct {
    int status;
    const char *name, *why;
} status_words;

static const status_words WORDS[] = {
    {STEWART_OK, "OK", "no error"},
    {STEWART_NONFINITE, "NONFINITE", "the state became non-finite"},
    {STEWART_STROKE, "STROKE", "a leg left its stroke"},
    {STEWART_SINGULAR, "SINGULAR", "the Jacobian became singular"},
    {STEWART_GIMBAL, "GIMBAL", "the pitch reached +-90 degrees (Euler-rate singularity)"},
    {STEWART_OVERFLOW, "OVERFLOW", "the accelerations overflowed"},
    {STEWART_TOO_MANY_STEPS, "TOO_MANY_STEPS",
     "the integrator needed more than max_steps internal steps (stiff, or the communication "
     "step is too long)"},
    {STEWART_STEP_TOO_SMALL, "STEP_TOO_SMALL", "the integrator's step fell below its minimum (stiff)"},
    {STEWART_UNSTABLE, "UNSTABLE",
     "integration unstable: the energy grew more than the rack forces supplied"},
    {STEWART_STATE_NONFINITE, "STATE_NONFINITE", "integration unstable: the state became non-finite"},
    {STEWART_BAD_CALL, "BAD_CALL", "the call is not allowed in this phase"},
    {STEWART_BAD_STEP, "BAD_STEP", "must be finite and > 0"},
    {STEWART_BAD_TIME, "BAD_TIME", "is not the component's time"},
    {STEWART_BAD_STATE, "BAD_STATE", "wrong size, magic or version"},
    {STEWART_STATE_FOREIGN, "STATE_FOREIGN", "it belongs to a different model"},
    {STEWART_STATE_CORRUPT, "STATE_CORRUPT", "checksum mismatch: the state is corrupted"},
    {STEWART_STATE_INVALID, "STATE_INVALID", "its values are out of range or not finite"},
};

static const status_words *find(int status) {
    size_t k;
    for (k = 0; k < sizeof WORDS / sizeof WORDS[0]; k++)
        if (WORDS[k].status == status) return &WORDS[k];
    return NULL;
}

const char *stewart_status_name(int status) {
    const status_words *w = find(status);
    return w ? w->name : NULL;
}

const char *stewart_status_why(int status) {
    const status_words *w = find(status);
    return w ? w->why : NULL;
}

/* x as Python's repr writes a float: the fewest digits that read back as x, positional for
   exponents in [-4, 16) (with ".0" when integral), else d.ddde+XX. */
void stewart_format_double(char out[32], double x) {
    char tmp[40], digits[20];
    int p, e, nd = 0, k, pos = 0;
    const char *s;
    if (isnan(x)) { strcpy(out, "nan"); return; }
    if (isinf(x)) { strcpy(out, x > 0 ? "inf" : "-inf"); return; }
    for (p = 0; p < 17; p++) {
        snprintf(tmp, sizeof tmp, "%.*e", p, x);
        if (strtod(tmp, NULL) == x) break;
    }
    e = atoi(strchr(tmp, 'e') + 1);
    if (e < -4 || e >= 16) {
        size_t n = strlen(tmp);  /* at most 24 characters: -d.dddddddddddddddde+ddd */
        memcpy(out, tmp, n < 31 ? n + 1 : 31);
        out[31] = '\0';
        return;
    }
    for (s = tmp; *s != 'e'; s++)
        if (*s >= '0' && *s <= '9') digits[nd++] = *s;
    if (tmp[0] == '-') out[pos++] = '-';
    if (e < 0) {
        out[pos++] = '0';
        out[pos++] = '.';
        for (k = 0; k < -e - 1; k++) out[pos++] = '0';
        for (k = 0; k < nd; k++) out[pos++] = digits[k];
    } else {
        for (k = 0; k <= e; k++) out[pos++] = k < nd ? digits[k] : '0';
        out[pos++] = '.';
        if (nd <= e + 1) out[pos++] = '0';
        for (k = e + 1; k < nd; k++) out[pos++] = digits[k];
    }
    out[pos] = '\0';
}

/* "(a, b, c, d, e, f)" with %.6g, appended at *pos of buf. */
static void six(char *buf, size_t size, size_t *pos, const double v[6]) {
    int k;
    for (k = 0; k < 6 && *pos < size; k++) {
        int w = snprintf(buf + *pos, size - *pos, "%s%.6g%s", k ? ", " : "(", v[k], k == 5 ? ")" : "");
        if (w > 0) *pos += (size_t)w;
    }
}

static void append(char *buf, size_t size, size_t *pos, const char *text) {
    if (*pos < size) {
        int w = snprintf(buf + *pos, size - *pos, "%s", text);
        if (w > 0) *pos += (size_t)w;
    }
}

size_t stewart_refusal(char *buf, size_t size, const double *params, const char *method, double t,
                       double h, int status, const double *y, const double rack[6], double excess,
                       double allowed) {
    char ts[32], hs[32], extra[96] = "", stroke[96];
    const char *why = stewart_status_why(status);
    double l[6], ld[6], om[3];
    size_t pos = 0;
    int w;
    if (!buf || size == 0) return 0;
    stewart_format_double(ts, t);
    stewart_format_double(hs, h);
    if (status == STEWART_UNSTABLE)
        snprintf(extra, sizeof extra, " (by %.3g J, allowed %.3g J)", excess, allowed);
    w = snprintf(buf, size, "doStep from t = %s s by %s s discarded (%s): %s%s; state kept at the "
                 "start of the step: q = ", ts, hs, method, why ? why : "unknown status", extra);
    pos = w > 0 ? (size_t)w : 0;
    stewart_leg_state(params, y, y + 6, l, ld, om);
    six(buf, size, &pos, y);
    append(buf, size, &pos, ", qd = ");
    six(buf, size, &pos, y + 6);
    append(buf, size, &pos, ", leg lengths = ");
    six(buf, size, &pos, l);
    snprintf(stroke, sizeof stroke, " m (stroke [%g, %g] m), rack force = ", params[STEWART_P_LEG_MIN],
             params[STEWART_P_LEG_MAX]);
    append(buf, size, &pos, stroke);
    six(buf, size, &pos, rack);
    append(buf, size, &pos, " N");
    return pos < size ? pos : size - 1;
}
