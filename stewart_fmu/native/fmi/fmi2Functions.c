/* FMI 2.0 co-simulation API over the plant (model.h). The call-sequence rules are those of the
 * FMI 2.0.4 state machine (section 4.2.4), as the Reference FMUs apply them: a call in the
 * wrong state, with a NULL instance or with bad arguments returns fmi2Error and logs why. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_api.h"
#include "model.h"

#define INSTANCE_MAGIC 0x46324d55u /* "F2MU" */
/* Each call names its rule of the component's one table (native/src/component.c, RULES). */
#define ANY STEWART_CALL_ANY
#define GETTABLE STEWART_CALL_GET

typedef struct {
    unsigned magic;
    Instance inst;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
} Fmi2Instance;

/* FMI 2.0 (2.1.5): the logger's message is a printf format: a literal '%' is written '%%'. */
static void fmi2_log(Instance *c, int status, const char *category, const char *message) {
    Fmi2Instance *f = (Fmi2Instance *)((char *)c - offsetof(Fmi2Instance, inst));
    char escaped[4200];
    size_t i, j = 0;
    if (!f->logger) return;
    for (i = 0; message[i] && j + 3 < sizeof escaped; i++) {
        if (message[i] == '%') escaped[j++] = '%';
        escaped[j++] = message[i];
    }
    escaped[j] = '\0';
    f->logger(f->env, c->name ? c->name : "", (fmi2Status)status, category, escaped);
}

static Instance *get(fmi2Component c, const char *call, int rule) {
    Fmi2Instance *f = (Fmi2Instance *)c;
    if (!f || f->magic != INSTANCE_MAGIC) return NULL;
    if (model_require(&f->inst, call, rule)) return NULL;
    return &f->inst;
}

#define GET(CALL, RULE)                            \
    Instance *inst = get(c, CALL, RULE);           \
    if (!inst) return fmi2Error

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    GET("fmi2SetDebugLogging", ANY);
    return (fmi2Status)model_set_debug_logging(inst, loggingOn, nCategories, categories);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Fmi2Instance *f;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) return NULL;
    f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->magic = INSTANCE_MAGIC;
    f->logger = functions->logger;
    f->env = functions->componentEnvironment;
    f->inst.log = fmi2_log;
    f->inst.log_on = loggingOn != 0;
    f->inst.log_mask = LOG_ALL;
    f->inst.name = NULL;
    if (!instanceName) instanceName = "";
    if (fmuType != fmi2CoSimulation) {
        model_log(&f->inst, M_ERROR, "fmi2Instantiate: this FMU supports Co-Simulation only");
        free(f);
        return NULL;
    }
    if (model_init(&f->inst, instanceName, fmuGUID) != M_OK) {
        free(f);
        return NULL;
    }
    return f;
}

