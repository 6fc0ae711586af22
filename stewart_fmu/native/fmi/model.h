/* The Stewart-platform plant as an FMU: value references, the instance, and the calls the
 * shared FMI 2.0 / 3.0 layers (fmi2Functions.c, fmi3Functions.c) make on it (model.c).
 *
 * Names, value references, units and descriptions are the table of ../include/stewart_table.h
 * (stewart_fmu/fmu/variables.py reads the same table from the core). A scene declares a subset: parameters of
 * absent tables, tau without a [drive] and force parts of absent effects are unknown value
 * references of that FMU. The generated scene file (written by stewart_fmu.fmu.variables.scene_c_source) holds the
 * start values, how many values each declared value reference holds (1 for each FMI 2.0 scalar;
 * an FMI 3.0 array's count at its first value reference, its elements stored at the following
 * ones, which it does not declare), and the instantiation token. */
#ifndef STEWART_FMI_MODEL_H
#define STEWART_FMI_MODEL_H

#include <stddef.h>

#include "../include/stewart.h"

/* ---- value references: the FMU variable groups of stewart_table.h -------------------------- */
/* VR_<ID>: the first value reference of each group. Parameters (Real, fixed) are par[vr] of the
 * instance, vr in [1, VR_N_PAR); VR_METHOD the String parameter; then inputs, then outputs (the
 * FMI 3.0 arrays q, qd last) up to VR_END. */
#define VR_PARAMETER(ID, ...) VR_##ID = STEWART_VR(PARAMETERS, stewart_fmu_parameters, ID),
#define VR_INPUT(ID, ...) VR_##ID = STEWART_VR(INPUTS, stewart_fmu_inputs, ID),
#define VR_OUTPUT(ID, ...) VR_##ID = STEWART_VR(OUTPUTS, stewart_fmu_outputs, ID),
enum {
    STEWART_FMU_SCENE(VR_PARAMETER) STEWART_FMU_SETTINGS(VR_PARAMETER)
    STEWART_FMU_INPUTS(VR_INPUT) STEWART_FMU_OUTPUTS(VR_OUTPUT) STEWART_FMU_OUTPUT_ARRAYS(VR_OUTPUT)
    VR_TIME = STEWART_VR_TIME, VR_N_PAR = STEWART_VR_N_PARAMETERS, VR_METHOD = STEWART_VR_METHOD,
    VR_END = STEWART_VR_N_OUTPUTS
};

/* ---- the generated scene file ---------------------------------------------------------------- */
extern const char STEWART_MODEL_TOKEN[];            /* guid / instantiationToken */
extern const double STEWART_START[VR_N_PAR];        /* start values of the parameters */
extern const double STEWART_START_SIGMA[6];         /* start of sigma: the force holding home */
extern const unsigned char STEWART_VALUES[VR_END];  /* values a declared value reference holds; 0: none */
extern const int STEWART_START_METHOD;              /* stewart_method */

/* ---- the instance ------------------------------------------------------------------------------ */
/* Everything a rollback restores: plain data (no pointers), copied as is into FMU states and
 * serialized in the component's format (stewart_serialize: s, then the rest as its extra). */
typedef struct {
    stewart_component s;        /* life cycle, inputs, state: the component (stewart.h) */
    int method;                 /* stewart_method */
    int tolerance_defined;
    double tolerance;
    double par[VR_N_PAR];       /* parameter values by value reference */
    double p[STEWART_N_PARAMS]; /* packed parameters (valid from exitInitializationMode) */
} PlantData;

typedef struct Instance Instance;
#include "glue.h"   /* status words, log categories, FMU_GLUE_FIELDS, model_log & co. */

struct Instance {
    PlantData d;
    /* outputs computed on demand (not part of the state; cleared whenever y or inputs change) */
    int have_legs, have_cond, have_parts, have_initial;
    int discarded;              /* the last doStep was discarded (FMI 2.0 fmi2Terminated status) */
    double l[6], ldot[6], omega[3], cond, parts[36];
    double lp[STEWART_N_PARAMS]; /* packed parameters for outputs before initialization ends */
    /* importer glue */
    FMU_GLUE_FIELDS
    const char *method_text;    /* for getString */
};

/* The model_* calls the FMI layers make are declared once, in glue.h. The plant's FMU states
 * are heap copies of PlantData, serialized by the component (stewart_serialize). */

#endif
