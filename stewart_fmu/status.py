"""Status codes of the C core, in one place, and what each means to a user.

Every core function returns an int status instead of raising; the Python layer turns a non-zero
status into the typed error of `errors.py`. The names and words are the core's own table
(native/src/status.c: stewart_status_name, stewart_status_why), read here once.
"""
from .native.core import ffi, lib

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
# The component's (native/src/component.c): a call or its arguments refused, a state refused.
BAD_CALL = lib.STEWART_BAD_CALL                # 110: the call is not allowed in this phase
BAD_STEP = lib.STEWART_BAD_STEP                # 111: a step size not finite and > 0
BAD_TIME = lib.STEWART_BAD_TIME                # 112: a current time not the component's
BAD_STATE = lib.STEWART_BAD_STATE              # 113: serialized state: size, magic, version
STATE_FOREIGN = lib.STEWART_STATE_FOREIGN      # 114: serialized state of another model
STATE_CORRUPT = lib.STEWART_STATE_CORRUPT      # 115: serialized state: checksum mismatch
STATE_INVALID = lib.STEWART_STATE_INVALID      # 116: a state out of range or not finite


def _table(fn) -> dict[int, str]:
    """{code: text} of a C table over the codes it knows (status codes are below 256)."""
    out = {}
    for code in range(256):
        text = fn(code)
        if text != ffi.NULL:
            out[code] = ffi.string(text).decode()
    return out


NAME = _table(lib.stewart_status_name)   # {code: "STROKE", ...}
WHY = _table(lib.stewart_status_why)     # {code: "a leg left its stroke", ...}


def why(status: int) -> str:
    """What a non-zero status means, for messages."""
    return WHY.get(status, f"status {status}")
