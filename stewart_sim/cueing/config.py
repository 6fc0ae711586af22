"""The scene's [cueing] table: every parameter of the classical washout (washout.py), SI units.

    [cueing]
    # translational channel, per vehicle axis (x forward, y left, z up)
    translational_gain = [0.5, 0.5, 0.5]         # on the specific force's deviation from rest
    translational_limit = [4.0, 4.0, 4.0]        # m/s^2, saturation after the gain
    translational_order = 3                      # 2 or 3 (3: washout to zero position)
    translational_frequency = [2.5, 2.5, 4.0]    # rad/s, the second-order break
    translational_damping = [1.0, 1.0, 1.0]      # of the second-order factor
    translational_first_order = [0.5, 0.5, 0.5]  # rad/s, the third order's first-order break
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

Every key is optional (the default above); the table itself is optional (all defaults). The
values are those of DEFAULTS below; why they are what they are is said there.
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
    (braking, lane change, take-off roll and rotation; tests/app/cueing). The tilt rate
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
}
_ORDERS = {"translational_order": (2, 3), "rotational_order": (1, 2)}
_KEYS = {f.name for f in fields(CueingConfig)}
TILT_LIMIT_MAX = np.pi / 2  # rad: asin(f / g) never exceeds it


def cueing_config(model: Model) -> CueingConfig:
    """The [cueing] table of the model's scene, checked (SceneKeyError names the key); the
    defaults when the table or a key is absent."""
    table = model.extra.get(TABLE)
    if table is None:
        return DEFAULTS
    if not isinstance(table, Mapping):
        raise SceneKeyError(TABLE, f"must be a table, got {table!r}", model.source)
    unknown = sorted(set(table) - _KEYS)
    if unknown:
        raise SceneKeyError(f"{TABLE}.{unknown[0]}", f"unknown key (allowed: {sorted(_KEYS)})",
                            model.source)
    values: dict[str, Any] = {}
    for key in sorted(table):
        if key in _ORDERS:
            values[key] = _order(table[key], key, model.source)
        else:
            kind, low, closed = _RULES[key]
            read = _vector if kind == "vector" else _number
            values[key] = read(table[key], key, low, closed, model.source)
    if values.get("tilt_limit", DEFAULTS.tilt_limit) >= TILT_LIMIT_MAX:
        raise SceneKeyError(f"{TABLE}.tilt_limit", f"must be below pi/2 rad, got "
                            f"{values['tilt_limit']!r}", model.source)
    return CueingConfig(**values)


def _number(x: Any, key: str, low: float, closed: bool, source: str | None) -> float:
    bound = f">= {low:g}" if closed else f"> {low:g}"
    if (isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x)
            or x < low or (x == low and not closed)):
        raise SceneKeyError(f"{TABLE}.{key}", f"must be a finite number {bound}, got {x!r}",
                            source)
    return float(x)


def _vector(x: Any, key: str, low: float, closed: bool,
            source: str | None) -> tuple[float, float, float]:
    if not isinstance(x, (list, tuple)) or len(x) != 3:
        raise SceneKeyError(f"{TABLE}.{key}", f"must be a list of 3 numbers (x, y, z or roll, "
                            f"pitch, yaw), got {x!r}", source)
    return tuple(_number(v, key, low, closed, source) for v in x)  # type: ignore[return-value]


def _order(x: Any, key: str, source: str | None) -> int:
    allowed = _ORDERS[key]
    if isinstance(x, bool) or not isinstance(x, int) or x not in allowed:
        raise SceneKeyError(f"{TABLE}.{key}", f"must be one of {allowed}, got {x!r}", source)
    return int(x)
