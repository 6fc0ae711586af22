/*
 * stewart_table.h -- the one table of the plant's packed parameters and of its FMU variables,
 * written once as X-macros (the pattern of MuJoCo's mjxmacro.h) and expanded wherever a layer
 * needs it: stewart.h (the STEWART_P_* offsets, STEWART_N_PARAMS; the regressor's STEWART_S_*
 * columns, STEWART_N_STANDARD), src/table.c (the same
 * table compiled into the core, which stewart_fmu/model.py and stewart_fmu/fmu/variables.py
 * read), fmi/model.h and fmi/model.c (value references, names, packing, bound checks).
 * tests/stewart_fmu/test_table.py fails when a layer spells a name, offset or value reference
 * this file does not hold. Units and names follow docs/conventions.md.
 *
 * Offsets and value references are computed, never written: each entry takes COUNT doubles
 * after the previous one (the layout structs below). A parameter that becomes per leg changes
 * its COUNT (and SHAPE) here; offsets, value references, FMU names, the FMU's packing and the
 * per-key bounds follow; the kernel that reads it indexes it by leg.
 */
#ifndef STEWART_TABLE_H
#define STEWART_TABLE_H

#include <stddef.h>

/* The kind of a value's bounds (BOUND, with MIN and MAX, of the parameters' rows below; checked
   per key by the scene reader, stewart_fmu/scene.py, and by the FMU's validation, fmi/model.c). */
#define STEWART_BOUND_ANY 0      /* any finite number: inputs and outputs (their rows have no MIN, MAX) */
#define STEWART_BOUND_CLOSED 1   /* MIN <= x <= MAX */
#define STEWART_BOUND_OPEN 2     /* MIN < x <= MAX: a quantity that cannot be MIN (a mass of 0) */

/* Shape of an FMU variable group beyond its COUNT: COLS > 0 is a matrix of COUNT / COLS rows;
   STEWART_VECTOR a plain vector (a scalar when COUNT is 1); STEWART_PER_LEG six values, one
   per leg, or one value for all legs (a scene that gives one number declares the group's
   first value reference alone, under the group's plain name). */
#define STEWART_VECTOR 0
#define STEWART_PER_LEG (-1)
#define STEWART_STRING (-2)      /* one String value (STEWART_FMU_STRINGS) */

/* Packed parameters, in layout order: X(NAME, COUNT, SOURCE, UNIT, DESCRIPTION).
   SOURCE: the FMU scene variable (ID of STEWART_FMU_SCENE) whose values the entry holds as
   they are, COUNT values from its first (a per-leg key given once fills all six); COMPUTED
   when the packing derives the values. UNIT "1" for flags, "" for mixed units. */
#define STEWART_PARAMS(X)                                                                      \
    X(HAS_LEGS, 1, COMPUTED, "1", "1 when the scene has [legs], else 0")                       \
    X(HAS_DRIVE, 1, COMPUTED, "1", "1 when the scene has [drive], else 0")                     \
    X(HAS_FRICTION, 1, COMPUTED, "1", "1 when the scene has [friction], else 0")               \
    X(GRAVITY, 3, GRAVITY, "m/s2", "gravity in N")                                             \
    X(MASS, 1, MASS, "kg", "platform mass")                                                    \
    X(INERTIA, 3, INERTIA, "kg.m2", "platform principal moments in C")                         \
    X(LOWER, 4, LOWER_MASS, "", "lower leg part: mass, centre of mass, transverse and axial moments") \
    X(UPPER, 4, UPPER_MASS, "", "upper leg part: mass, centre of mass, transverse and axial moments") \
    X(DRIVE_MASS, 6, COMPUTED, "kg", "reflected drive inertia m_d = zeta^2 I / r^2 per leg (Eq. 14)") \
    X(VISCOUS, 6, VISCOUS, "N.s/m", "viscous friction of each prismatic joint")                \
    X(COULOMB, 6, COULOMB, "N", "Coulomb friction of each prismatic joint")                    \
    X(LEG_MIN, 1, LEG_MIN, "m", "shortest leg (0 when unlimited)")                             \
    X(LEG_MAX, 1, LEG_MAX, "m", "longest leg (inf when unlimited)")                            \
    X(CHAR_LENGTH, 1, COMPUTED, "m", "mean platform-joint radius: scales J's rotational columns") \
    X(BASE, 18, BASE, "m", "base joints a_i in N, rows")                                       \
    X(PLATFORM, 18, PLATFORM, "m", "platform joints p_i in C, rows")                           \
    X(HAS_TRANSMISSION, 1, COMPUTED, "1", "1 when the scene has [transmission], else 0")       \
    X(STIFFNESS, 1, STIFFNESS, "N/m", "transmission stiffness (leg axis)")                     \
    X(DAMPING, 1, DAMPING, "N.s/m", "transmission damping (leg axis)")                         \
    X(HAS_PAYLOAD, 1, COMPUTED, "1", "1 when the scene has [payload], else 0")                 \
    X(PAYLOAD_MASS, 1, COMPUTED, "kg", "payload mass ([payload]; not an FMU variable)")        \
    X(PAYLOAD_COM, 3, COMPUTED, "m", "payload centre of mass in C")                            \
    X(PAYLOAD_INERTIA, 6, COMPUTED, "kg.m2", "payload inertia about its centre of mass in C: Ixx, Iyy, Izz, Ixy, Ixz, Iyz")

