"""Transports (pseudo-terminal pair, loopback UDP, in-process queues) and a link emulator."""
from __future__ import annotations

import collections
import errno
import ipaddress
import math
import os
import random
import select
import socket
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from typing import Protocol

from hil.errors import LinkError

BITS_PER_BYTE = 10  # UART 8N1: start bit + 8 data bits + stop bit
LOOPBACK = "127.0.0.1"
READ_SIZE = 65536


class Transport(Protocol):
    """A byte link end: send never blocks, recv waits at most `timeout` seconds."""

    def send(self, data: bytes) -> int:
        """Queue `data`; return the number of bytes accepted (the rest is dropped and counted)."""
        ...

    def recv(self, timeout: float = 0.0) -> bytes:
        """Bytes received within `timeout` seconds (b"" if none)."""
        ...

    def close(self) -> None:
        """Release the end; further use raises LinkError."""
        ...


@dataclass
class TransportStats:
    """Counters of one transport end."""

    bytes_sent: int = 0
    bytes_dropped: int = 0
    bytes_received: int = 0
    sends: int = 0
    recvs: int = 0


class _Base:
    """Shared counters, closed flag and context manager of the transports."""

    def __init__(self) -> None:
        self.stats = TransportStats()
        self.closed = False

    def _check(self) -> None:
        if self.closed:
            raise LinkError(f"{type(self).__name__} is closed")

    def _readable(self, handle, timeout: float) -> bool:
        """Checked open, then: does `handle` have input within `timeout` seconds?"""
        self._check()
        ready, _, _ = select.select([handle], [], [], max(timeout, 0.0))
        return bool(ready)

    def _count_send(self, offered: int, sent: int) -> int:
        self.stats.sends += 1
        self.stats.bytes_sent += sent
        self.stats.bytes_dropped += offered - sent
        return sent

    def _count_recv(self, data: bytes) -> bytes:
        self.stats.recvs += 1
        self.stats.bytes_received += len(data)
        return data

    def __enter__(self) -> "_Base":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()  # type: ignore[attr-defined]


class PtyTransport(_Base):
    """One end (master or slave fd) of a pseudo-terminal in raw, non-blocking mode."""

    def __init__(self, fd: int, name: str) -> None:
        super().__init__()
        self.fd, self.name = fd, name
        tty.setraw(fd, termios.TCSANOW)
        os.set_blocking(fd, False)
        self.peer_closed = False

    def send(self, data: bytes) -> int:
        """Write without blocking; bytes that do not fit are dropped, like a UART overrun."""
        self._check()
        view, sent = memoryview(data), 0
        while sent < len(data):
            try:
                k = os.write(self.fd, view[sent:])
            except BlockingIOError:
                break
            except OSError as exc:  # EIO: the other side is gone
                if exc.errno != errno.EIO:
                    raise LinkError(f"pty {self.name}: write failed: {exc}") from exc
                self.peer_closed = True
                break
            if k <= 0:
                break
            sent += k
        return self._count_send(len(data), sent)

    def recv(self, timeout: float = 0.0) -> bytes:
        """Read what arrives within `timeout` seconds."""
        if not self._readable(self.fd, timeout):
            return b""
        try:
            data = os.read(self.fd, READ_SIZE)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno != errno.EIO:
                raise LinkError(f"pty {self.name}: read failed: {exc}") from exc
            self.peer_closed = True
            return b""
        return self._count_recv(data)

    def close(self) -> None:
        """Close the fd (idempotent)."""
        if not self.closed:
            self.closed = True
            os.close(self.fd)


def pty_pair() -> tuple[PtyTransport, PtyTransport]:
    """A pseudo-terminal as (master, slave) transports; slave.name is the device path."""
    master, slave = os.openpty()
    try:
        name = os.ttyname(slave)
        return PtyTransport(master, f"master of {name}"), PtyTransport(slave, name)
    except Exception:
        os.close(master)
        os.close(slave)
        raise


