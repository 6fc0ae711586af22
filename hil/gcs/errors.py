"""PI's GCS 2.0 error codes the twin sets (`ERR?` reads and clears them), with PI's own texts.

The numbers and texts are PI's (the GCS 2.0 error table, as PIPython's
`pipython.pidevice.gcserror` carries it); only the codes the twin can set are listed.
"""
from __future__ import annotations

NO_ERROR = 0
PARAM_SYNTAX = 1            # Parameter syntax error
UNKNOWN_COMMAND = 2         # Unknown command
COMMAND_TOO_LONG = 3        # Command length out of limits or command buffer overrun
MOVE_WITHOUT_REF_OR_NO_SERVO = 5   # Unallowable move attempted on unreferenced axis, or move
#                                    attempted with servo off
POS_OUT_OF_LIMITS = 7       # Position out of limits
VEL_OUT_OF_LIMITS = 8       # Velocity out of limits
SET_PIVOT_NOT_POSSIBLE = 9  # Attempt to set pivot point while U,V and W not all 0
STOP = 10                   # Controller was stopped by command
INVALID_AXIS = 15           # Invalid axis identifier
PARAM_OUT_OF_RANGE = 17     # Parameter out of range
DOUBLE_AXIS = 22            # Axis identifier specified more than once
CMD_NOT_ALLOWED_FOR_STAGE = 34     # Command not allowed for selected stage(s)
UNKNOWN_PARAMETER = 54      # Unknown parameter
INVALID_RECORDER_CHAN = 57  # Data recorder table does not exist
INVALID_RECORDER_SRC_OPT = 58      # Source option does not exist; number too low or too high
INVALID_RECORDER_SRC_CHAN = 59     # Source ID (channel or axis) too low or too high
READ_ONLY_PARAMETER = 64    # Parameter is read-only
NOT_ENOUGH_RECORDED_DATA = 77      # Data Record Table does not hold enough recorded data
CS_DOES_NOT_EXIST = 530     # A command refers to a coordinate system that does not exist
CS_IN_USE = 532             # Attempt to delete or change a coordinate system that is in use
CS_CYCLIC = 533             # Definition of a coordinate system is cyclic
CS_WHILE_MOVING = 536       # Coordinate system cannot be defined as long as Hexapod is in motion
CS_LINKED_TO_ITSELF = 539   # A coordinate system cannot be linked to itself
CS_NOT_SAME_CHAIN = 542     # The coordinate systems are not part of the same chain
CS_UNUSED_MUST_BE_DELETED = 543    # Unused coordinate system must be deleted before new
#                                    coordinate system can be stored
SPI_NOT_WITH_CS = 544       # With this coordinate system type SPI usage is not supported
CS_WRITE_PROTECTED = 546    # Coordinate system is write protected
CS_MAY_NOT_BE_LINKED = 548  # Coordinate system may not be linked
CS_TYPE_UNKNOWN = 554       # This coordinate system type does not exist
NO_CS_OF_TYPE_ENABLED = 556  # No coordinate system of this type is enabled
CS_INVALID_NAME = 557       # Name of coordinate system is invalid
CONTROLLER_ERROR = 555      # BasMac: unknown controller error (a defect of the twin)
MOTION_ERROR = 1024         # Motion error: position error too large, servo is switched off
#                             automatically

TEXTS = {
    NO_ERROR: "No error",
    PARAM_SYNTAX: "Parameter syntax error",
    UNKNOWN_COMMAND: "Unknown command",
    COMMAND_TOO_LONG: "Command length out of limits or command buffer overrun",
    MOVE_WITHOUT_REF_OR_NO_SERVO: "Unallowable move attempted on unreferenced axis, or move "
                                  "attempted with servo off",
    POS_OUT_OF_LIMITS: "Position out of limits",
    VEL_OUT_OF_LIMITS: "Velocity out of limits",
    SET_PIVOT_NOT_POSSIBLE: "Attempt to set pivot point while U,V and W not all 0",
    STOP: "Controller was stopped by command",
    INVALID_AXIS: "Invalid axis identifier",
    PARAM_OUT_OF_RANGE: "Parameter out of range",
    DOUBLE_AXIS: "Axis identifier specified more than once",
    CMD_NOT_ALLOWED_FOR_STAGE: "Command not allowed for selected stage(s)",
    UNKNOWN_PARAMETER: "Unknown parameter",
    READ_ONLY_PARAMETER: "Parameter is read-only",
    INVALID_RECORDER_CHAN: "Data recorder table does not exist",
    INVALID_RECORDER_SRC_OPT: "Source option does not exist; number too low or too high",
    INVALID_RECORDER_SRC_CHAN: "Source ID (channel or axis) too low or too high",
    NOT_ENOUGH_RECORDED_DATA: "Data Record Table does not hold enough recorded data",
    CS_DOES_NOT_EXIST: 'A command refers to a coordinate system that does not exist',
    CS_IN_USE: 'Attempt to delete or change a coordinate system that is in use',
    CS_CYCLIC: 'Definition of a coordinate system is cyclic',
    CS_WHILE_MOVING: 'Coordinate system cannot be defined as long as Hexapod is in motion',
    CS_LINKED_TO_ITSELF: 'A coordinate system cannot be linked to itself',
    CS_NOT_SAME_CHAIN: 'The coordinate systems are not part of the same chain',
    CS_UNUSED_MUST_BE_DELETED: 'Unused coordinate system must be deleted before new coordinate '
                               'system can be stored',
    SPI_NOT_WITH_CS: 'With this coordinate system type SPI usage is not supported',
    CS_WRITE_PROTECTED: 'Coordinate system is write protected',
    CS_MAY_NOT_BE_LINKED: 'Coordinate system may not be linked',
    CS_TYPE_UNKNOWN: 'This coordinate system type does not exist',
    NO_CS_OF_TYPE_ENABLED: 'No coordinate system of this type is enabled',
    CS_INVALID_NAME: 'Name of coordinate system is invalid',
    CONTROLLER_ERROR: "BasMac: unknown controller error",
    MOTION_ERROR: "Motion error: position error too large, servo is switched off automatically",
}


class GcsError(Exception):
    """A command refused with PI's error `code`; `why` says what in the line caused it (for the
    twin's own log, never sent: GCS answers nothing to a refused command)."""

    def __init__(self, code: int, why: str = "") -> None:
        super().__init__(f"GCS error {code} ({TEXTS.get(code, '?')}){': ' + why if why else ''}")
        self.code = code
        self.why = why
