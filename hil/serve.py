"""The device's loop over a transport, and the UDP server end the `device` command listens on.

`serve(device, transport)` moves bytes: what arrives goes through the device's robust receiver
(`Device.feed`: framing, CRC, signature, decode) into `Device.receive`, and every reply is packed
and sent at once, one frame per `send` (one datagram per message over UDP). In real time the
device ticks at its controller rate by the monotonic clock: the loop waits in the transport's
`recv` (select) until the next tick is due, so it sleeps rather than spins. Before every tick it
drains all pending input (every datagram or byte already waiting is decoded and handled, and
on a UDP server end seen by the peer rule of hil.peer, as any other input), so a
backlog never delays a setpoint by more than the ticks it arrives between; a drain stops when
the tick is due (just before a tick: DRAIN_SHARE of a period after its due time; when the loop is
further behind, after one datagram), so input without end, a flood, cannot hold the ticks back.
On a UDP server end in real time, a datagram over its sender's budget (hil.peer,
hil.throttle.SourceLimiter) is dropped before it is decoded, and counted. Tick k (the one that
takes device time from k / rate to (k + 1) / rate) is due at wall time start + (k + 1) / rate on
the monotonic clock, and no tick is ever skipped: device time t maps to wall time start + t
(+ the tick's lateness, which does not accumulate). When the loop falls behind it catches up
tick by tick; a catch-up that started more than `max_lag` late counts one overrun, each tick that
started a full period late a deadline miss (`ServeStats.late`, a `hil.timing.Lateness`). While
served in real time the device's watchdog runs on the same monotonic clock (`Device.clock`). In
lockstep the device ticks only on LOCKSTEP (inside `Device.receive`), and the loop just waits
for input. The loop ends when `stop` is set (checked at least every `poll` seconds).
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Callable

from hil.address import host_port
from hil.device import Device, DeviceError
from hil.errors import LinkError
from hil.peer import PeerGuard
from hil.timing import Lateness

IDLE_FLUSH = 0.005   # s without input after which a partial frame is given up (Receiver.flush)
POLL = 0.05          # s: the longest wait before `stop` is looked at again
MAX_LAG = 0.05       # s behind the tick schedule beyond which a catch-up counts as an overrun
MAX_DRAIN = 10000    # datagrams handled at most in one drain (a flood cannot stop the ticks)
DRAIN_SHARE = 0.5    # of a period after a tick's due time: the input drained before it stops


@dataclass
class ServeStats:
    """What one serve() call did."""

    ticks: int = 0
    messages_in: int = 0
    messages_out: int = 0
    overruns: int = 0          # catch-ups after falling more than max_lag behind
    max_late: float = 0.0      # s, the latest a tick started after its due time
    busy: float = 0.0          # s spent in the device (feed, flush, tick, pack)
    wall: float = 0.0          # s in the loop
    late: Lateness | None = None   # real time: every tick's lateness (p50... and misses)


def _send_all(device: Device, transport, msgs: list) -> int:
    for m in msgs:
        transport.send(device.pack(m))
    return len(msgs)


def _drain(device: Device, transport, data: bytes, st: ServeStats,
           peers: PeerGuard | None = None, clock: Callable[[], float] = time.monotonic,
           until: float = math.inf) -> bool:
    """Handle `data` and then everything else already waiting, until clock() reaches `until`
    (a flood cannot hold the tick back); True if anything came. A datagram over its sender's
    budget is dropped undecoded (PeerGuard.admit); each other datagram's replies go out after
    the peer rule has seen it (hil.peer)."""
    n = 0
    while data:
        now = clock()
        if peers is None or peers.admit(len(data), now):
            replies = device.feed(data)
            if peers is not None:
                st.messages_out += peers.after_feed()
            st.messages_out += _send_all(device, transport, replies)
        n += 1
        if n >= MAX_DRAIN or now >= until:
            break
        data = transport.recv(0.0)
    return n > 0


def serve(device: Device, transport, realtime: bool | None = None,
          stop: threading.Event | None = None, *, max_ticks: int | None = None,
          poll: float = POLL, max_lag: float = MAX_LAG,
          clock: Callable[[], float] = time.monotonic, flood_limit: bool = True) -> ServeStats:
    """Run `device` over `transport` until `stop` is set (or `max_ticks` real-time ticks).

    `realtime` defaults to `not device.lockstep`; a device in lockstep mode cannot be served in
    real time nor the other way round (DeviceError). `clock` is the monotonic wall clock of the
    tick schedule and of the watchdog (a test may pass its own, with a transport advancing it).
    `flood_limit=False` turns the per-source budget of a UDP server end off (the "before" of
    tests and benchmarks; hil.peer).
    """
    if realtime is None:
        realtime = not device.lockstep
    if realtime == device.lockstep:
        raise DeviceError(f"serve: realtime={realtime} but the device is "
                          f"{'in lockstep' if device.lockstep else 'in real-time'} mode")
    stop = stop if stop is not None else threading.Event()
    st = ServeStats()
    period = device.dt
    start = clock()
    if realtime:
        st.late = Lateness(period)
        device.clock = clock   # the watchdog by the same wall clock as the tick schedule
    next_tick = start + period
    last_input = start
    behind = False
    window_start, window_busy, window_ticks = start, 0.0, 0
    peers = (PeerGuard(device, transport, limit=realtime and flood_limit, clock=clock)
             if PeerGuard.applies(transport) else None)
    while not stop.is_set():
        now = clock()
        timeout = min(poll, max(0.0, next_tick - now)) if realtime else poll
        data = transport.recv(timeout)
        t0 = clock()
        if data:
            _drain(device, transport, data, st, peers, clock, next_tick if realtime else math.inf)
            last_input = t1 = clock()
            st.busy += t1 - t0
            window_busy += t1 - t0
        elif device.rx.pending and t0 - last_input > IDLE_FLUSH:
            st.messages_out += _send_all(device, transport, device.flush())
        if not realtime:
            continue
        now = clock()
        while now >= next_tick and not stop.is_set():
            late = now - next_tick
            if late > max_lag and not behind:
                st.overruns += 1
                device.counters.overruns += 1
            behind = late > max_lag
            st.late.add(late)
            st.max_late = max(st.max_late, late)
            # input, then the tick: input is drained until DRAIN_SHARE of a period after the
            # tick's due time (behind schedule: one datagram), so a catch-up is ticks, not input
            if _drain(device, transport, transport.recv(0.0), st, peers, clock,
                      next_tick + DRAIN_SHARE * period):
                last_input = clock()
            st.messages_out += _send_all(device, transport, device.tick())
            st.ticks += 1
            window_ticks += 1
            next_tick += period          # never skipped: device time stays on the wall clock
            t1 = clock()
            st.busy += t1 - now
            window_busy += t1 - now
            now = t1
            if window_ticks >= round(1.0 / period):  # the load of the last second, per mille
                device.load = int(1000 * window_busy / max(now - window_start, 1e-9))
                window_start, window_busy, window_ticks = now, 0.0, 0
            if max_ticks is not None and st.ticks >= max_ticks:
                stop.set()
    st.messages_in = device.rx.stats.frames_ok
    st.wall = clock() - start
    return st


def serve_in_thread(device: Device, transport, realtime: bool | None = None, **kw
                    ) -> tuple[threading.Thread, threading.Event, list[ServeStats]]:
    """serve() in a daemon thread: (thread, stop event, a list that receives its ServeStats)."""
    stop = threading.Event()
    result: list[ServeStats] = []
    thread = threading.Thread(target=lambda: result.append(serve(device, transport, realtime,
                                                                 stop, **kw)),
                              daemon=True, name="hil-device")
    thread.start()
    return thread, stop, result


# ---------------------------------------------------------------- UDP server end

def loopback_address(text: str) -> tuple[str, int]:
    """Parse "HOST:PORT" where HOST is a loopback IPv4 address (or "localhost"), port 0 for
    any free one; hil.address.AddressError (a LinkError) else."""
    return host_port(text, "--udp", loopback_only="the device listens on loopback only")
