/* axis_table.h -- the controller FMU's variables, one row each (X-macros), read by the FMU
 * (model.c) and by controller/fmu.py (the model description, the start values): the one
 * spelling of their names, sizes, units and value references.
 *
 * X(ID, NAME, COUNT, UNIT, DESCRIPTION), one row per line (the parameters' bounds:
 * AXIS_FMU_PARAMETER_RANGES; the inputs' ranges: AXIS_FMU_INPUT_RANGES). Value references: a group's first is its section's
 * base plus the values before it in the section (COUNT per row, in this order); FMI 3.0's
 * independent variable `time` is 0. Per-leg groups (COUNT 6) are NAME[1] .. NAME[6]. */
#ifndef AXIS_TABLE_H
#define AXIS_TABLE_H

#define AXIS_VR_PARAMETERS 1
#define AXIS_VR_INPUTS 1001
#define AXIS_VR_OUTPUTS 2001

/* Parameters (Real, fixed): the design's gains, the drive, the start of the loop. */
#define AXIS_FMU_PARAMETERS(X)                                                                   \
    X(RATE, "rate", 1, "Hz", "controller rate: doStep takes whole numbers of its periods")      \
    X(KP, "kp", 1, "V/m", "proportional gain")                                                  \
    X(KI, "ki", 1, "V/(m.s)", "integral gain")                                                   \
    X(KD, "kd", 1, "V.s/m", "derivative gain (on ldot_ref - ldot)")                              \
    X(VOLTAGE_LIMIT, "voltage_limit", 1, "V", "motor voltage limit (anti-windup above it)")     \
    X(CURRENT_LIMIT, "current_limit", 1, "A", "motor current limit")                            \
    X(RESISTANCE, "resistance", 1, "Ohm", "motor winding resistance")                           \
    X(INDUCTANCE, "inductance", 1, "H", "motor winding inductance")                             \
    X(TORQUE_CONSTANT, "torque_constant", 1, "N.m/A", "motor torque constant Kt")               \
    X(EMF_CONSTANT, "emf_constant", 1, "V.s/m", "back-EMF per rack speed, Ke zeta / r")         \
    X(FORCE_PER_TORQUE, "force_per_torque", 1, "1/m", "rack force per motor torque, zeta / r")  \
    X(INTEGRAL0, "integral0", 6, "m.s", "PID integral at the start (the drives holding)")       \
    X(CURRENT0, "current0", 6, "A", "motor current at the start (the drives holding)")      \
    X(REFERENCE, "reference", 1, "", "1: l_ref, ldot_ref, v_ff from the carried move; 0: inputs") \
    X(DELAY, "delay", 1, "", "outputs: 0 the sample at this point, 1 the last step's (a period late)")

/* The parameters' bounds (the model description's min and max; exitInitializationMode refuses
   a value outside them, or a non-finite one, naming the parameter): X(ID, BOUND, MIN, MAX), one
   row per line. BOUND AXIS_BOUND_OPEN: MIN < x <= MAX (a rate, a resistance, a limit of 0 makes
   no loop: the model description declares MIN, which the FMU refuses), AXIS_BOUND_CLOSED:
   MIN <= x <= MAX. MAX HUGE_VAL: no upper bound (none declared): the design's gains and the
   drive's constants have no physical ceiling the controller's arithmetic needs (an output
   that overflows is caught as non-finite). reference and delay are moreover 0 or 1 (model.c).
   integral0 and current0 have no row: any finite number. */
#define AXIS_BOUND_CLOSED 1
#define AXIS_BOUND_OPEN 2
#define AXIS_FMU_PARAMETER_RANGES(X)                                                             \
    X(RATE, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                                      \
    X(KP, AXIS_BOUND_CLOSED, 0.0, HUGE_VAL)                                                      \
    X(KI, AXIS_BOUND_CLOSED, 0.0, HUGE_VAL)                                                      \
    X(KD, AXIS_BOUND_CLOSED, 0.0, HUGE_VAL)                                                      \
    X(VOLTAGE_LIMIT, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                             \
    X(CURRENT_LIMIT, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                             \
    X(RESISTANCE, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                                \
    X(INDUCTANCE, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                                \
    X(TORQUE_CONSTANT, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                           \
    X(EMF_CONSTANT, AXIS_BOUND_CLOSED, 0.0, HUGE_VAL)                                            \
    X(FORCE_PER_TORQUE, AXIS_BOUND_OPEN, 0.0, HUGE_VAL)                                          \
    X(REFERENCE, AXIS_BOUND_CLOSED, 0.0, 1.0)                                                    \
    X(DELAY, AXIS_BOUND_CLOSED, 0.0, 1.0)

/* Inputs (Real, continuous), held over a step. */
#define AXIS_FMU_INPUTS(X)                                                                       \
    X(L_REF, "l_ref", 6, "m", "reference leg length")                                           \
    X(LDOT_REF, "ldot_ref", 6, "m/s", "reference leg rate")                                     \
    X(V_FF, "v_ff", 6, "V", "feedforward voltage (the master's, 0 without feedforward)")        \
    X(L, "l", 6, "m", "measured leg length")                                                    \
    X(LDOT, "ldot", 6, "m/s", "measured leg rate")

/* The declared range of each input group (min and max in the model description; setReal
   refuses a value outside it, or a non-finite one, and changes nothing): X(ID, MIN, MAX), one
   row per line. No scene table bounds them, so these are fixed generous magnitudes beyond any
   Stewart platform's legs (1 km, 1 km/s) and any motor drive's voltage (1 MV) that keep the
   controller's arithmetic finite. */
#define AXIS_FMU_INPUT_RANGES(X)                                                                 \
    X(L_REF, 0.0, 1e3)                                                                           \
    X(LDOT_REF, -1e3, 1e3)                                                                       \
    X(V_FF, -1e6, 1e6)                                                                           \
    X(L, 0.0, 1e3)                                                                               \
    X(LDOT, -1e3, 1e3)

/* Outputs (Real, continuous). delay 0: the sample at the current communication point from the
   state and the inputs set (direct feedthrough), what doStep then holds over its first period.
   delay 1: the sample of the last period doStep took (before any step, the drives' start:
   current0, its torque and force, R current0), for masters that step every FMU before passing
   outputs on (SSP importers): the torque reaches the plant one period after its sample. */
#define AXIS_FMU_OUTPUTS(X)                                                                      \
    X(TAU, "tau", 6, "N.m", "motor torque, the mean over the controller period")                \
    X(FORCE, "force", 6, "N", "rack force, force_per_torque tau")                               \
    X(VOLTAGE, "voltage", 6, "V", "motor voltage (PID + feedforward, limited)")                 \
    X(CURRENT, "current", 6, "A", "motor current at the end of the period")                     \
    X(SATURATED, "saturated", 6, "", "1 where the voltage or the current is at its limit")

#define AXIS_X_FIELD(ID, NAME, COUNT, ...) double ID[COUNT];
typedef struct { AXIS_FMU_PARAMETERS(AXIS_X_FIELD) } axis_fmu_parameters;
typedef struct { AXIS_FMU_INPUTS(AXIS_X_FIELD) } axis_fmu_inputs;
typedef struct { AXIS_FMU_OUTPUTS(AXIS_X_FIELD) } axis_fmu_outputs;

#define AXIS_VR(SECTION, LAYOUT, ID) (AXIS_VR_##SECTION + (int)(offsetof(LAYOUT, ID) / sizeof(double)))
#define AXIS_N(LAYOUT) ((int)(sizeof(LAYOUT) / sizeof(double)))

#endif /* AXIS_TABLE_H */