class UdpTransport(_Base):
    """A non-blocking UDP socket on loopback: connected to one peer, or (a server, see
    udp_server) answering whoever sent last; before anyone has sent, a server drops (and
    counts) what it is given."""

    def __init__(self, sock: socket.socket, connected: bool = True) -> None:
        super().__init__()
        self.sock = sock
        sock.setblocking(False)
        self.address: tuple[str, int] = sock.getsockname()
        self.connected = connected
        self.peer: tuple[str, int] | None = sock.getpeername() if connected else None
        self.sender: tuple[str, int] | None = None   # of the last datagram received
        self.follow_sender = True   # a server answers the last sender (hil.peer turns this off)

    def send(self, data: bytes) -> int:
        """Send one datagram; if the socket buffer is full or the peer is gone it is dropped."""
        self._check()
        sent = 0
        if self.peer is not None:
            try:
                sent = self.sock.send(data) if self.connected else self.sock.sendto(data, self.peer)
            except (BlockingIOError, ConnectionRefusedError):
                sent = 0
            except OSError as exc:
                raise LinkError(f"udp {self.address}: send failed: {exc}") from exc
        return self._count_send(len(data), sent)

    def recv(self, timeout: float = 0.0) -> bytes:
        """One datagram received within `timeout` seconds (b"" if none)."""
        if not self._readable(self.sock, timeout):
            return b""
        try:
            data, peer = self.sock.recvfrom(READ_SIZE)
        except (BlockingIOError, ConnectionRefusedError):
            return b""
        self.sender = peer
        if not self.connected and self.follow_sender:
            self.peer = peer
        return self._count_recv(data)

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if not self.closed:
            self.closed = True
            self.sock.close()


def udp_server(host: str = LOOPBACK, port: int = 0) -> UdpTransport:
    """A UDP socket listening on a loopback address that answers the last peer it heard from
    (hil.serve narrows that with hil.peer.PeerGuard: only a datagram with a valid frame)."""
    if not ipaddress.IPv4Address(host).is_loopback:
        raise LinkError(f"udp_server: {host} is not a loopback address")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise LinkError(f"udp {host}:{port}: cannot listen: {exc}") from exc
    return UdpTransport(sock, connected=False)


def udp_pair(host: str = LOOPBACK) -> tuple[UdpTransport, UdpTransport]:
    """Two UDP sockets on ephemeral loopback ports, each connected to the other."""
    if host != LOOPBACK:
        raise LinkError(f"udp_pair: only {LOOPBACK} is allowed, got {host!r}")
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        a.bind((host, 0))
        b.bind((host, 0))
        a.connect(b.getsockname())
        b.connect(a.getsockname())
    except OSError as exc:
        a.close()
        b.close()
        raise LinkError(f"udp_pair: {exc}") from exc
    return UdpTransport(a), UdpTransport(b)


class MavutilTransport(_Base):
    """A byte end over a `pymavlink.mavutil` connection: `mavserial` (pyserial, e.g. on the
    device's pseudo-terminal) or `mavudp`. mavutil opens the port and moves the bytes; parsing
    is left to hil.framing.Receiver, because mavutil's parser does not backtrack after garbage.
    Writes never block: pyserial with a zero write timeout spins on a full buffer, so a serial
    write happens only when select says the port takes bytes, and what does not fit is dropped
    like a UART overrun."""

    def __init__(self, mf, name: str) -> None:
        super().__init__()
        self.mf, self.name = mf, name
        self.serial = hasattr(mf.port, "baudrate")
        if self.serial:
            mf.port.write_timeout = 0
        self.peer_closed = False

    def send(self, data: bytes) -> int:
        """Write `data` (one datagram over UDP); return the bytes accepted."""
        self._check()
        if not self.serial:
            self.mf.write(data)     # mavudp drops a datagram it cannot send and returns None
            return self._count_send(len(data), len(data))
        _, writable, _ = select.select([], [self.mf.fd], [], 0.0)
        sent = self.mf.write(data) if writable else 0
        return self._count_send(len(data), max(sent or 0, 0))

    def recv(self, timeout: float = 0.0) -> bytes:
        """Bytes (a datagram over UDP) received within `timeout` seconds."""
        if not self._readable(self.mf.fd, timeout):
            return b""
        try:
            data = self.mf.recv(READ_SIZE)
        except OSError as exc:       # pyserial's SerialException is an OSError
            self.peer_closed = True  # a pty whose other side has closed reads as "no data"
            if self.serial:
                return b""
            raise LinkError(f"{self.name}: read failed: {exc}") from exc
        return self._count_recv(bytes(data or b""))

    def close(self) -> None:
        """Close the connection (idempotent)."""
        if not self.closed:
            self.closed = True
            self.mf.close()


