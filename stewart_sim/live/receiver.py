"""Telemetry datagrams in, one sample per tick out: bounded draining, newest wins, every refusal
counted by kind.

`TelemetryReceiver.poll()` is called once per tick of the live loop. It reads what is waiting
(non-blocking) until MAX_READ datagrams or until the clock has moved DRAIN_BUDGET past the
start of the drain, whichever comes first, so a flood of datagrams costs a tick at most that
budget and the rest waits in the socket (the kernel drops what overflows its buffer). Each
datagram read is decoded (live.vehicle_datagrams: the native format or OutSim); a refused one is
counted under its TelemetryError.kind (malformed, truncated, non_finite, absurd), a sample not
newer than the newest seen (the last accepted one, or a newer one earlier in the same drain)
under out_of_order (older) or duplicate (the same time), and a sample ahead of the stream's
clock under ahead (below). Of the valid samples of one drain only the newest is returned; the
older ones are counted as superseded. A refused datagram never reaches the washout: the
platform moves only on an accepted sample.

The stream's clock: the first sample accepted (after a start or `forget_order`) anchors a time
line, its telemetry time at the time of its drain (the live loop's tick time); the line advances
at (1 + DRIFT) times our clock (a sender's clock may run that much faster). A sample whose time
is more than AHEAD past the line is refused as ahead: a datagram 1e6 s in the future never
reaches the washout, and no sender can make the stream's time run faster than (1 + DRIFT) times
ours, so the washout steps one sample asks for are bounded by the clock time since the last
accepted sample (at most the loss timeout while cueing) and the line's lead
(stewart_sim.live.cue_stream takes at most MAX_STEPS of them a tick, whatever the settings). An
accepted sample behind the line by more than AHEAD pulls the line PULL of the way towards AHEAD
above it: a slower sender's line follows it within a few samples, one late datagram hardly moves
it (the punctual ones after it stay within AHEAD). `forget_order()` lets the next sample start a
new time line (after a telemetry loss: a restarted sender, or a line anchored by an absurd first
sample, cannot lock the stream out for longer than the loss timeout).
"""
from __future__ import annotations

import math
import socket
from dataclasses import dataclass, field
from typing import Callable, Protocol

from stewart_sim.live.vehicle_datagrams import (REFUSAL_KINDS, TelemetryError, TelemetrySample,
                                                decode_native, decode_outsim)

MAX_READ = 256          # datagrams read at most per tick
DRAIN_BUDGET = 2e-4     # s of clock a tick's drain may take before it stops reading
READ_SIZE = 512         # bytes read of a datagram: larger ones arrive cut, and are malformed
# s a sample may lead the stream's clock: a late first sample, jitter, and the live loop's time
# trailing the clock by up to stewart_sim.live.session.MAX_LAG (0.01 s) before it skips ticks
AHEAD = 0.025
DRIFT = 1e-3            # how much faster than ours a sender's clock may run (10x a crystal's)
PULL = 0.1              # of its lead over a sample behind it that the line gives up
ORDER_KINDS = ("out_of_order", "duplicate", "ahead")
DECODERS: dict[str, Callable[[bytes], TelemetrySample]] = {"native": decode_native,
                                                            "outsim": decode_outsim}


class DatagramSource(Protocol):
    """Where datagrams come from: recv() returns one waiting datagram or None, never blocks."""

    def recv(self) -> bytes | None: ...

    def close(self) -> None: ...


class UdpSource:
    """A non-blocking UDP socket bound to (host, port) (port 0: any free port; `address` says
    which)."""

    def __init__(self, host: str, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise TelemetryError(f"telemetry udp://{host}:{port}: cannot listen: "
                                 f"{exc.strerror or exc}") from None
        self.sock.setblocking(False)
        self.address: tuple[str, int] = self.sock.getsockname()

    def recv(self) -> bytes | None:
        try:
            return self.sock.recv(READ_SIZE)
        except (BlockingIOError, InterruptedError, ConnectionRefusedError):
            return None

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()


@dataclass
class ReceiverCounts:
    """What the receiver has seen: datagrams read, samples accepted, refusals by kind, valid
    samples superseded by a newer one of the same drain."""

    received: int = 0
    accepted: int = 0
    superseded: int = 0
    refused: dict[str, int] = field(
        default_factory=lambda: {k: 0 for k in (*REFUSAL_KINDS, *ORDER_KINDS)})

    @property
    def refused_total(self) -> int:
        return sum(self.refused.values())


class TelemetryReceiver:
    """Drains a DatagramSource once per tick (see the module doc)."""

    def __init__(self, source: DatagramSource, fmt: str, clock: Callable[[], float],
                 max_read: int = MAX_READ, budget: float = DRAIN_BUDGET) -> None:
        if fmt not in DECODERS:
            raise TelemetryError(f"telemetry format {fmt!r}: one of {', '.join(DECODERS)}")
        self.source = source
        self.decode = DECODERS[fmt]
        self.clock = clock
        self.max_read = int(max_read)
        self.budget = float(budget)
        self.counts = ReceiverCounts()
        self.last_t: float | None = None
        self.last_error: str | None = None
        self._line: tuple[float, float] | None = None   # (clock, telemetry time) on the line

    def forget_order(self) -> None:
        """The next valid sample starts a new time line, whatever its time."""
        self.last_t = None
        self._line = None

    def line(self, now: float) -> float:
        """The stream's clock at clock time `now` (see the module doc); inf before a line."""
        if self._line is None:
            return math.inf
        c, t = self._line
        return t + max(now - c, 0.0) * (1.0 + DRIFT)

    def _follow(self, s: TelemetrySample, now: float) -> None:
        """The line after accepting `s` at `now`: anchored by the first sample, pulled towards
        AHEAD above a sample behind it by more (see the module doc)."""
        if self._line is None:
            self._line = (now, s.t)
            return
        line = self.line(now)
        if s.t + AHEAD < line:
            self._line = (now, line - PULL * (line - (s.t + AHEAD)))

    def poll(self, now: float | None = None) -> TelemetrySample | None:
        """The newest valid sample waiting, newer than the last accepted one and not ahead of
        the stream's clock at `now` (the live loop's time; default: the clock's); None if
        none."""
        c = self.counts
        until = self.clock() + self.budget
        now = self.clock() if now is None else now
        ahead = self.line(now) + AHEAD
        best: TelemetrySample | None = None
        for _ in range(self.max_read):
            data = self.source.recv()
            if data is None:
                break
            c.received += 1
            try:
                s = self.decode(data)
            except TelemetryError as exc:
                c.refused[exc.kind] += 1
                self.last_error = str(exc)
            else:
                newest = best.t if best is not None else self.last_t
                if s.t > ahead:
                    c.refused["ahead"] += 1
                elif newest is None or s.t > newest:
                    c.superseded += best is not None
                    best = s
                else:
                    c.refused["duplicate" if s.t == newest else "out_of_order"] += 1
            if self.clock() >= until:
                break
        if best is not None:
            c.accepted += 1
            self.last_t = best.t
            self._follow(best, now)
        return best

    def close(self) -> None:
        self.source.close()
