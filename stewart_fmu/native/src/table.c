/* table.c -- the tables of stewart_table.h compiled into the core, for the Python side
   (stewart_fmu/model.py reads the packed layout, stewart_fmu/standard.py the standard parameters, stewart_fmu/fmu/variables.py the FMU
   variables): one expansion of each X-macro table. */
#include <math.h>

#include "../include/stewart.h"

#define PARAM_ROW(NAME, COUNT, SOURCE, UNIT, WHAT) {#NAME, STEWART_P_##NAME, COUNT, #SOURCE, UNIT, WHAT},
const stewart_param_info stewart_param_table[] = {STEWART_PARAMS(PARAM_ROW)};
const int stewart_param_table_size = sizeof stewart_param_table / sizeof stewart_param_table[0];

#define STANDARD_ROW(NAME, COUNT, KEY, UNIT, WHAT) {#NAME, STEWART_S_##NAME, COUNT, KEY, UNIT, WHAT},
const stewart_standard_info stewart_standard_table[] = {STEWART_STANDARD(STANDARD_ROW)};
const int stewart_standard_table_size =
    sizeof stewart_standard_table / sizeof stewart_standard_table[0];

#define ELASTIC_ROW(NAME, KEY, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, WHAT)                       \
    {#NAME, KEY, 0, STEWART_E_##NAME, COUNT, SHAPE, STEWART_BOUND_##BOUND, MIN, MAX, UNIT, WHAT},
#define PAYLOAD_ROW(NAME, KEY, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, WHAT)                       \
    {"PAYLOAD_" #NAME, KEY, 1, STEWART_OFFSET(PAYLOAD_##NAME), COUNT, SHAPE, STEWART_BOUND_##BOUND, MIN,  \
     MAX, UNIT, WHAT},
const stewart_elastic_info stewart_elastic_table[] = {STEWART_ELASTIC(ELASTIC_ROW)
                                                      STEWART_PAYLOAD_KEYS(PAYLOAD_ROW)};
const int stewart_elastic_table_size = sizeof stewart_elastic_table / sizeof stewart_elastic_table[0];

#define PARAMETER_ROW(ID, NAME, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, WHAT, SCENE)                 \
    {#ID, NAME, STEWART_VR(PARAMETERS, stewart_fmu_parameters, ID), COUNT, SHAPE,                 \
     STEWART_BOUND_##BOUND, MIN, MAX, SCENE, 0, "parameter", UNIT, WHAT},
#define SCENE_ROW(...) PARAMETER_ROW(__VA_ARGS__, 1)
#define SETTING_ROW(...) PARAMETER_ROW(__VA_ARGS__, 0)
#define STRING_ROW(ID, NAME, WHAT)                                                                \
    {#ID, NAME, STEWART_VR_METHOD, 1, STEWART_STRING, STEWART_BOUND_ANY, -INFINITY, INFINITY, 0, 0,  \
     "parameter", "", WHAT},
#define INPUT_ROW(ID, NAME, COUNT, SHAPE, UNIT, BOUND, WHAT)                                      \
    {#ID, NAME, STEWART_VR(INPUTS, stewart_fmu_inputs, ID), COUNT, SHAPE, STEWART_BOUND_##BOUND,  \
     -INFINITY, INFINITY, 0, 0, "input", UNIT, WHAT},
#define OUTPUT_ROW_OF(ID, NAME, COUNT, SHAPE, UNIT, BOUND, WHAT, FMI3_ONLY)                       \
    {#ID, NAME, STEWART_VR(OUTPUTS, stewart_fmu_outputs, ID), COUNT, SHAPE,                       \
     STEWART_BOUND_##BOUND, -INFINITY, INFINITY, 0, FMI3_ONLY, "output", UNIT, WHAT},
#define OUTPUT_ROW(...) OUTPUT_ROW_OF(__VA_ARGS__, 0)
#define ARRAY_ROW(...) OUTPUT_ROW_OF(__VA_ARGS__, 1)
const stewart_variable_info stewart_variable_table[] = {
    STEWART_FMU_SCENE(SCENE_ROW) STEWART_FMU_SETTINGS(SETTING_ROW) STEWART_FMU_STRINGS(STRING_ROW)
    STEWART_FMU_INPUTS(INPUT_ROW) STEWART_FMU_OUTPUTS(OUTPUT_ROW) STEWART_FMU_OUTPUT_ARRAYS(ARRAY_ROW)};
const int stewart_variable_table_size =
    sizeof stewart_variable_table / sizeof stewart_variable_table[0];

#define RANGE_ROW(ID, MIN, MAX) \
    {#ID, STEWART_VR(INPUTS, stewart_fmu_inputs, ID), (int)(sizeof(((stewart_fmu_inputs *)0)->ID) / sizeof(double)), MIN, MAX},
const stewart_input_range stewart_input_range_table[] = {STEWART_FMU_INPUT_RANGES(RANGE_ROW)};
const int stewart_input_range_table_size =
    sizeof stewart_input_range_table / sizeof stewart_input_range_table[0];

#define REACH_PARAM_ROW(NAME, COUNT, UNIT, WHAT) {#NAME, STEWART_R_##NAME, COUNT, UNIT, WHAT},
const stewart_reach_param_info stewart_reach_param_table[] = {STEWART_REACH_PARAMS(REACH_PARAM_ROW)};
const int stewart_reach_param_table_size =
    sizeof stewart_reach_param_table / sizeof stewart_reach_param_table[0];

#define REACH_KEY_ROW(ID, NAME, COUNT, UNIT, BOUND, MIN, MAX, WHAT) \
    {#ID, NAME, COUNT, STEWART_BOUND_##BOUND, MIN, MAX, UNIT, WHAT},
const stewart_reach_key_info stewart_reach_key_table[] = {STEWART_REACH_SCENE(REACH_KEY_ROW)};
const int stewart_reach_key_table_size =
    sizeof stewart_reach_key_table / sizeof stewart_reach_key_table[0];

#define LIMIT_ROW(ID, NAME, KIND, UNIT, WHAT) {#ID, NAME, STEWART_LIMIT_KIND_##KIND, UNIT, WHAT},
const stewart_limit_info stewart_limit_table[] = {STEWART_LIMITS(LIMIT_ROW)};
const int stewart_limit_table_size = sizeof stewart_limit_table / sizeof stewart_limit_table[0];
