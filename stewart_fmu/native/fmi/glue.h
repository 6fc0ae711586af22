/* glue.h -- what every FMU of this project shares between its model and the FMI 2.0 / 3.0
 * layers (fmi2Functions.c, fmi3Functions.c): status words, log categories, the importer glue
 * of an Instance, and the calls glue.c implements once for all of them (logging,
 * setDebugLogging, the call-sequence check, instantiate's checks, the FMU-state blocks), and
 * the model_* calls each model.c implements. A model.h (the plant's here, the controller's in
 * controller/native/fmi/) includes it after `typedef struct Instance Instance;`, puts
 * FMU_GLUE_FIELDS in its struct Instance and keeps the component (stewart_component, stewart.h)
 * at c->d.s; glue.c, compiled beside that model.h, reads those names. */
#ifndef STEWART_FMI_GLUE_H
#define STEWART_FMI_GLUE_H

#include <stddef.h>

typedef enum { LOG_EVENTS = 1, LOG_WARNING = 2, LOG_DISCARD = 4, LOG_ERROR = 8, LOG_FATAL = 16,
               LOG_ALL = 31 } LogCategory;

enum { M_OK = 0, M_WARNING = 1, M_DISCARD = 2, M_ERROR = 3, M_FATAL = 4 };

typedef void (*InstanceLogger)(Instance *c, int status, const char *category, const char *message);

/* The importer's glue, the same fields in every Instance. */
#define FMU_GLUE_FIELDS                                                                          \
    char *name;                                                                                  \
    int log_on;                 /* loggingOn */                                                  \
    unsigned log_mask;          /* categories enabled by setDebugLogging */                      \
    InstanceLogger log;                                                                          \
    void *env;                  /* the importer's environment pointer */                         \
    void *callback;             /* the importer's logger (FMI 2.0 or 3.0) */

void model_log(Instance *c, int status, const char *fmt, ...)
#if defined(__GNUC__) || defined(__clang__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
int model_require(Instance *c, const char *call, int rule); /* stewart_call rule: M_OK/M_ERROR */
int model_set_debug_logging(Instance *c, int on, size_t n, const char *const categories[]);
/* instantiate's checks: `token` is this FMU's (`expected`), and the instance keeps a copy of
 * `name`; M_OK, or M_ERROR (logged) for another FMU's token or no memory. */
int glue_instantiate(Instance *c, const char *name, const char *token, const char *expected);

/* FMU states (get/set/free FMUstate, deserialize): a heap block of `size` bytes whose first
 * member is an `unsigned` magic naming the FMU, so that a state of another FMU is refused.
 * glue_state_block: the block to fill for `call`, *state itself when it is this FMU's (an
 * importer may pass one back to be overwritten) or a new zeroed block, stored in *state; NULL
 * (logged) for a NULL FMUstate, a foreign *state or no memory. glue_state_of: `state` when it
 * is this FMU's, else NULL (logged). glue_free_state: frees and clears *state (NULL is fine). */
void *glue_state_block(Instance *c, const char *call, void **state, unsigned magic, size_t size);
const void *glue_state_of(Instance *c, const char *call, const void *state, unsigned magic);
int glue_free_state(void **state);

/* What each model.c implements for the FMI 2.0 / 3.0 layers (fmi2Functions.c, fmi3Functions.c).
 * Status: M_OK .. M_FATAL. get/set_real take nvr value references and nvalues values: an FMI
 * 3.0 array's elements follow one another in row-major order; for FMI 2.0 nvalues = nvr; a
 * mismatch is M_ERROR, logged, nothing touched. */
int model_init(Instance *c, const char *name, const char *token);  /* after zeroing; M_OK/M_ERROR */
void model_reset(Instance *c);
int model_setup(Instance *c, int tolerance_defined, double tolerance, double start_time);
int model_enter_init(Instance *c);
int model_exit_init(Instance *c);
int model_terminate(Instance *c);
int model_do_step(Instance *c, double t, double h, double *last_time);
int model_get_real(Instance *c, const unsigned vr[], size_t nvr, double value[], size_t nvalues);
int model_set_real(Instance *c, const unsigned vr[], size_t nvr, const double value[], size_t nvalues);
int model_get_string(Instance *c, const unsigned vr[], size_t n, const char *value[]);
int model_set_string(Instance *c, const unsigned vr[], size_t n, const char *const value[]);
int model_wrong_type(Instance *c, const char *call, const unsigned vr[], size_t n);
int model_get_state(Instance *c, void **state);
int model_set_state(Instance *c, const void *state);
int model_free_state(Instance *c, void **state);
size_t model_serialized_size(void);
int model_serialize(Instance *c, const void *state, unsigned char *out, size_t size);
int model_deserialize(Instance *c, const unsigned char *in, size_t size, void **state);

#endif
