"""Text a user gave (a scene's name, a file's path, a catalogue's drive names, an error that
quotes them) where it lands in a Markdown report: rendered as the characters it holds, never as
markup or HTML, and on one line, so that it cannot break a table's row or add one.

`md_text`: for running text and table cells. Markup characters are backslash-escaped (CommonMark
renders `\\*` as `*`; GFM reads `\\|` in a cell as `|`), &, < and > become entities (a report is
often shown as HTML), line breaks and other control characters a space.
`md_code`: for a code span: the text is kept as it is (a code span renders no markup), fenced
with more backticks than it holds in a row, line breaks a space.
"""
from __future__ import annotations

import re

_BREAKS = re.compile(r"[\x00-\x1f\x7f\x85\u2028\u2029]")
_MARKUP = re.compile(r"([\\`*_\[\]|~])")
_ENTITIES = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}


def md_text(text: object) -> str:
    """`text` as Markdown that renders as itself, on one line."""
    flat = _BREAKS.sub(" ", str(text))
    flat = re.sub(r"[&<>]", lambda m: _ENTITIES[m.group(0)], flat)
    return _MARKUP.sub(r"\\\1", flat)


def md_code(text: object) -> str:
    """`text` as a Markdown code span (with its backticks), on one line."""
    flat = _BREAKS.sub(" ", str(text))
    fence = "`" * (max((len(run) for run in re.findall(r"`+", flat)), default=0) + 1)
    pad = " " if flat.startswith("`") or flat.endswith("`") else ""
    return f"{fence}{pad}{flat}{pad}{fence}"
