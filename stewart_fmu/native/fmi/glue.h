/* glue.h -- what every FMU of this project shares between its model and the FMI 2.0 / 3.0
 * layers (fmi2Functions.c, fmi3Functions.c): status words, log categories, the importer glue
 * of an Instance, and the three calls glue.c implements once for all of them (logging,
 * setDebugLogging, the call-sequence check). A model.h (the plant's here, the controller's in
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

#endif
