"""The live pipeline's moves that are not the washout's: the fade to neutral (telemetry lost,
park) and the ramp of the cue back in (resume), both along the project's one quintic
(controller.trajectory.minimum_jerk) and both sent through the envelope (live.envelope), which
keeps them within its limits whatever state they start from.

Fade: from the pose commanded when the fade begins to home, rest to rest, in pose coordinates.
Its duration is the shortest quintic (controller.trajectory.quintic_duration) whose leg rates
and accelerations stay within FADE_FRACTION of the envelope's speed and acceleration limits,
taken on the legs' own travel (the poses between are near the straight line in leg space over
the envelope's stroke), and never below FADE_MIN_TIME: a rig going home after a loss is a
slow, gentle move for its occupant, not a maximal one. A fade that begins while the platform
moves starts with a jump of the rate; the envelope's limited step absorbs it.

Blend: on resume the washout restarts at rest and its cue is ramped in from the pose the
platform holds: sent = start + w (cue - start) with the quintic weight w from 0 to 1 over
BLEND_TIME, the rates and accelerations by the product rule; once done, the cue itself is
sent. A resume during a fade (FADING, live.pipeline_modes) starts the ramp from the pose sent
then, still moving: the blend starts at rest, so its first sample steps the rate, and the
envelope takes that step within its limits.

Park is the same fade; once it is done the pipeline sends home at rest (Fade.sample after the
end), which the envelope passes unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.capability import Capability
from controller.trajectory import minimum_jerk, quintic_duration
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model

FADE_FRACTION = 0.25   # of the envelope's speed and acceleration limits
FADE_MIN_TIME = 1.0    # s
BLEND_TIME = 1.0       # s


@dataclass(frozen=True)
class Fade:
    """A rest-to-rest quintic from `start` to `goal` (poses) over [t0, t0 + duration]."""

    start: np.ndarray
    goal: np.ndarray
    t0: float
    duration: float

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd) at time t (s); the start before t0, the goal after the end."""
        u = min(max((t - self.t0) / self.duration, 0.0), 1.0)
        s, sd, sdd = minimum_jerk(u, self.duration)
        d = self.goal - self.start
        return self.start + s * d, sd * d, sdd * d

    def done(self, t: float) -> bool:
        return t >= self.t0 + self.duration


def fade_to_home(model: Model, limits: Capability, q, t0: float,
                 fraction: float = FADE_FRACTION, min_time: float = FADE_MIN_TIME) -> Fade:
    """The fade from pose `q` to the scene's home starting at t0 (see the module doc)."""
    start = np.array(q, dtype=float)
    home = np.asarray(model.home, dtype=float)
    travel = _lengths(model, home) - _lengths(model, start)
    duration = min_time
    if np.any(travel != 0.0):
        duration = max(min_time, quintic_duration(travel, fraction * limits.speed,
                                                  fraction * limits.acceleration))
    return Fade(start, home.copy(), float(t0), float(duration))


@dataclass(frozen=True)
class Blend:
    """The ramp of a cue in from the pose `start` (at rest) over [t0, t0 + duration]."""

    start: np.ndarray
    t0: float
    duration: float = BLEND_TIME

    def apply(self, t: float, q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pose sample to send at time t for the cue sample (q, qd, qdd)."""
        u = min(max((t - self.t0) / self.duration, 0.0), 1.0)
        w, wd, wdd = minimum_jerk(u, self.duration)
        d = np.asarray(q, dtype=float) - self.start
        qd, qdd = np.asarray(qd, dtype=float), np.asarray(qdd, dtype=float)
        return (self.start + w * d, w * qd + wd * d, w * qdd + 2.0 * wd * qd + wdd * d)

    def done(self, t: float) -> bool:
        """Whether the ramp has ended: from then on the cue itself is sent."""
        return t >= self.t0 + self.duration


def _lengths(model: Model, q: np.ndarray) -> np.ndarray:
    return inverse_kinematics(model, q, with_cond=False).lengths