class QueueTransport(_Base):
    """In-process end: every send is one packet in the peer's queue (deterministic, no OS)."""

    def __init__(self, capacity: int = 1 << 20) -> None:
        super().__init__()
        self.capacity = capacity
        self._inbox: collections.deque[bytes] = collections.deque()
        self._queued = 0
        self._cond = threading.Condition()
        self.peer: QueueTransport | None = None

    def send(self, data: bytes) -> int:
        """Put `data` in the peer's queue; dropped whole if it would exceed the capacity."""
        self._check()
        peer = self.peer
        if peer is None or peer.closed or peer._queued + len(data) > peer.capacity:
            return self._count_send(len(data), 0)
        with peer._cond:
            peer._inbox.append(bytes(data))
            peer._queued += len(data)
            peer._cond.notify()
        return self._count_send(len(data), len(data))

    def recv(self, timeout: float = 0.0) -> bytes:
        """The oldest queued packet, waiting at most `timeout` seconds."""
        self._check()
        with self._cond:
            if not self._inbox and timeout > 0:
                self._cond.wait(timeout)
            if not self._inbox:
                return b""
            data = self._inbox.popleft()
            self._queued -= len(data)
        return self._count_recv(data)

    def close(self) -> None:
        """Mark closed (idempotent)."""
        self.closed = True


def queue_pair(capacity: int = 1 << 20) -> tuple[QueueTransport, QueueTransport]:
    """Two in-process transports wired to each other."""
    a, b = QueueTransport(capacity), QueueTransport(capacity)
    a.peer, b.peer = b, a
    return a, b


# ---------------------------------------------------------------- impairments and timing

