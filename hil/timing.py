"""Real-time bookkeeping shared by the device loop (hil.serve) and the host loop (hil.client).

* `Lateness`: how late each periodic action (a device tick, a host setpoint) started after its
  due time, in a fixed histogram (1 us bins up to 100 ms, then one overflow bin plus the exact
  maximum), so a device that runs for hours keeps constant memory; percentiles are the upper
  edge of their bin (1 us resolution). A *deadline miss* is an action that started a full
  period or more after its due time (the next one was already due).
* `wait_until`: the hybrid wait of the host loop: sleep (in the caller's poll, e.g. select)
  until `spin` s before the deadline, then spin on a non-blocking poll, so wake-up latency of
  the OS timer does not make the action late.
* `gc_frozen`: a context manager that collects, freezes and disables the garbage collector for
  the duration of a real-time run (no collection pauses inside the loop), then restores it.
"""
from __future__ import annotations

import contextlib
import gc
import math
from typing import Callable, Iterator

import numpy as np

BIN = 1e-6          # s
NBINS = 100_000     # 100 ms of 1 us bins; later goes to the overflow bin
SPIN = 0.0005       # s: host loop spins for the last half millisecond before a deadline


class Lateness:
    """Histogram of lateness (s) of a periodic action of period `period` (see the module doc)."""

    def __init__(self, period: float) -> None:
        self.period = float(period)
        self._bins = np.zeros(NBINS + 1, dtype=np.int64)
        self.count = 0
        self.misses = 0
        self.max = 0.0

    def add(self, late: float) -> None:
        late = max(0.0, late)
        i = int(late / BIN)
        self._bins[i if i < NBINS else NBINS] += 1
        self.count += 1
        if late >= self.period:
            self.misses += 1
        if late > self.max:
            self.max = late

    def percentile(self, p: float) -> float:
        """Upper edge (s) of the bin holding the p-th percentile (nan when empty)."""
        if self.count == 0:
            return math.nan
        rank = math.ceil(p / 100.0 * self.count - 1e-9)
        i = int(np.searchsorted(np.cumsum(self._bins), max(rank, 1)))
        return self.max if i >= NBINS else min((i + 1) * BIN, self.max)

    def summary(self) -> dict[str, float]:
        """p50, p99, p99.9, max (s), the count and the deadline misses."""
        return {"p50": self.percentile(50), "p99": self.percentile(99),
                "p99.9": self.percentile(99.9), "max": self.max if self.count else math.nan,
                "count": self.count, "misses": self.misses}

    def text(self) -> str:
        s = self.summary()
        return (f"late p50 {s['p50'] * 1e6:.0f} us, p99 {s['p99'] * 1e6:.0f} us, "
                f"p99.9 {s['p99.9'] * 1e6:.0f} us, max {s['max'] * 1e6:.0f} us, "
                f"{s['misses']} deadline misses of {s['count']}")


def wait_until(due: float, clock: Callable[[], float], poll: Callable[[float], object],
               spin: float = SPIN) -> None:
    """Poll (blocking) until `spin` s before `due`, then poll without blocking until `due`."""
    while (left := due - clock()) > spin:
        poll(left - spin)
    while due - clock() > 0:
        poll(0.0)


@contextlib.contextmanager
def gc_frozen() -> Iterator[None]:
    """No garbage collection inside the block (collected and frozen first, restored after)."""
    was = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.unfreeze()
        if was:
            gc.enable()
