"""Status codes of the C core, in one place, and what each means to a user.

Every core function returns an int status instead of raising; the Python layer turns a non-zero
status into the typed error of `errors.py`.
"""
from .native.core import lib

# The numbers are the C core's (native/include/stewart.h), named as Python uses them.
OK = lib.STEWART_OK                    # 0
NONFINITE = lib.STEWART_NONFINITE      # 1: a non-finite input
STROKE = lib.STEWART_STROKE            # 2: a leg is outside [leg_min, leg_max]
SINGULAR = lib.STEWART_SINGULAR        # 3: the Jacobian is singular (smallest LU pivot tiny)
GIMBAL = lib.STEWART_GIMBAL            # 4: pitch at +-90 degrees: E cannot be inverted
OVERFLOW = lib.STEWART_OVERFLOW        # 5: an acceleration overflowed (a near-singular pose)
TOO_MANY_STEPS = lib.STEWART_TOO_MANY_STEPS    # 100: more than max_steps internal steps
STEP_TOO_SMALL = lib.STEWART_STEP_TOO_SMALL    # 101: the adaptive step fell below its minimum
ENERGY_GAIN = lib.STEWART_UNSTABLE             # 102: the step's check: energy grew beyond the work
STATE_NONFINITE = lib.STEWART_STATE_NONFINITE  # 103: the step's check: the new state is not finite

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
