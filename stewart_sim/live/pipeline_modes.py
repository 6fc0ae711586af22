"""The live cueing pipeline's mode: one enum, one table of (mode, event) -> transition, as
hil.operating_mode is the device's.

The pipeline holds one `Mode` and moves it only through `transition`; what each mode sends is
the pipeline's (the washout's cue through live.envelope.Envelope.step, a fade of
live.fade through the same step, or Envelope.brake). Every pair of the table is written out:
an accepted event gives the next mode (possibly the same), a refused one keeps the mode and
gives the reason (for the operator's commands, the line the pipeline reports).

Modes
  STARTING   at home at rest, waiting for telemetry (at start, and after a fade reached home):
             the platform holds home
  RUNNING    following the telemetry: washout -> envelope -> setpoints; the loss timer runs
  FADING     the telemetry stopped (no datagram for the loss time): the platform fades to home
             along live.fade's quintic, within the envelope; telemetry that comes back
             resumes RUNNING from where the fade got to
  PARKING    the operator's park: the same fade to home, telemetry ignored
  PARKED     at home at rest, telemetry ignored until the operator resumes
  STOPPED    the emergency stop: every leg braked as hard as the envelope allows
             (Envelope.brake), then held where the platform stopped; only a park (the slow
             way home) or another stop is accepted, so nothing moves the platform with
             telemetry again before it has been brought home and resumed

Events
  TELEMETRY  a valid telemetry sample arrived
  LOSS       no valid telemetry for the loss time (the timer runs only while RUNNING)
  PARK       the operator's park command (also Ctrl-C's, before the command exits)
  ESTOP      the operator's emergency stop
  FADE_DONE  the fade (FADING's or PARKING's) reached home
  RESUME     the operator's resume: a parked platform waits for telemetry again

Resuming (STARTING or FADING -> RUNNING on TELEMETRY): the washout restarts at rest (its filters
reset, so its cue starts at neutral, home, at rest) and the cue is ramped in from the pose the
platform holds, live.fade.Blend: the pose sent is start + w (cue - start) along the minimum-jerk
weight w (controller.trajectory.minimum_jerk) from 0 to 1, so neither a jump of the pose nor one
of its rate reaches the envelope.

What an operator expects (FlyPT Mover's and the motion4sim controller's park and emergency
commands): park takes the rig home slowly and keeps it there; an emergency stop stops the
motion at once and does not move the rig again by itself, it waits for the operator.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass


class Mode(enum.Enum):
    """The live pipeline's mode (see the module doc)."""

    STARTING = "starting"
    RUNNING = "running"
    FADING = "fading"
    PARKING = "parking"
    PARKED = "parked"
    STOPPED = "stopped"


class Event(enum.Enum):
    """What can move the mode (see the module doc)."""

    TELEMETRY = "telemetry"
    LOSS = "loss"
    PARK = "park"
    ESTOP = "estop"
    FADE_DONE = "fade done"
    RESUME = "resume"


@dataclass(frozen=True)
class Transition:
    """The mode after an event, and why the event was refused (None: accepted)."""

    mode: Mode
    refusal: str | None = None


TELEMETRY_PARKED = "telemetry ignored: parked (resume first)"
TELEMETRY_PARKING = "telemetry ignored: parking"
TELEMETRY_STOPPED = "telemetry ignored: emergency stop (park, then resume)"
RESUME_STOPPED = "resume refused: emergency stop (park first: the platform goes home)"
RESUME_NOT_PARKED = "resume refused: not parked"
_NO_LOSS = "the loss timer runs only while running"
_NOT_FADING = "no fade under way"

S, R, F, P, K, X = (Mode.STARTING, Mode.RUNNING, Mode.FADING, Mode.PARKING, Mode.PARKED,
                    Mode.STOPPED)
E = Event

#: Every (mode, event) pair: the transition.
TABLE: dict[tuple[Mode, Event], Transition] = {
    (S, E.TELEMETRY): Transition(R),
    (S, E.LOSS): Transition(S, _NO_LOSS),
    (S, E.PARK): Transition(P),
    (S, E.ESTOP): Transition(X),
    (S, E.FADE_DONE): Transition(S, _NOT_FADING),
    (S, E.RESUME): Transition(S, RESUME_NOT_PARKED),

    (R, E.TELEMETRY): Transition(R),
    (R, E.LOSS): Transition(F),
    (R, E.PARK): Transition(P),
    (R, E.ESTOP): Transition(X),
    (R, E.FADE_DONE): Transition(R, _NOT_FADING),
    (R, E.RESUME): Transition(R, RESUME_NOT_PARKED),

    (F, E.TELEMETRY): Transition(R),
    (F, E.LOSS): Transition(F, _NO_LOSS),
    (F, E.PARK): Transition(P),
    (F, E.ESTOP): Transition(X),
    (F, E.FADE_DONE): Transition(S),
    (F, E.RESUME): Transition(F, RESUME_NOT_PARKED),

    (P, E.TELEMETRY): Transition(P, TELEMETRY_PARKING),
    (P, E.LOSS): Transition(P, _NO_LOSS),
    (P, E.PARK): Transition(P),
    (P, E.ESTOP): Transition(X),
    (P, E.FADE_DONE): Transition(K),
    (P, E.RESUME): Transition(P, RESUME_NOT_PARKED),

    (K, E.TELEMETRY): Transition(K, TELEMETRY_PARKED),
    (K, E.LOSS): Transition(K, _NO_LOSS),
    (K, E.PARK): Transition(K),
    (K, E.ESTOP): Transition(X),
    (K, E.FADE_DONE): Transition(K, _NOT_FADING),
    (K, E.RESUME): Transition(S),

    (X, E.TELEMETRY): Transition(X, TELEMETRY_STOPPED),
    (X, E.LOSS): Transition(X, _NO_LOSS),
    (X, E.PARK): Transition(P),
    (X, E.ESTOP): Transition(X),
    (X, E.FADE_DONE): Transition(X, _NOT_FADING),
    (X, E.RESUME): Transition(X, RESUME_STOPPED),
}
del S, R, F, P, K, X, E


def transition(mode: Mode, event: Event) -> Transition:
    """What `event` does in `mode` (the one rule of the pipeline's mode)."""
    return TABLE[(mode, event)]


def follows_telemetry(mode: Mode) -> bool:
    """Whether the washout's cue is sent (only while RUNNING)."""
    return mode is Mode.RUNNING


def fading(mode: Mode) -> bool:
    """Whether the platform is on its way home along a fade (FADING, PARKING)."""
    return mode in (Mode.FADING, Mode.PARKING)


def at_rest(mode: Mode) -> bool:
    """Whether the platform holds still (STARTING, PARKED: at home; STOPPED: where it
    stopped, once the brake has stopped it)."""
    return mode in (Mode.STARTING, Mode.PARKED, Mode.STOPPED)
