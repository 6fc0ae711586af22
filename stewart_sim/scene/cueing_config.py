"""The scene's [cueing] table: every parameter of the classical washout (washout.py), and its
[cueing.optimal] sub-table: the options of the model-predictive cueing (optimal.py), SI units.

    [cueing]
    # translational channel, per vehicle axis (x forward, y left, z up)
    translational_gain = [0.5, 0.5, 0.5]         # on the specific force's deviation from rest
    translational_limit = [4.0, 4.0, 4.0]        # m/s^2, saturation after the gain
    translational_order = 3                      # 2 or 3 (3: washout to zero position)
    translational_frequency = [2.5, 2.5, 4.0]    # rad/s, the second-order break
    translational_damping = [1.0, 1.0, 1.0]      # of the second-order factor
    translational_first_order = [0.5, 0.5, 0.5]  # rad/s, the third order's first-order break
    # position_limit = [0.3, 0.3, 0.2]           # m, per axis; absent: no limit
    # tilt coordination (low-passed specific force x, y -> pitch, roll)
    tilt_frequency = 4.0                         # rad/s, second-order low-pass
    tilt_damping = 1.0
    tilt_rate_limit = 0.0524                     # rad/s (3 deg/s)
    tilt_limit = 0.35                            # rad; 0 switches tilt coordination off
    # rotational channel, per axis (roll, pitch, yaw rates in the vehicle frame)
    rotational_gain = [0.5, 0.5, 0.5]
    rotational_limit = [0.5, 0.5, 0.5]           # rad/s, saturation after the gain
    rotational_order = 2                         # 1 or 2 (2: the angle returns to zero)
    rotational_frequency = [1.0, 1.0, 1.0]       # rad/s
    rotational_damping = [1.0, 1.0, 1.0]         # second order only
    # where the person's head is (m, platform frame, from its origin): perception is taken there
    head = [0.0, 0.0, 0.0]                       # each |component| <= 5 m

    [cueing.optimal]
    rate = 20.0                        # Hz, MPC steps; horizon * rate: 2 to 200 steps
    horizon = 2.0                      # s
    preview = true                     # the future vehicle motion is known over the horizon
    stroke_margin = 0.02               # m kept from each end of the stroke
    force_margin = 0.05                # fraction of Kf I_max kept free, in [0, 1)
    voltage_margin = 0.05              # fraction of V_max kept free, in [0, 1)
    # tilt_rate_limit = 0.0524         # rad/s; absent: [cueing] tilt_rate_limit
    perception_weight = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]   # f x, y, z, omega x, y, z
    position_weight = [1.0, 1.0, 1.0]  # per m^2
    velocity_weight = [1.0, 1.0, 1.0]  # per (m/s)^2
    yaw_weight = 1.0                   # per rad^2
    rate_weight = [0.0, 0.0, 0.0]      # per (rad/s)^2
    acceleration_weight = [0.01, 0.01, 0.01]           # per (m/s^2)^2
    angular_acceleration_weight = [0.01, 0.01, 0.01]   # per (rad/s^2)^2
    slack_weight = [1000.0, 1000.0]    # linear, quadratic on the stroke slack
    terminal_weight = 100.0            # washout weights at the horizon's end, times this
    tolerance = 0.001                  # OSQP eps_abs = eps_rel
    max_iter = 20000                   # OSQP iterations per MPC step

Every key is optional (the default above); the tables themselves are optional (all defaults).
The values are those of DEFAULTS and OptimalOptions() below; why they are what they are is
said there.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Mapping

import numpy as np

from stewart_fmu.errors import SceneKeyError
from stewart_fmu.model import Model

TABLE = "cueing"
TILT_RATE_THRESHOLD = np.deg2rad(3.0)  # rad/s: the usual tilt-rate perception threshold


@dataclass(frozen=True)
class CueingConfig:
    """The classical washout's parameters (Reid & Nahon 1985; Nahon & Reid 1990), SI units:
    gains dimensionless, limits m/s^2 and rad/s, frequencies rad/s, angles rad.

    Defaults: break frequencies and damping of the order the classical-washout literature
    uses (second-order translational breaks of a few rad/s, a first-order break a decade
    lower, rotational breaks about 1 rad/s, damping 1 (no overshoot in the washout)), gains
    of 0.5 (the usual scaling of a full-size simulator), tuned so that
    scenes/motion_simulator.toml stays inside its stroke for the shipped vehicle motions
    (braking, lane change, take-off roll and rotation; tests/app/test_cueing_*.py). The tilt rate
    limit is the 3 deg/s perception threshold of tilt (Groen & Bles 2004, "How to use body
    tilt for the simulation of linear self motion", J. Vestibular Research 14); the classical
    algorithm limits the tilt rate so that the tilt itself goes unnoticed (Reid & Nahon 1985).
    """

    translational_gain: tuple[float, float, float] = (0.5, 0.5, 0.5)
    translational_limit: tuple[float, float, float] = (4.0, 4.0, 4.0)
    translational_order: int = 3
    translational_frequency: tuple[float, float, float] = (2.5, 2.5, 4.0)
    translational_damping: tuple[float, float, float] = (1.0, 1.0, 1.0)
    translational_first_order: tuple[float, float, float] = (0.5, 0.5, 0.5)
    tilt_frequency: float = 4.0
    tilt_damping: float = 1.0
    tilt_rate_limit: float = float(TILT_RATE_THRESHOLD)
    tilt_limit: float = 0.35
    rotational_gain: tuple[float, float, float] = (0.5, 0.5, 0.5)
    rotational_limit: tuple[float, float, float] = (0.5, 0.5, 0.5)
    rotational_order: int = 2
    rotational_frequency: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rotational_damping: tuple[float, float, float] = (1.0, 1.0, 1.0)
    # m per axis (x, y, z): the translational position's soft limit (washout_step.soft_limit);
    # None: no limit (the filters' position as it is)
    position_limit: tuple[float, float, float] | None = None
    # The pilot's head in the platform frame C (m, from C's origin): perception (vestibular.py)
    # is taken there, where a rotation adds its tangential and centripetal accelerations. The
    # washout above does not use it: it moves the platform's origin as it always has.
    head: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class OptimalOptions:
    """The model-predictive cueing's (optimal.py) rate, horizon, margins, weights and solver
    settings (defaults: the shipped motion simulator), the scene's [cueing.optimal] table.

    Weights are per unit of: position m, velocity m/s, yaw rad, angular rate rad/s,
    acceleration m/s^2, angular acceleration rad/s^2; the perceived error is counted in
    perception thresholds (its weight is `perception_weight` / threshold^2)."""

    rate: float = 20.0                 # Hz, MPC steps
    horizon: float = 2.0               # s
    preview: bool = True               # future vehicle motion known over the horizon
    stroke_margin: float = 0.02        # m, kept from each end of the stroke
    force_margin: float = 0.05         # fraction of Kf I_max kept free
    voltage_margin: float = 0.05       # fraction of V_max kept free
    tilt_rate_limit: float | None = None   # rad/s; None: the [cueing] table's
    # per axis: specific force x, y, z, angular velocity x, y, z
    perception_weight: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    position_weight: tuple[float, float, float] = (1.0, 1.0, 1.0)
    velocity_weight: tuple[float, float, float] = (1.0, 1.0, 1.0)
    yaw_weight: float = 1.0
    rate_weight: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acceleration_weight: tuple[float, float, float] = (0.01, 0.01, 0.01)
    angular_acceleration_weight: tuple[float, float, float] = (0.01, 0.01, 0.01)
    slack_weight: tuple[float, float] = (1e3, 1e3)   # linear, quadratic, per fraction of half-range
    # the washout weights at the horizon's last step, times this: what the horizon leaves
    # beyond its end is the platform's state, so it must not be left drifting (without it, a
    # sustained tilt's small f_z loss kept the platform 0.1-0.4 m up, accelerating upward at
    # the end of every horizon)
    terminal_weight: float = 100.0
    tolerance: float = 1e-3            # OSQP eps_abs = eps_rel (then polished: active set exact)
    max_iter: int = 20000
    # MPC steps per prediction step: the QP's grid is blocking / rate s, its inputs held over
    # each (move blocking); the state is still advanced and re-solved every MPC step. 1: the
    # grid is the MPC step. A QP about `blocking` times smaller: the live mode's lever
    blocking: int = 1


DEFAULTS = CueingConfig()
# key -> (kind, lower bound, whether the bound itself is allowed); kind "vector" is 3 numbers.
_RULES: dict[str, tuple[str, float, bool]] = {
    "translational_gain": ("vector", 0.0, True),
    "translational_limit": ("vector", 0.0, False),
    "translational_frequency": ("vector", 0.0, False),
    "translational_damping": ("vector", 0.0, False),
    "translational_first_order": ("vector", 0.0, False),
    "tilt_frequency": ("number", 0.0, False),
    "tilt_damping": ("number", 0.0, False),
    "tilt_rate_limit": ("number", 0.0, False),
    "tilt_limit": ("number", 0.0, True),
    "rotational_gain": ("vector", 0.0, True),
    "rotational_limit": ("vector", 0.0, False),
    "rotational_frequency": ("vector", 0.0, False),
    "rotational_damping": ("vector", 0.0, False),
    "position_limit": ("vector", 0.0, False),
}
_ORDERS = {"translational_order": (2, 3), "rotational_order": (1, 2)}
HEAD = "head"
# m: how far from the platform's origin the head may be, per axis. The largest motion
# simulators' cabins are a few metres across; a head farther out is a unit slip (cm for m).
HEAD_REACH = 5.0
_KEYS = {f.name for f in fields(CueingConfig)}
TILT_LIMIT_MAX = np.pi / 2  # rad: asin(f / g) never exceeds it

OPTIMAL = "optimal"   # the [cueing.optimal] sub-table
# The MPC's horizon in steps (round(horizon * rate)): at least 2 (one step is no prediction);
# at most 200, ten times the default 40 (the QP's size and each step's solve time grow with
# it: 200 steps is 10 s at the default 20 Hz, beyond any washout's time constant).
MPC_STEPS = (2, 200)
# key -> (kind, lower bound, whether the bound itself is allowed); kind "number", "boolean",
# "count" (an integer), or the length of a list of numbers. Every OptimalOptions field is a
# user's tuning parameter: all are keys. Upper bounds checked in optimal_options.
_OPTIMAL_RULES: dict[str, tuple[str, float, bool]] = {
    "rate": ("number", 0.0, False),
    "horizon": ("number", 0.0, False),
    "preview": ("boolean", 0.0, True),
    "stroke_margin": ("number", 0.0, True),
    "force_margin": ("number", 0.0, True),
    "voltage_margin": ("number", 0.0, True),
    "tilt_rate_limit": ("number", 0.0, False),
    "perception_weight": ("6", 0.0, True),
    "position_weight": ("3", 0.0, True),
    "velocity_weight": ("3", 0.0, True),
    "yaw_weight": ("number", 0.0, True),
    "rate_weight": ("3", 0.0, True),
    "acceleration_weight": ("3", 0.0, True),
    "angular_acceleration_weight": ("3", 0.0, True),
    "slack_weight": ("2", 0.0, False),
    "terminal_weight": ("number", 0.0, True),
    "tolerance": ("number", 0.0, False),
    "max_iter": ("count", 1.0, True),
    "blocking": ("count", 1.0, True),
}
_VECTOR_AXES = {
    2: " (linear, quadratic)",
    3: " (x, y, z or roll, pitch, yaw)",
    6: " (specific force x, y, z, angular velocity x, y, z)",
}


def cueing_config(model: Model) -> CueingConfig:
    """The [cueing] table of the model's scene, checked (SceneKeyError names the key); the
    defaults when the table or a key is absent."""
    return cueing_tables(model)[0]


def cueing_tables(model: Model) -> tuple[CueingConfig, OptimalOptions]:
    """[cueing] and its [cueing.optimal] sub-table, each checked and parsed once."""
    table = model.extra.get(TABLE)
    if table is None:
        return DEFAULTS, OptimalOptions()
    if not isinstance(table, Mapping):
        raise SceneKeyError(TABLE, f"must be a table, got {table!r}", model.source)
    unknown = sorted(set(table) - _KEYS - {OPTIMAL})
    if unknown:
        raise SceneKeyError(f"{TABLE}.{unknown[0]}", f"unknown key (allowed: "
                            f"{sorted(_KEYS | {OPTIMAL})})", model.source)
    # the sub-table is checked with the table: a typo there fails every cueing run, not only
    # the optimal mode's
    optimal = optimal_options(model)
    values: dict[str, Any] = {}
    for key in sorted(set(table) - {OPTIMAL}):
        if key in _ORDERS:
            values[key] = _order(table[key], key, model.source)
        elif key == HEAD:
            values[key] = _head(table[key], model.source)
        else:
            kind, low, closed = _RULES[key]
            read = _vector if kind == "vector" else _number
            values[key] = read(table[key], f"{TABLE}.{key}", low, closed, model.source)
    if values.get("tilt_limit", DEFAULTS.tilt_limit) >= TILT_LIMIT_MAX:
        raise SceneKeyError(f"{TABLE}.tilt_limit", f"must be below pi/2 rad, got "
                            f"{values['tilt_limit']!r}", model.source)
    return CueingConfig(**values), optimal


def optimal_options(model: Model) -> OptimalOptions:
    """The [cueing.optimal] table of the model's scene, checked (SceneKeyError names
    `cueing.optimal.<key>`); OptimalOptions() when the table or a key is absent."""
    table = model.extra.get(TABLE)
    if not isinstance(table, Mapping) or OPTIMAL not in table:
        return OptimalOptions()
    sub = table[OPTIMAL]
    name = f"{TABLE}.{OPTIMAL}"
    if not isinstance(sub, Mapping):
        raise SceneKeyError(name, f"must be a table, got {sub!r}", model.source)
    unknown = sorted(set(sub) - set(_OPTIMAL_RULES))
    if unknown:
        raise SceneKeyError(f"{name}.{unknown[0]}", f"unknown key (allowed: "
                            f"{sorted(_OPTIMAL_RULES)})", model.source)
    values: dict[str, Any] = {}
    for key in sorted(sub):
        kind, low, closed = _OPTIMAL_RULES[key]
        x, full = sub[key], f"{name}.{key}"
        if kind == "boolean":
            if not isinstance(x, bool):
                raise SceneKeyError(full, f"must be true or false, got {x!r}", model.source)
            values[key] = x
        elif kind == "count":
            if isinstance(x, bool) or not isinstance(x, int) or x < low:
                raise SceneKeyError(full, f"must be an integer >= {low:g}, got {x!r}",
                                    model.source)
            values[key] = int(x)
        elif kind == "number":
            values[key] = _number(x, full, low, closed, model.source)
        else:
            values[key] = _vector(x, full, low, closed, model.source, n=int(kind))
    options = OptimalOptions(**values)
    steps = round(options.horizon * options.rate)
    if not MPC_STEPS[0] <= steps <= MPC_STEPS[1]:
        raise SceneKeyError(f"{name}.horizon", f"horizon x rate must give {MPC_STEPS[0]} to "
                            f"{MPC_STEPS[1]} MPC steps, got {options.horizon:g} s x "
                            f"{options.rate:g} Hz = {steps}", model.source)
    for key in ("force_margin", "voltage_margin"):
        if getattr(options, key) >= 1.0:
            raise SceneKeyError(f"{name}.{key}", f"must be below 1 (a fraction of the limit "
                                f"kept free), got {getattr(options, key)!r}", model.source)
    if model.leg_min is not None and model.leg_max is not None:
        half = 0.5 * (model.leg_max - model.leg_min)
        if options.stroke_margin >= half:
            raise SceneKeyError(f"{name}.stroke_margin", f"must be below half the stroke "
                                f"({half:g} m), got {options.stroke_margin!r}", model.source)
    return options


def _number(x: Any, name: str, low: float, closed: bool, source: str | None) -> float:
    bound = f">= {low:g}" if closed else f"> {low:g}"
    if (isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x)
            or x < low or (x == low and not closed)):
        raise SceneKeyError(name, f"must be a finite number {bound}, got {x!r}", source)
    return float(x)


def _vector(x: Any, name: str, low: float, closed: bool, source: str | None,
            n: int = 3) -> tuple[float, ...]:
    if not isinstance(x, (list, tuple)) or len(x) != n:
        what = _VECTOR_AXES.get(n, "")
        raise SceneKeyError(name, f"must be a list of {n} numbers{what}, got {x!r}", source)
    return tuple(_number(v, name, low, closed, source) for v in x)


def _head(x: Any, source: str | None) -> tuple[float, float, float]:
    """[cueing] head: 3 finite numbers (x, y, z), each within +-HEAD_REACH metres."""
    name = f"{TABLE}.{HEAD}"
    if not isinstance(x, (list, tuple)) or len(x) != 3:
        raise SceneKeyError(name, f"must be a list of 3 numbers (x, y, z in m, platform frame), "
                            f"got {x!r}", source)
    for v in x:
        if (isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v)
                or abs(v) > HEAD_REACH):
            raise SceneKeyError(name, f"each coordinate must be a finite number of metres "
                                f"within +-{HEAD_REACH:g}, got {v!r}", source)
    return (float(x[0]), float(x[1]), float(x[2]))


def _order(x: Any, key: str, source: str | None) -> int:
    allowed = _ORDERS[key]
    if isinstance(x, bool) or not isinstance(x, int) or x not in allowed:
        raise SceneKeyError(f"{TABLE}.{key}", f"must be one of {allowed}, got {x!r}", source)
    return int(x)
