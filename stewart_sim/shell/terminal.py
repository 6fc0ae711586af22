"""What reaches the terminal: control characters escaped, wherever the text came from.

A scene's name, a file name or a message quoting an input may hold ANSI escape sequences or
other control characters; printed raw they would recolour, move the cursor, retitle the window
or hide text. `printable` escapes them (C0 but newline and tab, DEL, C1, and the bidirectional
overrides) as `\\xNN` / `\\uNNNN`; `escaping` installs it on standard output and standard error
for the run of a command (stewart_sim.cli), so that every printing path goes through it: error
messages, scene-info's fields, the lines that name what was written. A control character that
is meant (the progress line's carriage return) is written with `write_control`. Only the
standard library here (cli imports it before the command's packages).
"""
from __future__ import annotations

import sys
from contextlib import contextmanager
from typing import Iterator, TextIO

_KEEP = "\n\t"   # the control characters that are meant in printed text
_BIDI = (0x061C, 0x200E, 0x200F, *range(0x202A, 0x202F), *range(0x2066, 0x206A))
_TABLE = {c: (f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}")
          for c in (*range(0x20), *range(0x7F, 0xA0), *_BIDI) if chr(c) not in _KEEP}


def printable(text: str) -> str:
    """`text` with its control characters (all but newline and tab) escaped as \\xNN."""
    return text.translate(_TABLE)


class EscapingStream:
    """A text stream whose `write` escapes control characters (printable); every other
    attribute is the wrapped stream's (fileno, isatty, buffer, flush)."""

    def __init__(self, stream: TextIO):
        self._stream = stream

    def write(self, text: str) -> int:
        self._stream.write(printable(text))
        return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def write_control(self, text: str) -> int:
        """Write `text` as it is: control characters the program means (a carriage return)."""
        return self._stream.write(text)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def write_control(stream: TextIO, text: str) -> None:
    """Write control characters that are meant to `stream`, escaping or not."""
    getattr(stream, "write_control", stream.write)(text)


@contextmanager
def escaping() -> Iterator[None]:
    """Standard output and standard error escaping control characters inside (then restored)."""
    out, err = sys.stdout, sys.stderr
    sys.stdout = EscapingStream(out) if out is not None else out
    sys.stderr = EscapingStream(err) if err is not None else err
    try:
        yield
    finally:
        sys.stdout, sys.stderr = out, err
