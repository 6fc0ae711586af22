"""Telemetry datagrams in, one sample per tick out: bounded draining, newest wins, every refusal
counted by kind.

`TelemetryReceiver.poll()` is called once per tick of the live loop. It reads what is waiting
(non-blocking) until MAX_READ datagrams or until the clock has moved DRAIN_BUDGET past the
start of the drain, whichever comes first, so a flood of datagrams costs a tick at most that
budget and the rest waits in the socket (the kernel drops what overflows its buffer). Each
datagram read is decoded (cueing.telemetry: the native format or OutSim); a refused one is
counted under its TelemetryError.kind (malformed, truncated, non_finite, absurd), a sample not
newer than the newest seen (the last accepted one, or a newer one earlier in the same drain)
under out_of_order (older) or duplicate (the same time). Of the valid samples of one drain only
the newest is returned; the ones it replaced are counted as superseded. A refused datagram never reaches the washout: the platform moves
only on an accepted sample. `forget_order()` lets the next sample start a new time line (after
a telemetry loss: a restarted sender, or one earlier sample with an absurd future time, cannot
lock the stream out for longer than the loss timeout).
"""
from __future__ import annotations

import socket
from dataclasses import dataclass, field
from typing import Callable, Protocol

from stewart_sim.cueing.telemetry import (REFUSAL_KINDS, TelemetryError, TelemetrySample,
                                          decode_native, decode_outsim)

MAX_READ = 256          # datagrams read at most per tick
DRAIN_BUDGET = 2e-4     # s of clock a tick's drain may take before it stops reading
READ_SIZE = 512         # bytes read of a datagram: larger ones arrive cut, and are malformed
ORDER_KINDS = ("out_of_order", "duplicate")
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

    def forget_order(self) -> None:
        """The next valid sample starts a new time line, whatever its time."""
        self.last_t = None

    def poll(self) -> TelemetrySample | None:
        """The newest valid sample waiting, newer than the last accepted one; None if none."""
        c = self.counts
        until = self.clock() + self.budget
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
                if newest is None or s.t > newest:
                    c.superseded += best is not None
                    best = s
                else:
                    c.refused["duplicate" if s.t == newest else "out_of_order"] += 1
            if self.clock() >= until:
                break
        if best is not None:
            c.accepted += 1
            self.last_t = best.t
        return best

    def close(self) -> None:
        self.source.close()
