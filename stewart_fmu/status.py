"""Status codes of the compiled kernels, in one place, and what each means to a user.

Every kernel returns an int status instead of raising (compiled code cannot raise typed errors
cheaply); the Python layer turns a non-zero status into the typed error of `errors.py`.
"""
OK = 0
NONFINITE = 1        # a non-finite input, or the state became non-finite inside the integrator
STROKE = 2           # a leg is outside [leg_min, leg_max]
SINGULAR = 3         # the Jacobian is singular (smallest LU pivot below SINGULAR_PIVOT)
GIMBAL = 4           # pitch at +-90 degrees: the Euler-rate matrix E cannot be inverted
OVERFLOW = 5         # an acceleration overflowed (a near-singular pose)
TOO_MANY_STEPS = 100  # the integrator needed more than max_steps internal steps
STEP_TOO_SMALL = 101  # the adaptive step fell below 1e-14 of the time scale
ENERGY_GAIN = 102    # the step's check: energy grew beyond the work of the held rack forces
STATE_NONFINITE = 103  # the step's check: the integrated state is not finite

WHY = {NONFINITE: "the state became non-finite", OVERFLOW: "the accelerations overflowed",
       STROKE: "a leg left its stroke", SINGULAR: "the Jacobian became singular",
       GIMBAL: "the pitch reached +-90 degrees (Euler-rate singularity)",
       TOO_MANY_STEPS: "the integrator needed too many internal steps (stiff or too loose "
                       "max_steps: try 'Radau' or 'BDF')",
       STEP_TOO_SMALL: "the integrator's step fell below its minimum (stiff: try 'Radau')",
       ENERGY_GAIN: "the energy grew more than the rack forces supplied (numerical instability)",
       STATE_NONFINITE: "the state became non-finite (numerical instability)"}


def why(status: int) -> str:
    """What a non-zero status means, for messages."""
    return WHY.get(status, f"status {status}")
