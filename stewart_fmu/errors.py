"""Typed errors: every failure names the input and the reason."""
from __future__ import annotations


class StewartError(Exception):
    """Base of every error this package raises on purpose."""


FILE_KEY = "<file>"  # SceneError.key when the file itself is at fault (missing, not TOML)


class SceneError(StewartError, ValueError):
    """A scene file or table is malformed or non-physical; `key` names the offending key."""

    def __init__(self, key: str, reason: str, source: str | None = None):
        self.key, self.reason, self.source = key, reason, source
        where = f"{source}: " if source else ""
        what = "" if key == FILE_KEY else f"scene key '{key}': "
        super().__init__(f"{where}{what}{reason}")


class SceneKeyError(SceneError):
    """A key breaks its own rule (missing, unknown, wrong type or shape, out of its range):
    wrong whatever the scene's other values are. Other SceneErrors are relations between
    keys (leg_max above leg_min, a home pose within the stroke): a design sweep makes a point
    that breaks one a row with its error, and refuses a grid whose values break a key's rule."""


class TrajectoryError(StewartError, ValueError):
    """A trajectory (file or arrays) is malformed: wrong columns, shapes or non-finite values.

    `index` and `time` locate the sample when known (the message already names it)."""

    def __init__(self, message: str, index: int | None = None, time: float | None = None):
        self.index, self.time = index, time
        super().__init__(message)


class KinematicsError(StewartError):
    """A pose cannot be reached or computed; `index`/`time` locate the sample when known."""

    def __init__(self, message: str, index: int | None = None, time: float | None = None):
        self.index, self.time = index, time
        loc = ""
        if index is not None:
            loc = f" at sample {index}" + (f" (t = {time!r} s)" if time is not None else "")
        super().__init__(message + loc)


class ForwardKinematicsError(KinematicsError):
    """Newton's method for the pose from leg lengths did not converge."""


class StrokeLimitError(KinematicsError):
    """A leg length lies outside [leg_min, leg_max]."""


class SingularityError(KinematicsError):
    """The leg Jacobian (or the Euler-rate matrix) is singular or nearly so at a pose."""


class IntegrationError(StewartError):
    """A step went numerically unstable (non-finite state, or energy growing beyond what the
    inputs supply); the state stays at the start of the step. `time`, `method`, `step` (the
    internal step, s) and `stable_step` (the explicit stability limit there, s) locate it."""

    def __init__(self, message: str, time: float, method: str, step: float,
                 stable_step: float | None = None):
        self.time, self.method, self.step, self.stable_step = time, method, step, stable_step
        super().__init__(message)


class SweepError(StewartError, ValueError):
    """A design sweep (GRID.toml, its output directory, its cluster) is at fault; `key` names the
    grid key when one is."""

    def __init__(self, key: str | None, reason: str, source: str | None = None):
        self.key, self.reason, self.source = key, reason, source
        where = f"{source}: " if source else ""
        what = "" if key is None else f"grid key '{key}': "
        super().__init__(f"{where}{what}{reason}")


class UnstablePoseError(KinematicsError):
    """The pose is not a stable static equilibrium on the elastic legs: the loads' geometric
    stiffness outweighs the springs in some direction (the stiffness is not positive definite)."""