@dataclass(frozen=True)
class Impairments:
    """One direction of a link: baud (None = infinite), latency, jitter, loss, bit errors."""

    baud: float | None = None
    latency: float = 0.0
    jitter: float = 0.0  # uniform extra delay in [0, jitter] s; order is always kept
    loss: float = 0.0  # probability that a packet (one recv chunk) is lost
    bit_error_rate: float = 0.0  # independent per-bit flip probability
    max_backlog: float | None = None  # s of queued wire time beyond which packets overflow

    def __post_init__(self) -> None:
        if self.baud is not None and not self.baud > 0:
            raise LinkError(f"Impairments: baud must be > 0, got {self.baud!r}")
        if self.max_backlog is not None and not self.max_backlog >= 0:
            raise LinkError(f"Impairments: max_backlog must be >= 0, got {self.max_backlog!r}")
        for name in ("latency", "jitter"):
            if not getattr(self, name) >= 0:
                raise LinkError(f"Impairments: {name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("loss", "bit_error_rate"):
            value = getattr(self, name)
            if not 0 <= value <= 1:
                raise LinkError(f"Impairments: {name} must be in [0, 1], got {value!r}")


def wire_time(n_bytes: int, baud: float) -> float:
    """Seconds that `n_bytes` take on a UART at `baud` (10 bits per byte)."""
    return n_bytes * BITS_PER_BYTE / baud


def message_rates(baud: float, sizes: dict[str, int]) -> dict[str, float]:
    """Messages per second that fill a `baud` UART, per frame size in bytes (name -> size)."""
    return {name: baud / (BITS_PER_BYTE * size) for name, size in sizes.items()}


@dataclass
class ChannelStats:
    """Counters of one direction of the emulated link."""

    packets_in: int = 0
    packets_out: int = 0
    packets_lost: int = 0
    packets_overflow: int = 0
    packets_corrupted: int = 0
    bits_flipped: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    bytes_dropped_at_output: int = 0


@dataclass
class Channel:
    """One direction: schedules packets by wire time, latency and jitter; loses and corrupts."""

    imp: Impairments
    rng: random.Random
    stats: ChannelStats = field(default_factory=ChannelStats)
    wire_free_at: float = 0.0
    last_arrival: float = 0.0
    queue: collections.deque[tuple[float, bytes]] = field(default_factory=collections.deque)

    def submit(self, data: bytes, now: float) -> None:
        """Put `data` on the wire at time `now` (after whatever is still being transmitted)."""
        st, imp = self.stats, self.imp
        st.packets_in += 1
        st.bytes_in += len(data)
        start = max(now, self.wire_free_at)
        if imp.max_backlog is not None and start - now > imp.max_backlog:
            st.packets_overflow += 1  # the sender's buffer is full: dropped before the wire
            return
        end = start + (wire_time(len(data), imp.baud) if imp.baud else 0.0)
        self.wire_free_at = end  # a lost packet still occupied the wire
        if imp.loss and self.rng.random() < imp.loss:
            st.packets_lost += 1
            return
        data = self._corrupt(data)
        delay = imp.latency + (self.rng.uniform(0.0, imp.jitter) if imp.jitter else 0.0)
        arrival = max(end + delay, self.last_arrival)
        self.last_arrival = arrival
        self.queue.append((arrival, data))

    def _corrupt(self, data: bytes) -> bytes:
        """Flip each bit independently with probability bit_error_rate (geometric skipping)."""
        p, nbits = self.imp.bit_error_rate, 8 * len(data)
        if p <= 0 or nbits == 0:
            return data
        out = bytearray(data)
        flips, i = 0, -1
        log_q = math.log1p(-p) if p < 1 else -math.inf
        while True:
            u = 1.0 - self.rng.random()  # in (0, 1]
            i += 1 + (int(math.log(u) / log_q) if p < 1 else 0)
            if i >= nbits:
                break
            out[i >> 3] ^= 1 << (i & 7)
            flips += 1
        if flips:
            self.stats.bits_flipped += flips
            self.stats.packets_corrupted += 1
        return bytes(out)

    def due(self, now: float) -> list[bytes]:
        """Pop the packets that have arrived by `now`."""
        out = []
        while self.queue and self.queue[0][0] <= now:
            out.append(self.queue.popleft()[1])
        return out

    def next_arrival(self) -> float | None:
        """Arrival time of the oldest packet in flight, or None."""
        return self.queue[0][0] if self.queue else None


class VirtualClock:
    """A clock that moves only when told to (deterministic lockstep tests)."""

    def __init__(self, start: float = 0.0) -> None:
        self.t = start

    def now(self) -> float:
        """Current virtual time in seconds."""
        return self.t

    def advance(self, dt: float) -> float:
        """Move forward by `dt` >= 0 seconds; return the new time."""
        if dt < 0:
            raise LinkError(f"VirtualClock.advance: dt must be >= 0, got {dt!r}")
        self.t += dt
        return self.t


class WallClock:
    """Monotonic wall-clock time in seconds since creation."""

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Seconds since creation."""
        return time.monotonic() - self._t0


class Clock(Protocol):
    """Anything with now() in seconds."""

    def now(self) -> float:
        """Current time in seconds."""
        ...


class LinkEmulator:
    """Forwards packets a->b and b->a through impaired Channels, on a virtual or wall clock.

    `a` and `b` are the emulator's own ends (the peers of the two endpoints' transports).
    """

    def __init__(self, a: Transport, b: Transport, forward: Impairments,
                 backward: Impairments | None = None, clock: Clock | None = None,
                 seed: int = 0) -> None:
        self.a, self.b = a, b
        rng = random.Random(seed)
        self.ab = Channel(forward, random.Random(rng.getrandbits(64)))
        self.ba = Channel(backward if backward is not None else forward,
                          random.Random(rng.getrandbits(64)))
        self.clock: Clock = clock if clock is not None else VirtualClock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def pump(self, timeout: float = 0.0) -> int:
        """Take everything waiting on both ends, deliver what is due; return packets delivered."""
        with self._lock:
            now = self.clock.now()
            for src, chan in ((self.a, self.ab), (self.b, self.ba)):
                while data := src.recv(0.0):
                    chan.submit(data, now)
            delivered = 0
            for dst, chan in ((self.b, self.ab), (self.a, self.ba)):
                for data in chan.due(now):
                    sent = dst.send(data)
                    chan.stats.packets_out += 1
                    chan.stats.bytes_out += sent
                    chan.stats.bytes_dropped_at_output += len(data) - sent
                    delivered += 1
        if not delivered and timeout > 0:
            time.sleep(timeout)
        return delivered

    def next_event(self) -> float | None:
        """Earliest arrival time still in flight in either direction."""
        times = [t for t in (self.ab.next_arrival(), self.ba.next_arrival()) if t is not None]
        return min(times) if times else None

    def start(self, period: float = 0.0005) -> "LinkEmulator":
        """Pump in a background thread on the wall clock until stop()."""
        if not isinstance(self.clock, WallClock):
            raise LinkError("LinkEmulator.start: a background thread needs a WallClock")
        if self._thread is not None:
            raise LinkError("LinkEmulator.start: already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, args=(period,), daemon=True,
                                        name="hil-link-emulator")
        self._thread.start()
        return self

    def _run(self, period: float) -> None:
        while not self._stop.is_set():
            self.pump()
            self._stop.wait(period)

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the background thread and wait at most `timeout` s for it."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join(timeout)
        alive = self._thread.is_alive()
        self._thread = None
        if alive:
            raise LinkError(f"LinkEmulator.stop: thread did not end within {timeout} s")

    def __enter__(self) -> "LinkEmulator":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