/* FMU variables by group, value references from STEWART_VR_PARAMETERS, _INPUTS and _OUTPUTS
   on (0 is time, FMI 3.0's independent variable): X(ID, NAME, COUNT, SHAPE, UNIT, BOUND,
   DESCRIPTION), the parameters X(ID, NAME, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, DESCRIPTION)
   with the physical bounds of each of their values, in UNIT (STEWART_BOUND_CLOSED or _OPEN).
   UNIT "pose" is m for x, y, z and rad for the angles, "rate" their rates; "" none. The parameters are Real, fixed: first the scene keys of the plant tables (a scene
   declares those of the tables it has), then the FMU's settings. FMI 2.0 declares a group of
   COUNT > 1 as COUNT scalars NAME[i] (NAME[i,j] for a matrix) at consecutive value references;
   FMI 3.0 as one array variable NAME of its shape at the group's first value reference, its
   values in row-major order (a per-leg key given once is a scalar in both). */
/* The bounds are engineering ones, wide enough for any machine this model describes (from a
   micro-manipulator of grams and millimetres to a motion simulator of tonnes and metres, with
   two or three orders of magnitude to spare) and narrow enough that every product the model
   forms of them stays far inside float64 (a mass times a length squared is at most ~1e12, a
   force ~1e20): a value beyond them is a typo or a unit error (mm for m, g for kg), refused by
   the scene reader and the FMU alike, never a NaN later. Lengths within 1 km, masses up to
   1,000 t (platform) and 100 t (a leg part), gear ratios up to 1e5 (multi-stage reducers),
   pinions of 1 um to 10 m, frictions up to 1e7 N (s/m), springs up to 1e12 N/m (a steel bar
   of 1 m^2 section and 0.2 m length); the lower bound 0 is OPEN where the model divides by the
   value or a zero makes no body (mass, stroke, gear ratio, rotor, stiffness). Every shipped
   scene (scenes/) lies within them (tests/stewart_fmu/test_table.py). */
