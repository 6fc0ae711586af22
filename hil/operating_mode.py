"""The emulated device's mode: one enum, one table of (mode, event) -> transition.

`hil.device.Device` holds one `Mode` and moves it only through `transition` (what each move does
to the drives' references is the device's, in hil.device and hil.servo). Every pair of the table
is written out: an accepted event gives the next mode (possibly the same), a refused one keeps
the mode and gives the reason, which for the host's events (SETPOINT, HOME) is the STATUSTEXT
the device sends.

Modes
  DISARMED   the drives hold the leg lengths measured at disarm (at start: the scene's home);
             valid setpoints are ignored (one STATUSTEXT per disarmed period), homing refused
  ARMED      armed, holding the lengths measured at arming (or the home lengths once homing
             ends); the watchdog waits for the first valid setpoint
  TRACKING   armed, following the valid setpoints (HOLD: the lengths measured then); the
             watchdog runs: `watchdog` s without a valid setpoint trips it
  HOMING     armed, moving to the scene's home lengths along a quintic in leg space; the
             watchdog waits; a valid setpoint takes over
  TRIPPED    armed, the watchdog tripped: holding the lengths measured at the trip; the next
             valid setpoint (or a re-arm) resumes

Events
  ARM, DISARM        MAV_CMD_COMPONENT_ARM_DISARM with param1 1 or 0 (any other param1 is
                     refused by the command's check, whatever the mode)
  HOME               MAV_CMD_NAV_RETURN_TO_LAUNCH
  SETPOINT           a LEG_SETPOINT that passed its checks (an invalid one is refused by them,
                     whatever the mode)
  WATCHDOG_EXPIRED   a tick found `watchdog` s without a valid setpoint (checked only while
                     TRACKING)
  HOMING_DONE        the homing quintic reached its end this tick
  FAULT              the plant refused a step (an end stop) or the tick failed numerically: the
                     plant restarts at rest, drives holding, disarmed
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

from hil import mavlink_stewart as ms


class Mode(enum.Enum):
    """The device's mode (see the module doc)."""

    DISARMED = "disarmed"
    ARMED = "armed"
    TRACKING = "tracking"
    HOMING = "homing"
    TRIPPED = "tripped"


class Event(enum.Enum):
    """What can move the mode (see the module doc)."""

    ARM = "arm"
    DISARM = "disarm"
    HOME = "home"
    SETPOINT = "setpoint"
    WATCHDOG_EXPIRED = "watchdog expired"
    HOMING_DONE = "homing done"
    FAULT = "fault"


@dataclass(frozen=True)
class Transition:
    """The mode after an event, and why the event was refused (None: accepted)."""

    mode: Mode
    refusal: str | None = None


SETPOINT_DISARMED = "setpoints ignored: disarmed (arm first)"
HOME_DISARMED = "home refused: disarmed"
_NO_WATCHDOG = "the watchdog runs only while tracking"
_NOT_HOMING = "not homing"

D, A, T, H, W = Mode.DISARMED, Mode.ARMED, Mode.TRACKING, Mode.HOMING, Mode.TRIPPED

#: Every (mode, event) pair: the transition.
TABLE: dict[tuple[Mode, Event], Transition] = {
    (D, Event.ARM): Transition(A),
    (D, Event.DISARM): Transition(D),
    (D, Event.HOME): Transition(D, HOME_DISARMED),
    (D, Event.SETPOINT): Transition(D, SETPOINT_DISARMED),
    (D, Event.WATCHDOG_EXPIRED): Transition(D, _NO_WATCHDOG),
    (D, Event.HOMING_DONE): Transition(D, _NOT_HOMING),
    (D, Event.FAULT): Transition(D),

    (A, Event.ARM): Transition(A),
    (A, Event.DISARM): Transition(D),
    (A, Event.HOME): Transition(H),
    (A, Event.SETPOINT): Transition(T),
    (A, Event.WATCHDOG_EXPIRED): Transition(A, _NO_WATCHDOG),
    (A, Event.HOMING_DONE): Transition(A, _NOT_HOMING),
    (A, Event.FAULT): Transition(D),

    (T, Event.ARM): Transition(A),
    (T, Event.DISARM): Transition(D),
    (T, Event.HOME): Transition(H),
    (T, Event.SETPOINT): Transition(T),
    (T, Event.WATCHDOG_EXPIRED): Transition(W),
    (T, Event.HOMING_DONE): Transition(T, _NOT_HOMING),
    (T, Event.FAULT): Transition(D),

    (H, Event.ARM): Transition(A),
    (H, Event.DISARM): Transition(D),
    (H, Event.HOME): Transition(H),
    (H, Event.SETPOINT): Transition(T),
    (H, Event.WATCHDOG_EXPIRED): Transition(H, _NO_WATCHDOG),
    (H, Event.HOMING_DONE): Transition(A),
    (H, Event.FAULT): Transition(D),

    (W, Event.ARM): Transition(A),
    (W, Event.DISARM): Transition(D),
    (W, Event.HOME): Transition(H),
    (W, Event.SETPOINT): Transition(T),
    (W, Event.WATCHDOG_EXPIRED): Transition(W, _NO_WATCHDOG),
    (W, Event.HOMING_DONE): Transition(W, _NOT_HOMING),
    (W, Event.FAULT): Transition(D),
}
del D, A, T, H, W


def transition(mode: Mode, event: Event) -> Transition:
    """What `event` does in `mode` (the one rule of the device's mode)."""
    return TABLE[(mode, event)]


def armed(mode: Mode) -> bool:
    """Whether the drives follow the host (any mode but DISARMED)."""
    return mode is not Mode.DISARMED


#: The watchdog's state on the wire (DRIVE_STATUS.watchdog) in each mode.
WATCHDOG_STATE = {Mode.DISARMED: ms.STEWART_WATCHDOG_IDLE, Mode.ARMED: ms.STEWART_WATCHDOG_IDLE,
                  Mode.TRACKING: ms.STEWART_WATCHDOG_OK, Mode.HOMING: ms.STEWART_WATCHDOG_IDLE,
                  Mode.TRIPPED: ms.STEWART_WATCHDOG_TRIPPED}
