/* glue.c -- logging, setDebugLogging, the call-sequence check and the FMU-state blocks of an
 * FMU's Instance (glue.h), written once for the plant's FMU and the controller's: compiled
 * beside the model.h of the FMU it goes into, which defines Instance. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

static const char *const CATEGORY[] = {"logEvents", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};

void model_log(Instance *c, int status, const char *fmt, ...) {
    char msg[2048];
    va_list ap;
    int cat;
    if (!c || !c->log) return;
    cat = status <= M_OK ? 0 : (status > M_FATAL ? 4 : status);
    /* Events only when the importer asked for them; warnings and errors always. */
    if (cat == 0 && !(c->log_on && (c->log_mask & LOG_EVENTS))) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    c->log(c, status, CATEGORY[cat], msg);
}

int model_set_debug_logging(Instance *c, int on, size_t n, const char *const categories[]) {
    size_t k;
    unsigned mask = 0;
    if (n > 0 && !categories) {
        model_log(c, M_ERROR, "setDebugLogging: categories is NULL with nCategories = %lu", (unsigned long)n);
        return M_ERROR;
    }
    for (k = 0; k < n; k++) {
        int j, found = 0;
        for (j = 0; j < 5; j++)
            if (categories[k] && strcmp(categories[k], CATEGORY[j]) == 0) {
                mask |= 1u << j;
                found = 1;
            }
        if (!found) {
            model_log(c, M_ERROR, "setDebugLogging: unknown log category '%s'",
                      categories[k] ? categories[k] : "(null)");
            return M_ERROR;
        }
    }
    c->log_on = on != 0;
    c->log_mask = n == 0 ? LOG_ALL : mask;
    return M_OK;
}

int model_require(Instance *c, const char *call, int rule) {
    char msg[256];
    if (stewart_allowed(rule, c->d.s.phase)) return M_OK;
    stewart_call_refusal(msg, sizeof msg, call, rule, c->d.s.phase);
    model_log(c, M_ERROR, "%s", msg);
    return M_ERROR;
}

void *glue_state_block(Instance *c, const char *call, void **state, unsigned magic, size_t size) {
    unsigned *block;
    if (!state) {
        model_log(c, M_ERROR, "%s: FMUstate is NULL", call);
        return NULL;
    }
    block = *state ? (unsigned *)*state : calloc(1, size);
    if (!block) {
        model_log(c, M_ERROR, "%s: out of memory", call);
        return NULL;
    }
    if (*block && *block != magic) {
        model_log(c, M_ERROR, "%s: *FMUstate is not NULL and not a state of this FMU", call);
        return NULL;
    }
    *block = magic;
    *state = block;
    return block;
}

const void *glue_state_of(Instance *c, const char *call, const void *state, unsigned magic) {
    if (state && *(const unsigned *)state == magic) return state;
    model_log(c, M_ERROR, "%s: not a state of this FMU%s", call, state ? "" : " (NULL)");
    return NULL;
}

int glue_free_state(void **state) {
    if (!state || !*state) return M_OK;
    *(unsigned *)*state = 0;
    free(*state);
    *state = NULL;
    return M_OK;
}

int glue_instantiate(Instance *c, const char *name, const char *token, const char *expected) {
    if (!token || strcmp(token, expected) != 0) {
        model_log(c, M_ERROR, "instantiate: the token '%s' is not this FMU's '%s'",
                  token ? token : "(null)", expected);
        return M_ERROR;
    }
    c->name = malloc(strlen(name) + 1);
    if (!c->name) return M_ERROR;
    strcpy(c->name, name);
    return M_OK;
}