#define STEWART_FMU_SCENE(X)                                                                       \
    X(GRAVITY, "gravity", 3, STEWART_VECTOR, "m/s2", CLOSED, -1e3, 1e3, "gravity in N")            \
    X(BASE, "geometry.base_joints", 18, 3, "m", CLOSED, -1e3, 1e3, "base joint a_i in N")          \
    X(PLATFORM, "geometry.platform_joints", 18, 3, "m", CLOSED, -1e3, 1e3, "platform joint p_i in C") \
    X(HOME, "geometry.home", 6, STEWART_VECTOR, "pose", CLOSED, -1e3, 1e3, "home pose (x, y, z, thx, thy, thz)") \
    X(LEG_MIN, "geometry.leg_min", 1, STEWART_VECTOR, "m", OPEN, 0.0, 1e3, "shortest leg length (stroke)") \
    X(LEG_MAX, "geometry.leg_max", 1, STEWART_VECTOR, "m", OPEN, 0.0, 1e3, "longest leg length (stroke)") \
    X(MASS, "platform.mass", 1, STEWART_VECTOR, "kg", OPEN, 0.0, 1e6, "platform mass")             \
    X(INERTIA, "platform.inertia", 3, STEWART_VECTOR, "kg.m2", CLOSED, 0.0, 1e10,                  \
      "platform principal moments about its centre of mass")                                       \
    X(LOWER_MASS, "legs.lower_mass", 1, STEWART_VECTOR, "kg", CLOSED, 0.0, 1e5, "lower leg part (cylinder) mass") \
    X(LOWER_COM, "legs.lower_com", 1, STEWART_VECTOR, "m", CLOSED, 0.0, 1e3,                       \
      "lower part centre of mass from the base joint")                                             \
    X(LOWER_INERTIA, "legs.lower_inertia", 2, STEWART_VECTOR, "kg.m2", CLOSED, 0.0, 1e9,           \
      "lower part [transverse, axial] moments")                                                    \
    X(UPPER_MASS, "legs.upper_mass", 1, STEWART_VECTOR, "kg", CLOSED, 0.0, 1e5, "upper leg part (piston) mass") \
    X(UPPER_COM, "legs.upper_com", 1, STEWART_VECTOR, "m", CLOSED, 0.0, 1e3,                       \
      "upper part centre of mass from the platform joint")                                         \
    X(UPPER_INERTIA, "legs.upper_inertia", 2, STEWART_VECTOR, "kg.m2", CLOSED, 0.0, 1e9,           \
      "upper part [transverse, axial] moments")                                                    \
    X(GEAR_RATIO, "drive.gear_ratio", 1, STEWART_VECTOR, "1", OPEN, 0.0, 1e5, "gearbox reduction ratio zeta") \
    X(ROTOR_INERTIA, "drive.rotor_inertia", 6, STEWART_PER_LEG, "kg.m2", OPEN, 0.0, 1e3, "motor rotor inertia") \
    X(PINION_RADIUS, "drive.pinion_radius", 1, STEWART_VECTOR, "m", CLOSED, 1e-6, 10.0, "rack-and-pinion radius") \
    X(VISCOUS, "friction.viscous", 6, STEWART_PER_LEG, "N.s/m", CLOSED, 0.0, 1e7,                  \
      "viscous friction of each prismatic joint")                                                  \
    X(COULOMB, "friction.coulomb", 6, STEWART_PER_LEG, "N", CLOSED, 0.0, 1e7,                      \
      "Coulomb friction of each prismatic joint")                                                  \
    X(STIFFNESS, "transmission.stiffness", 1, STEWART_VECTOR, "N/m", OPEN, 0.0, 1e12,              \
      "transmission stiffness, motor to leg (leg axis)")                                           \
    X(DAMPING, "transmission.damping", 1, STEWART_VECTOR, "N.s/m", CLOSED, 0.0, 1e9,               \
      "transmission damping, motor to leg (leg axis)")

/* The FMU's own parameters (Real, fixed), after the scene's: the start state and the solver
   (a scene's [solver] table takes the same bounds: stewart_sim/scene/load.py). */
#define STEWART_FMU_SETTINGS(X)                                                                    \
    X(Q0, "q0", 6, STEWART_VECTOR, "pose", CLOSED, -1e3, 1e3, "initial pose")                      \
    X(QD0, "qd0", 6, STEWART_VECTOR, "rate", CLOSED, -1e3, 1e3, "initial pose rates")              \
    X(RTOL, "solver.rtol", 1, STEWART_VECTOR, "", OPEN, 0.0, 1.0, "integrator relative tolerance (dopri5)") \
    X(ATOL, "solver.atol", 1, STEWART_VECTOR, "", OPEN, 0.0, 1e3, "integrator absolute tolerance (dopri5)") \
    X(MAX_STEP, "solver.max_step", 1, STEWART_VECTOR, "s", OPEN, 0.0, 1e3, "largest internal step (s)")

/* The String parameter, after the Real ones (value reference STEWART_VR_METHOD):
   X(ID, NAME, DESCRIPTION). */
#define STEWART_FMU_STRINGS(X) X(METHOD, "solver.method", "integrator")

/* Inputs (Real, continuous): tau only with a [drive]. */
#define STEWART_FMU_INPUTS(X)                                                                    \
    X(SIGMA, "sigma", 6, STEWART_PER_LEG, "N", ANY,                                              \
      "actuator force at the rack (starts at the force holding home)")                           \
    X(TAU, "tau", 6, STEWART_PER_LEG, "N.m", ANY, "motor torque")

