"""A recorded vehicle motion streamed as telemetry datagrams (`stewart-sim telemetry-replay`).

`Replay` holds the schedule: sample k (of the motion resampled to `rate` when given, linearly,
as the washout's filters take their input: cueing.study.resample) is due `t_k - t_0` after the
start and carries the time `t_k - t_0`; with `loop` the motion starts again one sample period
after its end, its times continuing (telemetry time never goes back, so the receiver takes each
pass). `due(now)` returns the datagrams due by `now` (seconds since the start, on any clock: the
wall clock of `stream`, or a test's simulated one), at most MAX_BURST per call (a stalled
sender catches up in bursts, never all at once). `stream` runs it in real time on the monotonic
clock, waiting with hil.timing.wait_until (sleep, then spin the last half millisecond).
"""
from __future__ import annotations

import math
import socket
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from hil.timing import wait_until
from stewart_sim.cueing.motion import VehicleMotion
from stewart_sim.cueing.study import resample
from stewart_sim.live.vehicle_datagrams import (TelemetryError, TelemetrySample, encode,
                                                encode_outsim)

ENCODERS: dict[str, Callable[[TelemetrySample], bytes]] = {"native": encode,
                                                           "outsim": encode_outsim}
MAX_BURST = 1000   # datagrams one due() call returns at most


class Replay:
    """The schedule of a motion's datagrams (see the module doc)."""

    def __init__(self, motion: VehicleMotion, fmt: str = "native", rate: float | None = None,
                 loop: bool = False) -> None:
        if fmt not in ENCODERS:
            raise TelemetryError(f"telemetry format {fmt!r}: one of {', '.join(ENCODERS)}")
        if rate is not None:
            motion = resample(motion, rate)
        self.t = np.asarray(motion.t, float) - float(motion.t[0])
        self.f = np.asarray(motion.specific_force, float)
        self.w = np.asarray(motion.angular_velocity, float)
        self.period = float(self.t[-1] / (self.t.size - 1))
        self.span = float(self.t[-1]) + self.period       # one pass, then the next starts
        self.encode = ENCODERS[fmt]
        self.loop = loop
        self.sent = 0          # samples handed out so far (over all passes)

    def _time(self, i: int) -> float:
        n = self.t.size
        return (i // n) * self.span + float(self.t[i % n])

    @property
    def done(self) -> bool:
        return not self.loop and self.sent >= self.t.size

    def next_due(self) -> float:
        """When (s since the start) the next datagram is due; inf when done."""
        return math.inf if self.done else self._time(self.sent)

    def sample(self, i: int) -> TelemetrySample:
        """Sample i of the stream (i counts over passes)."""
        k = i % self.t.size
        return TelemetrySample(self._time(i), tuple(self.f[k]), tuple(self.w[k]))

    def due(self, now: float) -> list[bytes]:
        """The datagrams due by `now` not handed out yet (at most MAX_BURST)."""
        out: list[bytes] = []
        while len(out) < MAX_BURST and not self.done and self._time(self.sent) <= now:
            out.append(self.encode(self.sample(self.sent)))
            self.sent += 1
        return out


class UdpSink:
    """A UDP socket sending to (host, port); a datagram the kernel cannot take is dropped and
    counted (the receiver sees a gap, as from a lossy network)."""

    def __init__(self, host: str, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.target = (host, port)
        self.dropped = 0

    def send(self, data: bytes) -> None:
        try:
            self.sock.sendto(data, self.target)
        except (BlockingIOError, ConnectionRefusedError):
            self.dropped += 1
        except OSError as exc:
            raise TelemetryError(f"telemetry udp://{self.target[0]}:{self.target[1]}: "
                                 f"send failed: {exc.strerror or exc}") from None

    def close(self) -> None:
        self.sock.close()


@dataclass(frozen=True)
class ReplayStats:
    sent: int
    dropped: int
    seconds: float


def stream(replay: Replay, sink: UdpSink, clock: Callable[[], float] = time.monotonic,
           duration: float = math.inf) -> ReplayStats:
    """Send `replay`'s datagrams at their due times on `clock` until it is done or `duration`
    s have passed (a looping replay ends with `duration` or Ctrl-C)."""
    start = clock()
    while not replay.done:
        # compared on the stream's own time: (start + t) - start may round past `duration`
        if replay.next_due() > duration:
            break
        due = start + replay.next_due()
        wait_until(due, clock, lambda left: time.sleep(max(left, 0.0)))
        for data in replay.due(min(clock() - start, duration)):   # never past the end
            sink.send(data)
    return ReplayStats(replay.sent, sink.dropped, clock() - start)
