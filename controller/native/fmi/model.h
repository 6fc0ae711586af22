/* The six axis controllers as an FMU: value references, the instance, and the calls the shared
 * FMI 2.0 / 3.0 layers make on it (the plant's stewart_fmu/native/fmi/fmi2Functions.c and
 * fmi3Functions.c, compiled beside this header in the FMU's sources/fmi/). The same calls and
 * Instance glue as the plant's model.h; the controller's step is axis.c's axis_step, the one
 * the closed loop (closed_loop_run) takes. Variables: axis_table.h. The generated start file
 * (controller/fmu.py, start_c_source) holds the start values and the instantiation token. */
#ifndef AXIS_FMI_MODEL_H
#define AXIS_FMI_MODEL_H

#include <stddef.h>

#include "stewart.h"  /* include directories: the core's include/ and axis.h's directory */
#include "axis.h"
#include "axis_table.h"

#define VR_PARAMETER(ID, ...) VR_##ID = AXIS_VR(PARAMETERS, axis_fmu_parameters, ID),
#define VR_INPUT(ID, ...) VR_##ID = AXIS_VR(INPUTS, axis_fmu_inputs, ID),
#define VR_OUTPUT(ID, ...) VR_##ID = AXIS_VR(OUTPUTS, axis_fmu_outputs, ID),
enum {
    AXIS_FMU_PARAMETERS(VR_PARAMETER) AXIS_FMU_INPUTS(VR_INPUT) AXIS_FMU_OUTPUTS(VR_OUTPUT)
    VR_TIME = 0,
    N_PAR = AXIS_N(axis_fmu_parameters), N_IN = AXIS_N(axis_fmu_inputs),
    N_OUT = AXIS_N(axis_fmu_outputs)
};

/* ---- the generated start file ---------------------------------------------------------------- */
extern const char AXIS_MODEL_TOKEN[];        /* guid / instantiationToken */
extern const double AXIS_START[N_PAR];       /* start values of the parameters */
extern const double AXIS_START_INPUTS[N_IN]; /* start values of the inputs */
/* The reference move the FMU carries (export-ssp; none for export-fmu --controller): AXIS_REF_N
   samples at the rate from startTime, each l_ref, ldot_ref, v_ff (18 values, row-major). */
extern const long AXIS_REF_N;
extern const double AXIS_REF[];

/* ---- the instance ------------------------------------------------------------------------------ */
/* Everything a rollback restores: plain data. s: the component's life cycle (phase, time) and
 * its call rules (native/src/component.c); the plant state in it is unused. */
typedef struct {
    stewart_component s;
    double par[N_PAR];          /* parameter values, by value reference - AXIS_VR_PARAMETERS */
    double in[N_IN];            /* held inputs, by value reference - AXIS_VR_INPUTS */
    double integral[6];         /* the PIDs' integrals */
    double current[6];          /* the motor currents */
    axis_loop loop;             /* the constants of axis_step (valid from exitInitializationMode) */
    double last[N_OUT];         /* the last period's sample (parameter delay = 1) */
} ControllerData;

typedef struct Instance Instance;
#include "glue.h"   /* status words, log categories, FMU_GLUE_FIELDS, model_log & co. */

struct Instance {
    ControllerData d;
    int have_out;               /* out holds the sample of the state and inputs (cleared on change) */
    int discarded;              /* the last doStep was discarded: its state would not have been finite */
    double out[N_OUT];
    FMU_GLUE_FIELDS
};

/* The model_* calls the FMI layers make are declared once, in glue.h. The controller's variables
 * are all scalars (nvalues must equal nvr); its FMU states are heap copies of ControllerData,
 * not serializable (canSerializeFMUstate false). */

#endif