/* The declared range of each input (min and max in the model description; setReal refuses a
   value outside it, or a non-finite one, and changes nothing): X(ID, MIN, MAX). No plant table
   gives a force or torque limit, so these are fixed generous magnitudes that keep every derived
   force finite: 1e7 N at the rack (the weight of 1,000 t; the motion simulator holds ~2.5e3 N a
   leg) and 1e6 N m at the motor (above any electric servomotor's peak torque). */
#define STEWART_FMU_INPUT_RANGES(X)                                                              \
    X(SIGMA, -1e7, 1e7)                                                                          \
    X(TAU, -1e6, 1e6)

/* Outputs (Real, continuous, calculated on demand); force.<part> in STEWART_PART_* order, only
   the parts of the effects the scene declares. */
#define STEWART_FMU_OUTPUTS(X)                                                                   \
    X(L, "l", 6, STEWART_PER_LEG, "m", ANY, "leg length")                                        \
    X(LDOT, "ldot", 6, STEWART_PER_LEG, "m/s", ANY, "leg rate")                                  \
    X(Q_X, "x", 1, STEWART_VECTOR, "m", ANY, "platform pose x")                                    \
    X(Q_Y, "y", 1, STEWART_VECTOR, "m", ANY, "platform pose y")                                    \
    X(Q_Z, "z", 1, STEWART_VECTOR, "m", ANY, "platform pose z")                                    \
    X(Q_THX, "thx", 1, STEWART_VECTOR, "rad", ANY, "platform pose thx")                            \
    X(Q_THY, "thy", 1, STEWART_VECTOR, "rad", ANY, "platform pose thy")                            \
    X(Q_THZ, "thz", 1, STEWART_VECTOR, "rad", ANY, "platform pose thz")                            \
    X(QD_X, "dx", 1, STEWART_VECTOR, "m/s", ANY, "rate of x")                                      \
    X(QD_Y, "dy", 1, STEWART_VECTOR, "m/s", ANY, "rate of y")                                      \
    X(QD_Z, "dz", 1, STEWART_VECTOR, "m/s", ANY, "rate of z")                                      \
    X(QD_THX, "dthx", 1, STEWART_VECTOR, "rad/s", ANY, "rate of thx")                              \
    X(QD_THY, "dthy", 1, STEWART_VECTOR, "rad/s", ANY, "rate of thy")                              \
    X(QD_THZ, "dthz", 1, STEWART_VECTOR, "rad/s", ANY, "rate of thz")                              \
    X(V, "v", 3, STEWART_VECTOR, "m/s", ANY, "platform velocity in N")                           \
    X(OMEGA, "omega", 3, STEWART_VECTOR, "rad/s", ANY, "platform angular velocity in N")         \
    X(COND, "cond", 1, STEWART_VECTOR, "1", ANY, "condition number of the leg Jacobian (scaled)") \
    X(RACK, "rack_force", 6, STEWART_PER_LEG, "N", ANY, "total force at the rack (sigma + zeta/r tau)") \
    X(FORCE_PLATFORM, "force.platform", 6, STEWART_PER_LEG, "N", ANY, "rack force spent on the platform") \
    X(FORCE_LOWER_LEGS, "force.lower_legs", 6, STEWART_PER_LEG, "N", ANY,                        \
      "rack force spent on the lower legs")                                                      \
    X(FORCE_UPPER_LEGS, "force.upper_legs", 6, STEWART_PER_LEG, "N", ANY,                        \
      "rack force spent on the upper legs")                                                      \
    X(FORCE_DRIVES, "force.drives", 6, STEWART_PER_LEG, "N", ANY, "rack force spent on the drives") \
    X(FORCE_GRAVITY, "force.gravity", 6, STEWART_PER_LEG, "N", ANY, "rack force spent on gravity") \
    X(FORCE_FRICTION, "force.friction", 6, STEWART_PER_LEG, "N", ANY, "rack force spent on friction")

/* Outputs of FMI 3.0 only, after the others: the pose and its rates as arrays, beside the named
   scalars x .. dthz (which keep their units, m or rad: an FMI 3.0 array has one unit, and FMI
   2.0 has no arrays). */
#define STEWART_FMU_OUTPUT_ARRAYS(X)                                                             \
    X(Q, "q", 6, STEWART_VECTOR, "pose", ANY, "platform pose (x, y, z in m; thx, thy, thz in rad)") \
    X(QD, "qd", 6, STEWART_VECTOR, "rate", ANY, "pose rates (dx, dy, dz in m/s; dthx, dthy, dthz in rad/s)")

