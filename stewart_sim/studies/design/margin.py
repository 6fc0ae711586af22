"""A requirement's margin, named: positive when met, in the requirement's unit and relative
to its scale (what the search compares)."""
from __future__ import annotations

from dataclasses import dataclass

UNITS = {"stroke_min": "m", "stroke_max": "m", "base_cone": "rad", "platform_cone": "rad",
         "leg_clearance": "m", "obstacle": "m", "cond": "1", "first_resonance": "Hz"}
FAILED = -10.0   # the relative margin of a requirement a candidate cannot be evaluated on


@dataclass(frozen=True)
class Margin:
    name: str
    absolute: float      # in `unit`; positive: met
    unit: str
    relative: float      # absolute / the requirement's scale
    where: str = ""      # the pose (or leg) that binds
