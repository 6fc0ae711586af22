"""Argument types of the command line (standard library only: `--help` stays fast): a number
that must satisfy a rule, else argparse's one-line usage error saying the rule."""
from __future__ import annotations

import argparse
import math
from typing import Callable


def number(convert: Callable[[str], float], what: str, ok: Callable[[float], bool], rule: str):
    """An argparse type: `convert(text)` that must satisfy `ok`, else a message saying `rule`."""
    def parse(text: str):
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None
        if not ok(value):
            raise argparse.ArgumentTypeError(f"must be {rule}, got {text!r}")
        return value
    return parse


def _finite_positive(v: float) -> bool:
    return math.isfinite(v) and v > 0


positive_seconds = number(float, "a number", _finite_positive, "a finite number of seconds > 0")
positive_rate = number(float, "a rate in Hz", _finite_positive, "a finite rate in Hz > 0")


def _port(v: int) -> bool:
    return 0 <= v <= 65535


port = number(int, "a port number", _port, "a TCP port 1-65535, or 0 for any free one")