/* The standard parameters of the identification model, in column order of the regressor Y
   (src/regressor.c: sigma = Y(q, qd, qdd) pi, linear in pi): X(NAME, COUNT, KEY, UNIT,
   DESCRIPTION). KEY is the dotted name reports use. The platform's are taken about the platform
   frame's origin C in the platform frame; a leg part's about its own joint (the lower part's
   base joint, the upper part's platform joint), along the leg. The scene's model holds C at the
   platform's centre of mass with principal axes along the platform frame, so its first moment
   and its products of inertia are zero; the regressor has their columns all the same. */
#define STEWART_STANDARD(X)                                                                      \
    X(PLATFORM_MASS, 1, "platform.mass", "kg", "platform mass m")                              \
    X(PLATFORM_MOMENT, 3, "platform.first_moment", "kg.m", "m c, c the centre of mass from C")  \
    X(PLATFORM_INERTIA, 6, "platform.inertia_tensor", "kg.m2",                                  \
      "inertia tensor about C: xx, xy, xz, yy, yz, zz")                                         \
    X(LOWER_MASS, 1, "legs.lower_mass", "kg", "lower part mass m_A")                            \
    X(LOWER_MOMENT, 1, "legs.lower_first_moment", "kg.m", "m_A c_A about the base joint")       \
    X(LOWER_INERTIA, 1, "legs.lower_joint_inertia", "kg.m2",                                    \
      "lower part transverse moment about the base joint, I_tA + m_A c_A^2")                    \
    X(LOWER_AXIAL, 1, "legs.lower_axial_inertia", "kg.m2", "lower part axial moment")           \
    X(UPPER_MASS, 1, "legs.upper_mass", "kg", "upper part mass m_B")                            \
    X(UPPER_MOMENT, 1, "legs.upper_first_moment", "kg.m", "m_B c_B about the platform joint")   \
    X(UPPER_INERTIA, 1, "legs.upper_joint_inertia", "kg.m2",                                    \
      "upper part transverse moment about the platform joint, I_tB + m_B c_B^2")                \
    X(UPPER_AXIAL, 1, "legs.upper_axial_inertia", "kg.m2", "upper part axial moment")           \
    X(DRIVE_MASS, 6, "drive.reflected_mass", "kg", "reflected drive inertia m_d of each leg")   \
    X(VISCOUS, 6, "friction.viscous", "N.s/m", "viscous friction of each prismatic joint")      \
    X(COULOMB, 6, "friction.coulomb", "N", "Coulomb friction of each prismatic joint")

/* Quantities derived from the scene's keys, checked finite and within their bounds once
   computed (native/src/rules.c, for the scene reader and the FMU alike; the reason names the
   keys they come from): X(ID, NAME, UNIT, BOUND, MIN, MAX). The key bounds above keep them
   finite; these bounds refuse the combinations no machine has (a reflected drive mass above
   100 times the heaviest platform). */
#define STEWART_DERIVED(X)                                                                       \
    X(RACK_RATIO, "the rack ratio zeta / r", "1/m", OPEN, 0.0, 1e8)                                \
    X(DRIVE_MASS, "the reflected drive mass m_d = zeta^2 I / r^2", "kg", CLOSED, 0.0, 1e8)         \
    X(MOVING_MASS, "the moving mass (platform and 12 leg parts)", "kg", OPEN, 0.0, 1e7)

/* The scene keys of [stiffness] and [payload] (contract tables, not FMU variables), with the
   physical bounds of each value as the plant's keys above (stewart_fmu/scene.py checks them):
   X(NAME, KEY, COUNT, SHAPE, UNIT, BOUND, MIN, MAX, DESCRIPTION), KEY "" for a computed entry
   (a flag). [stiffness] is packed into its own vector, the elastic one of the stiffness and the
   modes (src/stiffness.c; Model.elastic), in STEWART_ELASTIC's order; [payload] into the
   plant's parameters (STEWART_PARAMS PAYLOAD_*: the dynamics carries it), STEWART_PAYLOAD_KEYS
   gives its keys' bounds. How the springs combine (docs/scene-format.md, [stiffness]):
   - [stiffness] leg: each leg's axial stiffness between its joints; with a [transmission] the
     transmission's spring (its key stiffness, the motor held) acts in series with it,
     k = k_leg k_t / (k_leg + k_t);
   - [stiffness] joint_bending: the bending stiffness of each of the 12 joints (flexures), about
     any axis across the leg, relaxed at the pose: the base joint resists the leg's rotation
     against the base, the platform joint the leg's rotation against the platform;
   - [stiffness] joint_torsion: each joint's stiffness about the leg's axis; the two joints of a
     leg act in series on the platform's rotation about that axis (k_t / 2), the leg free to
     spin between them.
   The payload: a rigid body fixed to the platform, its mass, its centre of mass in C and its
   inertia tensor about that centre in C's axes, [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] the entries of
   the symmetric matrix [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] (three principal
   moments fill the first three). */
