"""Progress of long runs: one status line on stderr, quiet for short runs."""
from __future__ import annotations

import math
import sys
import time
from typing import TextIO

from stewart_sim.shell.terminal import write_control

PROGRESS_SAMPLES = 200_000   # show progress from the start for runs longer than this
PROGRESS_SECONDS = 1.0       # ... and for any run still busy after this long
PROGRESS_INTERVAL = 0.5      # s between two progress updates


class Progress:
    """One status line on stderr for long runs (carriage return on a terminal), quiet otherwise."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.start = time.monotonic()
        self.last = -math.inf
        self.shown = False
        self.width = 0
        self.first: dict[str, tuple[int, float]] = {}   # by stage: (done, time) at its first update

    def update(self, stage: str, done: int, total: int | None = None, unit: str = "samples",
               rate: bool = False) -> None:
        """Report `done` of `total` units (total None: unknown) of the current stage; with
        `rate`, also units per second since the stage's first update and (total known) an
        estimate of the time left."""
        now = time.monotonic()
        first = self.first.setdefault(stage, (done, now))
        finished = total is not None and done >= total
        if not self.shown:
            big = (total if total is not None else done) > PROGRESS_SAMPLES
            if not (big or (now - self.start > PROGRESS_SECONDS and not finished)):
                return
            self.shown = True
        elif not finished and now - self.last < PROGRESS_INTERVAL:
            return
        self.last = now
        count = f"{done:,}" if total is None else f"{done:,}/{total:,} ({100 * done / total:.0f}%)"
        speed = rate_text(done - first[0], now - first[1], None if total is None else total - done,
                          unit) if rate else ""
        self._write(f"{stage}: {count} {unit}, {now - self.start:.1f} s{speed}")

    def close(self) -> None:
        """End the status line so that later output starts on a fresh line."""
        if self.tty and self.width:
            self.stream.write("\n")
            self.stream.flush()
        self.width = 0

    def _write(self, text: str) -> None:
        """Overwrite the line on a terminal; one line per update elsewhere (logs)."""
        if self.tty:
            write_control(self.stream, "\r")     # meant: the line is written over
            self.stream.write(text.ljust(self.width))
            self.width = max(self.width, len(text))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def rate_text(done: int, seconds: float, left: int | None, unit: str) -> str:
    """", 410 points/s, about 12 s left" (empty before anything is measured; no estimate for
    an unknown total)."""
    if done <= 0 or seconds <= 0:
        return ""
    speed = done / seconds
    text = f", {speed:.3g} {unit}/s"
    if left is not None and left > 0:
        eta = left / speed
        text += (f", about {eta:.0f} s left" if eta < 120 else
                 f", about {eta / 60:.0f} min left" if eta < 7200 else
                 f", about {eta / 3600:.1f} h left")
    return text
