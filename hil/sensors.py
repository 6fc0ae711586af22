"""The emulated device's sensors: what it reports of its legs, as a real machine's sensors would.

A scene's `[sensors]` table (`SensorConfig`, checked by `sensor_config`) describes the encoders,
the force and current measurement and their delay; the device (hil.device) applies it to what it
REPORTS (LEG_STATE's lengths, rates and forces, DRIVE_STATUS's currents), never to what its
drive loops and plant use. With `stewart-sim device --truth TRUE.toml` the truth scene's table
is the one used: it describes the machine.

The measurement reported on tick k (`Sensors.sample`) is the true state of tick k - n, n the
latency in device ticks (before tick n: the state the device started in), with the leg lengths
rounded to the encoder resolution (round(l / res) * res: an absolute encoder whose zero is the
frame's; rates are not quantised, they stand for the drive's velocity estimate) and
independent Gaussian noise of standard deviation `force_noise` on each rack force and
`current_noise` on each motor current, drawn on every tick from numpy's PCG64 seeded with
`seed` (so a run is reproducible, whatever the telemetry rates). All zero: ideal sensors, the
default, and the device reports its plant's own numbers (bit for bit).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

import numpy as np

from stewart_fmu.errors import SceneKeyError
from stewart_fmu.model import Model

# Physical bounds of each key: (low, high, unit); low is allowed (0: ideal).
SENSOR_BOUNDS: dict[str, tuple[float, float, str]] = {
    "encoder_resolution": (0.0, 1e-3, "m"),   # coarser than 1 mm is no leg encoder
    "force_noise": (0.0, 1e5, "N"),
    "current_noise": (0.0, 1e2, "A"),
    "latency": (0.0, 1.0, "s"),
}
SEED_MAX = 2**63 - 1
TICK_TOLERANCE = 1e-9   # relative: latency * rate must be this close to a whole number


@dataclass(frozen=True)
class SensorConfig:
    """The [sensors] table: encoder resolution (m), force noise (N, std), current noise (A,
    std), latency (s, whole device ticks), seed of the noise."""

    encoder_resolution: float = 0.0
    force_noise: float = 0.0
    current_noise: float = 0.0
    latency: float = 0.0
    seed: int = 0

    @property
    def ideal(self) -> bool:
        """No quantisation, no noise, no delay: the plant's own numbers are reported."""
        return not (self.encoder_resolution or self.force_noise or self.current_noise
                    or self.latency)


def sensor_config(model: Model) -> SensorConfig:
    """The [sensors] table of the model's scene, checked (SceneKeyError names sensors.<key>);
    absent: ideal sensors."""
    table = model.extra.get("sensors")
    if table is None:
        return SensorConfig()
    if not isinstance(table, Mapping):
        raise SceneKeyError("sensors", f"must be a table, got {table!r}", model.source)
    allowed = [f.name for f in fields(SensorConfig)]
    for key in sorted(set(table) - set(allowed)):
        raise SceneKeyError(f"sensors.{key}", f"unknown key (allowed: {allowed})", model.source)
    values: dict[str, Any] = {}
    for key, (lo, hi, unit) in SENSOR_BOUNDS.items():
        if key in table:
            x = table[key]
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) \
                    or not lo <= x <= hi:
                raise SceneKeyError(f"sensors.{key}", f"must be a finite number in [{lo:g}, "
                                    f"{hi:g}] {unit}, got {x!r}", model.source)
            values[key] = float(x)
    if "seed" in table:
        s = table["seed"]
        if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= SEED_MAX:
            raise SceneKeyError("sensors.seed", f"must be an integer in [0, 2**63 - 1], got "
                                f"{s!r}", model.source)
        values["seed"] = s
    return SensorConfig(**values)


def latency_ticks(config: SensorConfig, rate: float, source: str | None = None) -> int:
    """The latency in device ticks at `rate` (SceneKeyError when it is not a whole number)."""
    x = config.latency * rate
    n = round(x)
    if abs(x - n) > TICK_TOLERANCE * max(1.0, x):
        raise SceneKeyError("sensors.latency", f"must be a whole number of device ticks "
                            f"(1/{rate:g} s), got {config.latency!r} s = {x:.6g} ticks", source)
    return int(n)


class Sensors:
    """The reported measurement, tick by tick (see the module doc): `lengths`, `rates`,
    `force`, `current` are what the device reports now."""

    def __init__(self, config: SensorConfig, rate: float, lengths: np.ndarray, rates: np.ndarray,
                 force: np.ndarray, current: np.ndarray, source: str | None = None) -> None:
        self.config = config
        self.delay = latency_ticks(config, rate, source)
        self._rng = np.random.Generator(np.random.PCG64(config.seed))
        # the true states of the last delay + 1 ticks, oldest at _head: rows l, ldot, F, i
        first = np.stack([lengths, rates, force, current]).astype(float)
        self._ring = np.repeat(first[None], self.delay + 1, axis=0)
        self._head = 0
        self._report(first)

    def sample(self, lengths: np.ndarray, rates: np.ndarray, force: np.ndarray,
               current: np.ndarray) -> None:
        """One tick: take the true state now, report the one `delay` ticks old."""
        ring = self._ring
        ring[self._head] = (lengths, rates, force, current)
        self._head = (self._head + 1) % ring.shape[0]
        self._report(ring[self._head])   # the oldest kept: delay ticks ago (itself if 0)

    def _report(self, true: np.ndarray) -> None:
        c = self.config
        res = c.encoder_resolution
        # n / (1 / res): the decimal a user expects (0.128482, not 0.12848199999999999)
        self.lengths = np.round(true[0] / res) / (1.0 / res) if res > 0 else true[0].copy()
        self.rates = true[1].copy()
        self.force = true[2] + c.force_noise * self._rng.standard_normal(6) if c.force_noise \
            else true[2].copy()
        self.current = true[3] + c.current_noise * self._rng.standard_normal(6) \
            if c.current_noise else true[3].copy()
