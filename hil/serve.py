"""The device's loop over a transport, and the UDP server end the `device` command listens on.

`serve(device, transport)` moves bytes: what arrives goes through the device's robust receiver
(`Device.feed`: framing, CRC, signature, decode) into `Device.receive`, and every reply is packed
and sent at once, one frame per `send` (one datagram per message over UDP). In real time the
device ticks at its controller rate by the monotonic clock: the loop waits in the transport's
`recv` (select) until the next tick is due, so it sleeps rather than spins; when it falls behind
it catches up tick by tick, and beyond `max_lag` it resynchronises and counts an overrun. In
lockstep the device ticks only on LOCKSTEP (inside `Device.receive`), and the loop just waits
for input. The loop ends when `stop` is set (checked at least every `poll` seconds).
"""
from __future__ import annotations

import ipaddress
import threading
import time
from dataclasses import dataclass

from hil.device import Device, DeviceError
from hil.errors import LinkError
from hil.peer import PeerGuard

IDLE_FLUSH = 0.005   # s without input after which a partial frame is given up (Receiver.flush)
POLL = 0.05          # s: the longest wait before `stop` is looked at again
MAX_LAG = 0.05       # s behind the tick schedule beyond which real time is resynchronised


@dataclass
class ServeStats:
    """What one serve() call did."""

    ticks: int = 0
    messages_in: int = 0
    messages_out: int = 0
    overruns: int = 0          # resynchronisations after falling more than max_lag behind
    max_late: float = 0.0      # s, the latest a tick started after its due time
    busy: float = 0.0          # s spent in the device (feed, flush, tick, pack)
    wall: float = 0.0          # s in the loop


def _send_all(device: Device, transport, msgs: list) -> int:
    for m in msgs:
        transport.send(device.pack(m))
    return len(msgs)


def serve(device: Device, transport, realtime: bool | None = None,
          stop: threading.Event | None = None, *, max_ticks: int | None = None,
          poll: float = POLL, max_lag: float = MAX_LAG) -> ServeStats:
    """Run `device` over `transport` until `stop` is set (or `max_ticks` real-time ticks).

    `realtime` defaults to `not device.lockstep`; a device in lockstep mode cannot be served in
    real time nor the other way round (DeviceError).
    """
    if realtime is None:
        realtime = not device.lockstep
    if realtime == device.lockstep:
        raise DeviceError(f"serve: realtime={realtime} but the device is "
                          f"{'in lockstep' if device.lockstep else 'in real-time'} mode")
    stop = stop if stop is not None else threading.Event()
    st = ServeStats()
    period = device.dt
    clock = time.monotonic
    start = clock()
    next_tick = start + period
    last_input = start
    window_start, window_busy, window_ticks = start, 0.0, 0
    peers = PeerGuard(device, transport) if PeerGuard.applies(transport) else None
    while not stop.is_set():
        now = clock()
        timeout = min(poll, max(0.0, next_tick - now)) if realtime else poll
        data = transport.recv(timeout)
        if data:
            t0 = clock()
            replies = device.feed(data)
            if peers is not None:
                st.messages_out += peers.after_feed()
            st.messages_out += _send_all(device, transport, replies)
            last_input = t1 = clock()
            st.busy += t1 - t0
            window_busy += t1 - t0
        elif device.rx.pending and clock() - last_input > IDLE_FLUSH:
            st.messages_out += _send_all(device, transport, device.flush())
        if not realtime:
            continue
        now = clock()
        while now >= next_tick and not stop.is_set():
            late = now - next_tick
            if late > max_lag:
                st.overruns += 1
                device.counters.overruns += 1
                next_tick = now
                late = 0.0
            st.max_late = max(st.max_late, late)
            st.messages_out += _send_all(device, transport, device.tick())
            st.ticks += 1
            window_ticks += 1
            next_tick += period
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
    """Parse "HOST:PORT" where HOST is a loopback IPv4 address (or "localhost"); LinkError else."""
    host, sep, port_text = text.rpartition(":")
    if not sep or not host:
        raise LinkError(f"--udp: expected HOST:PORT, got {text!r}")
    if host == "localhost":
        host = "127.0.0.1"
    try:
        addr = ipaddress.IPv4Address(host)
    except ValueError:
        raise LinkError(f"--udp: {host!r} is not an IPv4 address; the device listens on "
                        "loopback only (127.0.0.1)") from None
    if not addr.is_loopback:
        raise LinkError(f"--udp: {host} is not a loopback address; the device listens on "
                        "loopback only (127.0.0.1)")
    try:
        port = int(port_text)
    except ValueError:
        raise LinkError(f"--udp: port must be an integer, got {port_text!r}") from None
    if not 0 <= port <= 65535:
        raise LinkError(f"--udp: port must be 0..65535 (0: any free port), got {port}")
    return str(addr), port
