"""GCS 2.0 lines: one command a line, its arguments, and the answers' line conventions.

A command line is a mnemonic (three letters, `*IDN?`, or a query ending in '?') and its
arguments, separated by spaces, ended by LF (a CR before it is dropped). Set commands with axes
take axis-value pairs (`MOV X 1.5 Y -2`); queries take an optional list of axes (`POS? X Y`;
none: all axes, answered in the controller's order) and answer one line per item, `X=1.5`. A
few commands are a single control byte with no LF (PIPython sends them so): 5 (is moving), 7
(controller ready), 24 (stop all); HLP? lists them as a hash sign and the byte's number. A multi-line answer ends every line
but the last with a space before the LF (" \\n"): that is how a client knows more follows.

Numbers are decimal (`-1.5`, `2e-3`); `nan`, `inf`, hex, underscores and anything longer than
NUMBER_MAX characters are syntax errors. Parsing never changes state: a handler receives the
parsed arguments and checks them all before it acts.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from hil.gcs import errors as E
from hil.gcs.axes import AXES

SINGLE_BYTE = {5: "#5", 7: "#7", 24: "#24"}   # control-byte commands, no LF after them
NUMBER_MAX = 40                               # characters of one number
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d{1,4})?\Z")
_WORD = re.compile(r"[\x21-\x7e]+\Z")          # printable ASCII, no space


@dataclass(frozen=True)
class Line:
    """One parsed command line: the mnemonic (upper case) and its arguments."""

    name: str
    args: tuple[str, ...]


def parse(text: str) -> Line | None:
    """The command of one line (without its LF); None for an empty line. GcsError 2 when the
    mnemonic is not a printable word, 1 when an argument is not."""
    words = text.rstrip("\r").split(" ")
    words = [w for w in words if w]
    if not words:
        return None
    if not _WORD.match(words[0]):
        raise E.GcsError(E.UNKNOWN_COMMAND, "not a command word")
    if not all(_WORD.match(w) for w in words[1:]):
        raise E.GcsError(E.PARAM_SYNTAX, "an argument is not printable ASCII")
    return Line(words[0].upper(), tuple(words[1:]))


def number(word: str) -> float:
    """A decimal number (GcsError 1 when it is not one; inf when it overflows a float)."""
    if len(word) > NUMBER_MAX or not _NUMBER.match(word):
        raise E.GcsError(E.PARAM_SYNTAX, f"{word[:NUMBER_MAX]!r} is not a number")
    return float(word)


def integer(word: str) -> int:
    """A decimal integer (GcsError 1 when it is not one)."""
    if len(word) > 9 or not word.lstrip("+-").isdigit():
        raise E.GcsError(E.PARAM_SYNTAX, f"{word[:NUMBER_MAX]!r} is not an integer")
    return int(word)


def axis(word: str, names: tuple[str, ...] = AXES) -> int:
    """The index of an axis identifier in `names` (GcsError 15 when it is not one: X Y Z U V W,
    or the pivot point's R S T)."""
    try:
        return names.index(word)
    except ValueError:
        raise E.GcsError(E.INVALID_AXIS, f"axis {word[:NUMBER_MAX]!r}") from None


def axes(args: tuple[str, ...], names: tuple[str, ...] = AXES) -> list[int]:
    """The axes a query names (all of them when it names none), in the order named."""
    if not args:
        return list(range(len(names)))
    return [axis(a, names) for a in args]


def axis_values(args: tuple[str, ...], names: tuple[str, ...] = AXES) -> list[tuple[int, float]]:
    """Axis-value pairs (`X 1 Y 2`): GcsError 1 when they do not pair up or a value is not a
    number, 15 for an unknown axis, 22 for an axis named twice."""
    if not args or len(args) % 2:
        raise E.GcsError(E.PARAM_SYNTAX, "expected axis-value pairs")
    out: list[tuple[int, float]] = []
    seen: set[int] = set()
    for i in range(0, len(args), 2):
        k = axis(args[i], names)
        if k in seen:
            raise E.GcsError(E.DOUBLE_AXIS, f"axis {args[i]} twice")
        seen.add(k)
        out.append((k, number(args[i + 1])))
    return out


def finite(value: float, code: int, what: str) -> float:
    """`value` when finite, else GcsError `code`."""
    if not math.isfinite(value):
        raise E.GcsError(code, f"{what} is not finite")
    return value


def answer(lines: list[str]) -> str:
    """A (multi-line) answer: every line but the last ends with " \\n", the last with "\\n"."""
    return " \n".join(lines) + "\n"


def fmt(value: float) -> str:
    """A number as answers carry it: the shortest text that reads back to the same float (a
    negative zero as 0.0)."""
    return repr(float(value) + 0.0)
