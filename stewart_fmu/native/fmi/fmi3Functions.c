/* FMI 3.0 co-simulation API over the plant (model.h). Co-Simulation without event mode,
 * intermediate updates or early return; the Model Exchange and Scheduled Execution entry points
 * exist (the standard's binary exports them all) and refuse. State machine of FMI 3.0, section
 * 4.2.1, as the Reference FMUs apply it: a call in the wrong state, with a NULL instance or bad
 * arguments returns fmi3Error and logs why. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_api.h"
#include "model.h"

#define INSTANCE_MAGIC 0x46334d55u /* "F3MU" */
/* Each call names its rule of the component's one table (native/src/component.c, RULES). */
#define ANY STEWART_CALL_ANY
#define GETTABLE STEWART_CALL_GET

typedef struct {
    unsigned magic;
    Instance inst;
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment env;
} Fmi3Instance;

/* FMI 3.0: the message is plain text (not a format), passed as is. */
static void fmi3_log(Instance *c, int status, const char *category, const char *message) {
    Fmi3Instance *f = (Fmi3Instance *)((char *)c - offsetof(Fmi3Instance, inst));
    if (f->logger) f->logger(f->env, (fmi3Status)status, category, message);
}

static Instance *get(fmi3Instance c, const char *call, int rule) {
    Fmi3Instance *f = (Fmi3Instance *)c;
    if (!f || f->magic != INSTANCE_MAGIC) return NULL;
    if (model_require(&f->inst, call, rule)) return NULL;
    return &f->inst;
}

#define GET(CALL, RULE)                            \
    Instance *inst = get(instance, CALL, RULE);    \
    if (!inst) return fmi3Error

static fmi3Status refuse(fmi3Instance instance, const char *call, const char *why) {
    GET(call, ANY);
    model_log(inst, M_ERROR, "%s: %s", call, why);
    return fmi3Error;
}

#define NOT_CS(CALL) return refuse(instance, CALL, "not available in Co-Simulation without event mode")

/* The String variable is a scalar: one value per value reference (the Float64 arrays are
 * counted by model_get_real / model_set_real). */