void fmi2FreeInstance(fmi2Component c) {
    Fmi2Instance *f = (Fmi2Instance *)c;
    if (!f || f->magic != INSTANCE_MAGIC) return;
    f->magic = 0;
    free(f->inst.name);
    free(f);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    GET("fmi2SetupExperiment", STEWART_CALL_SETUP);
    (void)stopTimeDefined;
    (void)stopTime;
    return (fmi2Status)model_setup(inst, toleranceDefined, tolerance, startTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    GET("fmi2EnterInitializationMode", STEWART_CALL_ENTER_INIT);
    return (fmi2Status)model_enter_init(inst);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    GET("fmi2ExitInitializationMode", STEWART_CALL_EXIT_INIT);
    return (fmi2Status)model_exit_init(inst);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    GET("fmi2Terminate", STEWART_CALL_TERMINATE);
    return (fmi2Status)model_terminate(inst);
}

fmi2Status fmi2Reset(fmi2Component c) {
    GET("fmi2Reset", ANY);
    model_reset(inst);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    GET("fmi2GetReal", GETTABLE);
    return (fmi2Status)model_get_real(inst, vr, nvr, value, nvr);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    GET("fmi2SetReal", ANY);
    return (fmi2Status)model_set_real(inst, vr, nvr, value, nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    GET("fmi2GetString", GETTABLE);
    return (fmi2Status)model_get_string(inst, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    GET("fmi2SetString", ANY);
    return (fmi2Status)model_set_string(inst, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    GET("fmi2GetInteger", GETTABLE);
    (void)value;
    return (fmi2Status)model_wrong_type(inst, "fmi2GetInteger", vr, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    GET("fmi2SetInteger", ANY);
    (void)value;
    return (fmi2Status)model_wrong_type(inst, "fmi2SetInteger", vr, nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    GET("fmi2GetBoolean", GETTABLE);
    (void)value;
    return (fmi2Status)model_wrong_type(inst, "fmi2GetBoolean", vr, nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    GET("fmi2SetBoolean", ANY);
    (void)value;
    return (fmi2Status)model_wrong_type(inst, "fmi2SetBoolean", vr, nvr);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    GET("fmi2GetFMUstate", ANY);
    return (fmi2Status)model_get_state(inst, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    GET("fmi2SetFMUstate", ANY);
    return (fmi2Status)model_set_state(inst, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    GET("fmi2FreeFMUstate", ANY);
    return (fmi2Status)model_free_state(inst, FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    GET("fmi2SerializedFMUstateSize", ANY);
    (void)FMUstate;
    if (!size) {
        model_log(inst, M_ERROR, "fmi2SerializedFMUstateSize: size is NULL");
        return fmi2Error;
    }
    *size = model_serialized_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    GET("fmi2SerializeFMUstate", ANY);
    return (fmi2Status)model_serialize(inst, FMUstate, (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    GET("fmi2DeSerializeFMUstate", ANY);
    return (fmi2Status)model_deserialize(inst, (const unsigned char *)serializedState, size, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    GET("fmi2GetDirectionalDerivative", ANY);
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    model_log(inst, M_ERROR, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative = false)");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    GET("fmi2SetRealInputDerivatives", ANY);
    (void)vr, (void)nvr, (void)order, (void)value;
    model_log(inst, M_ERROR, "fmi2SetRealInputDerivatives: inputs are held over a step (canInterpolateInputs = false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    GET("fmi2GetRealOutputDerivatives", ANY);
    (void)vr, (void)nvr, (void)order, (void)value;
    model_log(inst, M_ERROR, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Fmi2Instance *f = (Fmi2Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!f || f->magic != INSTANCE_MAGIC) return fmi2Error;
    return (fmi2Status)model_do_step(&f->inst, currentCommunicationPoint, communicationStepSize, NULL);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    GET("fmi2CancelStep", ANY);
    model_log(inst, M_ERROR, "fmi2CancelStep: doStep always completes synchronously");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    GET("fmi2GetStatus", STEWART_CALL_STATUS);
    (void)value;
    model_log(inst, M_ERROR, "fmi2GetStatus: status kind %d not provided (doStep is synchronous)", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    GET("fmi2GetRealStatus", STEWART_CALL_STATUS);
    if (s != fmi2LastSuccessfulTime || !value) {
        model_log(inst, M_ERROR, "fmi2GetRealStatus: only fmi2LastSuccessfulTime, with a value pointer");
        return fmi2Error;
    }
    *value = inst->d.s.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    GET("fmi2GetIntegerStatus", STEWART_CALL_STATUS);
    (void)value;
    model_log(inst, M_ERROR, "fmi2GetIntegerStatus: status kind %d not provided", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    GET("fmi2GetBooleanStatus", STEWART_CALL_STATUS);
    if (s != fmi2Terminated || !value) {
        model_log(inst, M_ERROR, "fmi2GetBooleanStatus: only fmi2Terminated, with a value pointer");
        return fmi2Error;
    }
    /* After a discarded step: true. The state is intact and a master
     * that rolls back may carry on, but a master that retries the same step (fmpy's
     * simulate_fmu) would otherwise loop forever; it ends at the last successful time. */
    *value = inst->discarded ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    GET("fmi2GetStringStatus", STEWART_CALL_STATUS);
    (void)value;
    model_log(inst, M_ERROR, "fmi2GetStringStatus: status kind %d not provided", (int)s);
    return fmi2Error;
}