#define STEWART_ELASTIC(X)                                                                       \
    X(HAS_STIFFNESS, "", 1, STEWART_VECTOR, "1", CLOSED, 0.0, 1.0, "1 when the scene has [stiffness]") \
    X(LEG, "stiffness.leg", 6, STEWART_PER_LEG, "N/m", OPEN, 0.0, 1e12,                          \
      "axial stiffness of each leg between its joints")                                          \
    X(BENDING, "stiffness.joint_bending", 1, STEWART_VECTOR, "N.m/rad", OPEN, 0.0, 1e9,          \
      "bending stiffness of each joint (0 when absent: ball joints)")                            \
    X(TORSION, "stiffness.joint_torsion", 1, STEWART_VECTOR, "N.m/rad", OPEN, 0.0, 1e9,          \
      "torsion stiffness of each joint about the leg (0 when absent)")
/* NAME: the STEWART_PARAMS entry PAYLOAD_<NAME> that holds the key's values. */
#define STEWART_PAYLOAD_KEYS(X)                                                                  \
    X(MASS, "payload.mass", 1, STEWART_VECTOR, "kg", OPEN, 0.0, 1e6, "payload mass")             \
    X(COM, "payload.com", 3, STEWART_VECTOR, "m", CLOSED, -1e3, 1e3, "payload centre of mass in C") \
    X(INERTIA, "payload.inertia", 6, STEWART_VECTOR, "kg.m2", CLOSED, -1e10, 1e10,               \
      "payload inertia about its centre of mass in C: Ixx, Iyy, Izz, Ixy, Ixz, Iyz")

#define STEWART_VR_TIME 0          /* FMI 3.0's independent variable */
#define STEWART_VR_PARAMETERS 1    /* first value reference of each section */
#define STEWART_VR_INPUTS 100
#define STEWART_VR_OUTPUTS 200

/* ---- the layouts: one double array per entry, in table order ---------------------------- */
#define STEWART_X_FIELD(NAME, COUNT, ...) double NAME[COUNT];
#define STEWART_X_VARIABLE(ID, NAME, COUNT, ...) double ID[COUNT];
typedef struct { STEWART_PARAMS(STEWART_X_FIELD) } stewart_param_layout;
typedef struct {
    STEWART_FMU_SCENE(STEWART_X_VARIABLE) STEWART_FMU_SETTINGS(STEWART_X_VARIABLE)
} stewart_fmu_parameters;
typedef struct { STEWART_STANDARD(STEWART_X_FIELD) } stewart_standard_layout;
#define STEWART_X_ELASTIC_FIELD(NAME, KEY, COUNT, ...) double NAME[COUNT];
typedef struct { STEWART_ELASTIC(STEWART_X_ELASTIC_FIELD) } stewart_elastic_layout;
typedef struct { STEWART_FMU_INPUTS(STEWART_X_VARIABLE) } stewart_fmu_inputs;
typedef struct {
    STEWART_FMU_OUTPUTS(STEWART_X_VARIABLE) STEWART_FMU_OUTPUT_ARRAYS(STEWART_X_VARIABLE)
} stewart_fmu_outputs;

/* The offset of a packed entry, and the value reference of an FMU variable group
   (SECTION: PARAMETERS, INPUTS or OUTPUTS; LAYOUT: the struct of that section). */
