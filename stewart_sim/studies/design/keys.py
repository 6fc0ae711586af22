"""design.toml's keys checked against their bounds: a bad one is a DesignInputError naming it
(exit 2)."""
from __future__ import annotations

import math

from stewart_fmu.errors import StewartError


class DesignInputError(StewartError, ValueError):
    """design.toml (or a command-line option) is at fault; the message names the key."""


def only(t: dict, allowed: set, prefix: str, src: str) -> None:
    for key in t:
        if key not in allowed:
            raise DesignInputError(f"{src}: {prefix}{key}: unknown key (known: "
                                   f"{', '.join(sorted(allowed))})")


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def number(t, key, default, lo, hi, prefix, src, unit):
    if key not in t:
        return default
    v = t[key]
    if not (is_number(v) and lo <= v <= hi):
        raise DesignInputError(f"{src}: {prefix}{key}: need a number in [{lo:g}, {hi:g}] "
                               f"({unit}), got {v!r}")
    return float(v)


def integer(t, key, default, lo, hi, prefix, src) -> int:
    if key not in t:
        return default
    v = t[key]
    if not (isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi):
        raise DesignInputError(f"{src}: {prefix}{key}: need an integer in [{lo}, {hi}], got {v!r}")
    return v