static int count_ok(Instance *inst, const char *call, size_t nvr, size_t nvalues) {
    if (nvr == nvalues) return 1;
    model_log(inst, M_ERROR, "%s: %lu values for %lu scalar variables", call, (unsigned long)nvalues,
              (unsigned long)nvr);
    return 0;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    GET("fmi3SetDebugLogging", ANY);
    return (fmi3Status)model_set_debug_logging(inst, loggingOn, nCategories, categories);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Fmi3Instance *f;
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->magic = INSTANCE_MAGIC;
    f->logger = logMessage;
    f->env = instanceEnvironment;
    f->inst.log = fmi3_log;
    f->inst.log_on = loggingOn;
    f->inst.log_mask = LOG_ALL;
    if (eventModeUsed || nRequiredIntermediateVariables > 0) {
        model_log(&f->inst, M_ERROR, "fmi3InstantiateCoSimulation: %s",
                  eventModeUsed ? "event mode is not supported (hasEventMode = false)"
                                : "no intermediate variables (providesIntermediateUpdate = false)");
        free(f);
        return NULL;
    }
    if (model_init(&f->inst, instanceName ? instanceName : "", instantiationToken) != M_OK) {
        free(f);
        return NULL;
    }
    return f;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU supports Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Fmi3Instance *f = (Fmi3Instance *)instance;
    if (!f || f->magic != INSTANCE_MAGIC) return;
    f->magic = 0;
    free(f->inst.name);
    free(f);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    GET("fmi3EnterInitializationMode", STEWART_CALL_ENTER_INIT);
    (void)stopTimeDefined, (void)stopTime;
    if (model_setup(inst, toleranceDefined, tolerance, startTime)) return fmi3Error;
    return (fmi3Status)model_enter_init(inst);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    GET("fmi3ExitInitializationMode", STEWART_CALL_EXIT_INIT);
    return (fmi3Status)model_exit_init(inst);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { NOT_CS("fmi3EnterEventMode"); }

fmi3Status fmi3Terminate(fmi3Instance instance) {
    GET("fmi3Terminate", STEWART_CALL_TERMINATE);
    return (fmi3Status)model_terminate(inst);
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    GET("fmi3Reset", ANY);
    model_reset(inst);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    GET("fmi3GetFloat64", GETTABLE);
    return (fmi3Status)model_get_real(inst, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    GET("fmi3SetFloat64", ANY);
    return (fmi3Status)model_set_real(inst, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         fmi3String values[], size_t nValues) {
    GET("fmi3GetString", GETTABLE);
    if (!count_ok(inst, "fmi3GetString", nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)model_get_string(inst, valueReferences, nValueReferences, values);
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const fmi3String values[], size_t nValues) {
    GET("fmi3SetString", ANY);
    if (!count_ok(inst, "fmi3SetString", nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)model_set_string(inst, valueReferences, nValueReferences, values);
}

/* Types this FMU has no variables of: any value reference is of the wrong type. */
#define WRONG_TYPE(T, N)                                                                                  \
    fmi3Status fmi3Get##N(fmi3Instance instance, const fmi3ValueReference valueReferences[],              \
                          size_t nValueReferences, T values[], size_t nValues) {                          \
        GET("fmi3Get" #N, GETTABLE);                                                                           \
        (void)values, (void)nValues;                                                                      \
        return (fmi3Status)model_wrong_type(inst, "fmi3Get" #N, valueReferences, nValueReferences);       \
    }                                                                                                     \
    fmi3Status fmi3Set##N(fmi3Instance instance, const fmi3ValueReference valueReferences[],              \
                          size_t nValueReferences, const T values[], size_t nValues) {                    \
        GET("fmi3Set" #N, ANY);                                                                           \
        (void)values, (void)nValues;                                                                      \
        return (fmi3Status)model_wrong_type(inst, "fmi3Set" #N, valueReferences, nValueReferences);       \
    }

WRONG_TYPE(fmi3Float32, Float32)
WRONG_TYPE(fmi3Int8, Int8)
WRONG_TYPE(fmi3UInt8, UInt8)
WRONG_TYPE(fmi3Int16, Int16)
WRONG_TYPE(fmi3UInt16, UInt16)
WRONG_TYPE(fmi3Int32, Int32)
WRONG_TYPE(fmi3UInt32, UInt32)
WRONG_TYPE(fmi3Int64, Int64)
WRONG_TYPE(fmi3UInt64, UInt64)
WRONG_TYPE(fmi3Boolean, Boolean)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    GET("fmi3GetBinary", GETTABLE);
    (void)valueSizes, (void)values, (void)nValues;
    return (fmi3Status)model_wrong_type(inst, "fmi3GetBinary", valueReferences, nValueReferences);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    GET("fmi3SetBinary", ANY);
    (void)valueSizes, (void)values, (void)nValues;
    return (fmi3Status)model_wrong_type(inst, "fmi3SetBinary", valueReferences, nValueReferences);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    GET("fmi3GetClock", GETTABLE);
    (void)values;
    return (fmi3Status)model_wrong_type(inst, "fmi3GetClock", valueReferences, nValueReferences);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    GET("fmi3SetClock", ANY);
    (void)values;
    return (fmi3Status)model_wrong_type(inst, "fmi3SetClock", valueReferences, nValueReferences);
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference, (void)nDependencies;
    return refuse(instance, "fmi3GetNumberOfVariableDependencies", "dependencies are given in the model description");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    return refuse(instance, "fmi3GetVariableDependencies", "dependencies are given in the model description");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    GET("fmi3GetFMUState", ANY);
    return (fmi3Status)model_get_state(inst, FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    GET("fmi3SetFMUState", ANY);
    return (fmi3Status)model_set_state(inst, FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    GET("fmi3FreeFMUState", ANY);
    return (fmi3Status)model_free_state(inst, FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    GET("fmi3SerializedFMUStateSize", ANY);
    (void)FMUState;
    if (!size) {
        model_log(inst, M_ERROR, "fmi3SerializedFMUStateSize: size is NULL");
        return fmi3Error;
    }
    *size = model_serialized_size();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    GET("fmi3SerializeFMUState", ANY);
    return (fmi3Status)model_serialize(inst, FMUState, serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    GET("fmi3DeserializeFMUState", ANY);
    return (fmi3Status)model_deserialize(inst, serializedState, size, FMUState);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetDirectionalDerivative", "not provided (providesDirectionalDerivatives = false)");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives = false)");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return refuse(instance, "fmi3EnterConfigurationMode", "this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return refuse(instance, "fmi3ExitConfigurationMode", "this FMU has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalDecimal", "this FMU has no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions, (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalFraction", "this FMU has no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return refuse(instance, "fmi3GetShiftDecimal", "this FMU has no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refuse(instance, "fmi3GetShiftFraction", "this FMU has no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences, (void)nValueReferences, (void)intervals;
    return refuse(instance, "fmi3SetIntervalDecimal", "this FMU has no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refuse(instance, "fmi3SetIntervalFraction", "this FMU has no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return refuse(instance, "fmi3SetShiftDecimal", "this FMU has no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refuse(instance, "fmi3SetShiftFraction", "this FMU has no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { NOT_CS("fmi3EvaluateDiscreteStates"); }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate, (void)terminateSimulation, (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged, (void)nextEventTimeDefined, (void)nextEventTime;
    NOT_CS("fmi3UpdateDiscreteStates");
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { NOT_CS("fmi3EnterContinuousTimeMode"); }

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    NOT_CS("fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    NOT_CS("fmi3SetTime");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    NOT_CS("fmi3SetContinuousStates");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    NOT_CS("fmi3GetContinuousStateDerivatives");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    NOT_CS("fmi3GetEventIndicators");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    NOT_CS("fmi3GetContinuousStates");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    NOT_CS("fmi3GetNominalsOfContinuousStates");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    NOT_CS("fmi3GetNumberOfEventIndicators");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    NOT_CS("fmi3GetNumberOfContinuousStates");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) { NOT_CS("fmi3EnterStepMode"); }

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues;
    return refuse(instance, "fmi3GetOutputDerivatives", "not provided (maxOutputDerivativeOrder = 0)");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Fmi3Instance *f = (Fmi3Instance *)instance;
    double last = 0.0;
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!f || f->magic != INSTANCE_MAGIC) return fmi3Error;
    status = model_do_step(&f->inst, currentCommunicationPoint, communicationStepSize, &last);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = last;
    return (fmi3Status)status;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    return refuse(instance, "fmi3ActivateModelPartition", "this FMU supports Co-Simulation only");
}