#define STEWART_OFFSET(NAME) ((int)(offsetof(stewart_param_layout, NAME) / sizeof(double)))
#define STEWART_ELASTIC_OFFSET(NAME) ((int)(offsetof(stewart_elastic_layout, NAME) / sizeof(double)))
#define STEWART_STANDARD_OFFSET(NAME) ((int)(offsetof(stewart_standard_layout, NAME) / sizeof(double)))
#define STEWART_VR(SECTION, LAYOUT, ID) \
    (STEWART_VR_##SECTION + (int)(offsetof(LAYOUT, ID) / sizeof(double)))
#define STEWART_VR_END(SECTION, LAYOUT) \
    (STEWART_VR_##SECTION + (int)(sizeof(LAYOUT) / sizeof(double)))
#define STEWART_VR_N_PARAMETERS STEWART_VR_END(PARAMETERS, stewart_fmu_parameters)
#define STEWART_VR_METHOD STEWART_VR_N_PARAMETERS  /* the String parameter solver.method */
#define STEWART_VR_N_OUTPUTS STEWART_VR_END(OUTPUTS, stewart_fmu_outputs)

/* ==== reach: the mechanism's limits (src/reach.c) and frames (src/frames.c) =================
   The contract's tables [joints], [clearance] and [frames] (docs/guides/workspace.md), packed apart from
   the plant's parameters (the FMU's variables and outputs are not affected): their scene keys
   with their bounds, the packed reach vector the engine reads, the obstacle records, and the
   limits the engine reports, in the order it reports them. */
#define STEWART_BOUND_INTERIOR 3  /* MIN < x < MAX: an angle strictly inside (0, pi/2) */

/* Scene keys of the reach tables: X(ID, NAME, COUNT, UNIT, BOUND, MIN, MAX, DESCRIPTION); an
   obstacle's keys are read in each [[clearance.obstacles]] table. The pivot lies within 10 m of
   C (per component); the rest takes the plant's length bound (1 km). */
#define STEWART_REACH_SCENE(X)                                                                   \
    X(BASE_CONE, "joints.base_cone", 1, "rad", INTERIOR, 0.0, 1.5707963267948966,                \
      "largest angle between leg i and its base joint's axis")                                   \
    X(PLATFORM_CONE, "joints.platform_cone", 1, "rad", INTERIOR, 0.0, 1.5707963267948966,        \
      "largest angle between leg i and its platform joint's axis")                               \
    X(BASE_AXES, "joints.base_axes", 18, "1", CLOSED, -1e3, 1e3, "base joint axes in N (six directions)") \
    X(PLATFORM_AXES, "joints.platform_axes", 18, "1", CLOSED, -1e3, 1e3,                         \
      "platform joint axes in C (six directions)")                                               \
    X(LEG_RADIUS, "clearance.leg_radius", 1, "m", OPEN, 0.0, 10.0, "radius of each leg's capsule") \
    X(OBSTACLE_CENTER, "clearance.obstacles.center", 3, "m", CLOSED, -1e3, 1e3,                  \
      "an obstacle's centre, in N (body base) or C (body platform)")                             \
    X(OBSTACLE_ANGLES, "clearance.obstacles.angles", 3, "rad", CLOSED, -1e3, 1e3,                \
      "an obstacle's orientation in its body (thx, thy, thz as a pose's)")                       \
    X(OBSTACLE_SIZE, "clearance.obstacles.size", 3, "m", OPEN, 0.0, 1e3, "a box's edge lengths") \
    X(OBSTACLE_RADIUS, "clearance.obstacles.radius", 1, "m", OPEN, 0.0, 1e3,                     \
      "a sphere's or cylinder's radius")                                                         \
    X(OBSTACLE_LENGTH, "clearance.obstacles.length", 1, "m", OPEN, 0.0, 1e3,                     \
      "a cylinder's length along its axis (local z)")                                            \
    X(PIVOT, "frames.pivot", 3, "m", CLOSED, -10.0, 10.0, "the pivot point in C")               \
    X(USER, "frames.user", 6, "pose", CLOSED, -1e3, 1e3, "the user (work) frame's pose in N")     \
    X(TOOL, "frames.tool", 6, "pose", CLOSED, -1e3, 1e3, "the tool frame's pose in C")

/* Obstacles: at most STEWART_MAX_OBSTACLES, each a record of STEWART_OBSTACLE_SIZE doubles:
   shape, body, centre (3) in its body, rotation (9, row-major, local to body), half extents
   (3: a box's half edges; a cylinder's radius, radius, half length; a sphere's radius). */
#define STEWART_MAX_OBSTACLES 16
#define STEWART_OBSTACLE_SIZE 17
#define STEWART_SHAPE_SPHERE 0
#define STEWART_SHAPE_BOX 1
#define STEWART_SHAPE_CYLINDER 2
#define STEWART_BODY_BASE 0
#define STEWART_BODY_PLATFORM 1

/* The packed reach vector (stewart_fmu/reach_params.py builds it): X(NAME, COUNT, UNIT,
   DESCRIPTION). A limit whose table or bound is absent has its HAS_ flag 0 (or its bound inf)
   and is not computed. */
#define STEWART_REACH_PARAMS(X)                                                                  \
    X(HAS_JOINTS, 1, "1", "1 when the scene has [joints]")                                       \
    X(BASE_CONE, 1, "rad", "base joint cone")                                                    \
    X(PLATFORM_CONE, 1, "rad", "platform joint cone")                                            \
    X(BASE_AXES, 18, "1", "base joint axes in N, unit rows")                                     \
    X(PLATFORM_AXES, 18, "1", "platform joint axes in C, unit rows")                             \
    X(HAS_CLEARANCE, 1, "1", "1 when the scene has [clearance]")                                 \
    X(LEG_RADIUS, 1, "m", "leg capsule radius")                                                  \
    X(N_OBSTACLES, 1, "1", "number of obstacle records")                                         \
    X(OBSTACLES, STEWART_MAX_OBSTACLES * STEWART_OBSTACLE_SIZE, "", "obstacle records")         \
    X(COND_LIMIT, 1, "1", "largest scaled cond(J) (inf: not limited)")                           \
    X(SPEED, 1, "m/s", "largest |leg speed| (inf: not limited)")                                 \
    X(ACCELERATION, 1, "m/s2", "largest |leg acceleration| (inf: not limited)")                  \
    X(FORCE, 1, "N", "largest |rack force| (inf: not limited)")

/* The limits, in the order the engine reports them (the first violated one in this order is
   the binding limit): X(ID, NAME, KIND, UNIT, DESCRIPTION). KIND: LEG (one margin per leg),
   PAIR (per pair of legs, (1,2), (1,3) .. (5,6)), OBSTACLE (per obstacle and leg), POSE (one).
   A margin is positive inside the limit, in UNIT. */
#define STEWART_LIMIT_KIND_LEG 0
#define STEWART_LIMIT_KIND_PAIR 1
#define STEWART_LIMIT_KIND_OBSTACLE 2
#define STEWART_LIMIT_KIND_POSE 3
#define STEWART_LIMITS(X)                                                                        \
    X(STROKE_MIN, "stroke_min", LEG, "m", "leg length above geometry.leg_min")                   \
    X(STROKE_MAX, "stroke_max", LEG, "m", "leg length below geometry.leg_max")                   \
    X(BASE_CONE, "base_cone", LEG, "rad", "joints.base_cone less the leg's angle to its base joint's axis") \
    X(PLATFORM_CONE, "platform_cone", LEG, "rad",                                                \
      "joints.platform_cone less the leg's angle to its platform joint's axis")                  \
    X(LEG_CLEARANCE, "leg_clearance", PAIR, "m", "distance between two legs' segments less 2 leg_radius") \
    X(OBSTACLE, "obstacle", OBSTACLE, "m", "signed distance of a leg's segment to an obstacle less leg_radius") \
    X(COND, "cond", POSE, "1", "the cond limit less the scaled cond(J)")                         \
    X(SPEED, "speed", LEG, "m/s", "the speed limit less |leg speed|")                            \
    X(ACCELERATION, "acceleration", LEG, "m/s2", "the acceleration limit less |leg acceleration|") \
    X(FORCE, "force", LEG, "N", "the force limit less |rack force| (inverse dynamics, drive included)")

/* The scaled cond(J) a pose may reach by default (the emulated device's SP_COND_MAX default):
   beyond it forces amplify ~100x. */
#define STEWART_REACH_COND_LIMIT 100.0

#define STEWART_X_REACH_FIELD(NAME, COUNT, ...) double NAME[COUNT];
typedef struct { STEWART_REACH_PARAMS(STEWART_X_REACH_FIELD) } stewart_reach_layout;
#define STEWART_REACH_OFFSET(NAME) ((int)(offsetof(stewart_reach_layout, NAME) / sizeof(double)))

#endif /* STEWART_TABLE_H */
