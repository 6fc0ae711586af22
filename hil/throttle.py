"""Token buckets: the STATUSTEXT the device sends, and the bytes strangers send a UDP server.

`StatusLimiter` cuts floods of STATUSTEXT in device time (the device's own refusals and notices);
`SourceLimiter` drops a datagram from any address but the peer's once its source has spent its
budget, before it is decoded (hil.peer, hil.serve). Both count what they cut; neither grows with
its input.
"""
from __future__ import annotations

import math
from typing import Any

# STATUSTEXT rate limit (token bucket in device time): at most STATUS_RATE per second on
# average, bursts of STATUS_BURST; the last STATUS_RESERVE tokens are kept for CRITICAL and above.
STATUS_RATE = 20.0
STATUS_BURST = 30.0
STATUS_RESERVE = 10.0

# Input on a UDP server end from any address but the peer's (hil.peer, real time only): a token
# bucket of bytes per source address on the serve loop's clock. Decoding costs about 27 us a
# frame (a 21-byte HEARTBEAT) and a tick 110 us at 1 kHz on the reference machine, so a flood of
# small valid frames decoded in full is what put device time behind wall time. A stranger may
# send STRANGER_RATE in bursts of STRANGER_BURST (enough for a new host's first frames, or a
# second station's occasional request); the peer is not limited (a host streaming setpoints
# must never lose one, nor the backlog of a stall). SOURCES addresses get a bucket of their own;
# beyond, new sources share one (bounded memory), and a source idle for FLOOD_MEMORY s is
# forgotten (its bucket was full again). A source that went over its budget within FLOOD_MEMORY
# s is flooding: it never becomes the peer (hil.peer).
STRANGER_RATE = 1024.0     # bytes/s
STRANGER_BURST = 1024.0    # bytes
SOURCES = 16
FLOOD_MEMORY = STRANGER_BURST / STRANGER_RATE   # s


class StatusLimiter:
    """Token bucket over STATUSTEXT messages in device time (ticks): floods are cut, counted.

    Chunks of one long text (same nonzero id) pass or go together; a message that passed once
    is marked and passes again untouched (replies repeated in lockstep, nested filtering)."""

    def __init__(self, dt: float, rate: float = STATUS_RATE, burst: float = STATUS_BURST,
                 reserve: float = STATUS_RESERVE) -> None:
        self.dt, self.rate, self.burst, self.reserve = dt, rate, burst, reserve
        self.tokens = burst
        self._k = 0
        self._chunk_ok: dict[int, bool] = {}
        self.suppressed = 0

    def filter(self, msgs: list[Any], k: int, critical: int) -> list[Any]:
        if k != self._k:
            self.tokens = min(self.burst, self.tokens + (k - self._k) * self.dt * self.rate)
            self._k = k
        out = []
        for m in msgs:
            if getattr(m, "_limited", False) or m.get_type() != "STATUSTEXT":
                out.append(m)
                continue
            cid = getattr(m, "id", 0)
            if cid and getattr(m, "chunk_seq", 0) > 0 and cid in self._chunk_ok:
                ok = self._chunk_ok[cid]
            else:
                need = 1.0 if m.severity <= critical else 1.0 + self.reserve
                ok = self.tokens >= need
                if ok:
                    self.tokens -= 1.0
                if cid:
                    if len(self._chunk_ok) > 64:
                        self._chunk_ok.clear()
                    self._chunk_ok[cid] = ok
            if ok:
                m._limited = True
                out.append(m)
            else:
                self.suppressed += 1
        return out


class SourceLimiter:
    """Token buckets of bytes per source address (see STRANGER_RATE...): a datagram over its
    source's budget is dropped before it is decoded, and counted (`dropped`, `bytes_dropped`).
    Memory: at most SOURCES + 1 buckets, whatever the number of addresses."""

    def __init__(self, sources: int = SOURCES) -> None:
        self.sources = sources
        # source -> [tokens, time of the last update, time of the last drop]
        self._buckets: dict[Any, list[float]] = {}
        self._shared: list[float] | None = None      # of the sources beyond `sources`
        self.dropped = 0
        self.bytes_dropped = 0

    def admit(self, source: Any, nbytes: int, now: float) -> bool:
        """True when `nbytes` from `source` fit its budget at clock time `now` (s); else False,
        counted."""
        rate, burst = STRANGER_RATE, STRANGER_BURST
        b = self._buckets.get(source)
        if b is None:
            if len(self._buckets) >= self.sources:
                self._forget_idle(now)
            if len(self._buckets) < self.sources:
                b = self._buckets[source] = [burst, now, -math.inf]
            else:
                if self._shared is None:
                    self._shared = [burst, now, -math.inf]
                b = self._shared
        tokens = min(burst, b[0] + max(0.0, now - b[1]) * rate)
        b[1] = now
        if nbytes <= tokens:
            b[0] = tokens - nbytes
            return True
        b[0], b[2] = tokens, now
        self.dropped += 1
        self.bytes_dropped += nbytes
        return False

    def flooding(self, source: Any, now: float) -> bool:
        """Whether `source` (or the shared bucket it falls in) went over its budget within
        FLOOD_MEMORY s of `now`."""
        b = self._buckets.get(source)
        if b is None and len(self._buckets) >= self.sources:
            b = self._shared
        return b is not None and now - b[2] < FLOOD_MEMORY

    def _forget_idle(self, now: float) -> None:
        """Forget the sources idle for FLOOD_MEMORY s: their buckets are full again and their
        last drop is older than FLOOD_MEMORY."""
        for key in [k for k, b in self._buckets.items() if now - b[1] >= FLOOD_MEMORY]:
            del self._buckets[key]

    def __len__(self) -> int:
        """The buckets held (at most `sources` + 1)."""
        return len(self._buckets) + (self._shared is not None)
