"""GCS over TCP: a non-blocking line server polled from the device's own loop (no threads).

`GcsServer.poll(timeout)` waits at most `timeout` for sockets to become ready, accepts, reads,
runs complete lines through hil.gcs.command_set.execute and writes answers. Everything is bounded:
at most `max_clients` connections (one more is accepted and closed at once, counted), a
connection idle for `idle_timeout` s is closed, a line longer than MAX_LINE bytes is an error 3
and is skipped up to its LF, at most LINES_PER_POLL lines run per poll, and none after
LINE_SHARE of a servo period (the rest waits for the next poll: a flood cannot hold the device's
ticks back), a long answer (DRR?) is formatted one chunk a poll while its connection's next
lines wait, at most READ_CHUNK bytes are read per connection per poll, and a connection whose
unsent answers pass OUT_HIGH bytes, or whose unrun input passes IN_HIGH bytes, is not read until
they drain (a client that floods, or sends queries and never reads, stalls only itself). A
client that resets or closes is dropped. Bytes are read as Latin-1 (PI's controllers speak
ASCII; cp1252 agrees with Latin-1 on every byte the answers use).
"""
from __future__ import annotations

import selectors
import socket
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

from hil.gcs import errors as E
from hil.gcs.command_set import execute
from hil.gcs.controller import GcsController, Session
from hil.gcs.parser import SINGLE_BYTE

PORT = 50000            # PI's GCS port
MAX_CLIENTS = 4
IDLE_TIMEOUT = 600.0    # s without input before a connection is closed
MAX_LINE = 1024         # bytes of one command line
LINES_PER_POLL = 32
LINE_SHARE = 0.25       # of a servo period: the time one poll may spend running lines
READ_CHUNK = 8192
OUT_HIGH = 1 << 20      # bytes of unsent answers above which a connection is not read
IN_HIGH = 1 << 16       # bytes of unrun input above which a connection is not read


@dataclass
class ServerStats:
    """What the server counted."""

    accepted: int = 0
    refused: int = 0          # connections over max_clients
    closed_idle: int = 0
    lines: int = 0            # lines run (answered or refused)
    errors: int = 0           # lines that set an error
    overlong: int = 0         # lines over MAX_LINE
    bytes_in: int = 0


@dataclass
class _Conn:
    sock: socket.socket
    last: float
    session: Session = field(default_factory=Session)
    inbuf: bytearray = field(default_factory=bytearray)
    out: bytearray = field(default_factory=bytearray)
    skipping: bool = False    # inside an overlong line: drop up to its LF
    events: int = selectors.EVENT_READ    # what the selector watches for (0: not registered)
    stream: Iterator[str] | None = None   # an answer still being formatted (DRR?)


class GcsServer:
    """The TCP end of the GCS twin (see the module doc)."""

    def __init__(self, controller: GcsController, host: str = "127.0.0.1", port: int = PORT, *,
                 max_clients: int = MAX_CLIENTS, idle_timeout: float = IDLE_TIMEOUT,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.controller = controller
        self.max_clients, self.idle_timeout, self.clock = max_clients, idle_timeout, clock
        self.stats = ServerStats()
        # select(2): microsecond timeouts (epoll and poll round up to the next millisecond, a
        # whole servo period late); a handful of sockets
        self.sel = selectors.SelectSelector()
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.listener.bind((host, port))
            self.listener.listen(max_clients)
        except OSError:
            self.listener.close()
            raise
        self.listener.setblocking(False)
        self.sel.register(self.listener, selectors.EVENT_READ, None)
        self.conns: dict[int, _Conn] = {}
        self._last_idle_check = clock()

    @property
    def address(self) -> tuple[str, int]:
        host, port = self.listener.getsockname()[:2]
        return host, port

    def wake_on(self, handle: Any) -> None:
        """Also end a poll's wait when `handle` (a socket or a file descriptor: the MAVLink
        transport beside this server) becomes readable; the server does not read it."""
        self.sel.register(handle, selectors.EVENT_READ, "wake")

    def close(self) -> None:
        for c in list(self.conns.values()):
            self._drop(c)
        self.sel.unregister(self.listener)
        self.listener.close()
        self.sel.close()

    # --- the poll ------------------------------------------------------------------------

    def poll(self, timeout: float = 0.0) -> None:
        """Wait up to `timeout` s, then serve whatever is ready (bounded; see the module doc)."""
        pending = any(self._has_line(c) or (c.stream is not None and len(c.out) < OUT_HIGH)
                      for c in self.conns.values())
        for key, mask in self.sel.select(0.0 if pending else max(0.0, timeout)):
            if key.data is None:
                self._accept()
                continue
            if key.data == "wake":
                continue
            c = self.conns.get(key.fd)
            if c is None:
                continue
            if mask & selectors.EVENT_READ:
                self._read(c)
            if mask & selectors.EVENT_WRITE and key.fd in self.conns:
                self._write(c)
        until = self.clock() + LINE_SHARE * self.controller.device.dt
        self._run_lines(until)
        self._stream_answers(until)
        now = self.clock()
        if now - self._last_idle_check >= 1.0:
            self._last_idle_check = now
            for c in [c for c in self.conns.values() if now - c.last > self.idle_timeout]:
                self.stats.closed_idle += 1
                self._drop(c)

    def _accept(self) -> None:
        for _ in range(self.max_clients + 1):
            try:
                sock, _ = self.listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            if len(self.conns) >= self.max_clients:
                self.stats.refused += 1
                sock.close()
                continue
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.conns[sock.fileno()] = _Conn(sock, self.clock())
            self.sel.register(sock, selectors.EVENT_READ, sock.fileno())
            self.stats.accepted += 1

    def _read(self, c: _Conn) -> None:
        try:
            data = c.sock.recv(READ_CHUNK)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._drop(c)
            return
        if not data:
            self._drop(c)
            return
        c.last = self.clock()
        self.stats.bytes_in += len(data)
        c.inbuf += data
        self._watch(c)

    def _write(self, c: _Conn) -> None:
        try:
            n = c.sock.send(c.out)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._drop(c)
            return
        del c.out[:n]
        self._watch(c)

    def _watch(self, c: _Conn) -> None:
        """Read while the unsent answers are under OUT_HIGH; write while there are some."""
        events = (selectors.EVENT_READ if len(c.out) < OUT_HIGH and len(c.inbuf) < IN_HIGH
                  else 0) | (selectors.EVENT_WRITE if c.out else 0)
        fd = c.sock.fileno()
        if fd not in self.conns or events == c.events:
            return
        if c.events:
            self.sel.unregister(c.sock)
        if events:               # none: wait for its lines to run (poll keeps running them)
            self.sel.register(c.sock, events, fd)
        c.events = events

    def _drop(self, c: _Conn) -> None:
        self.conns.pop(c.sock.fileno(), None)
        if c.events:
            self.sel.unregister(c.sock)
            c.events = 0
        c.sock.close()

    # --- lines ---------------------------------------------------------------------------

    def _has_line(self, c: _Conn) -> bool:
        return bool(c.inbuf) and c.stream is None and len(c.out) < OUT_HIGH and (
            c.inbuf[0] in SINGLE_BYTE or b"\n" in c.inbuf or len(c.inbuf) > MAX_LINE)

    def _run_lines(self, until: float) -> None:
        """Lines of the ready connections in turn, one each a round, within the poll's budget
        (at least one line a poll; none after the clock reads `until`)."""
        budget = LINES_PER_POLL
        while budget > 0:
            ready = [c for c in self.conns.values() if self._has_line(c)]
            if not ready:
                return
            for c in ready:
                budget -= 1
                self._one_line(c)
                if c.sock.fileno() in self.conns:
                    if c.out:
                        self._write(c)
                    else:
                        self._watch(c)
                if budget <= 0 or self.clock() >= until:
                    return

    def _stream_answers(self, until: float) -> None:
        """One chunk of each answer being formatted, for connections that took the last, while
        the poll's budget lasts (at least one chunk a poll)."""
        first = True
        for c in [c for c in self.conns.values() if c.stream is not None]:
            if len(c.out) >= OUT_HIGH or (not first and self.clock() >= until):
                continue
            first = False
            chunk = next(c.stream, None)
            if chunk is None:
                c.stream = None
            else:
                c.out += chunk.encode("latin-1", errors="replace")
            self._write(c)

    def _one_line(self, c: _Conn) -> None:
        buf = c.inbuf
        if not c.skipping and buf[0] in SINGLE_BYTE:
            text = SINGLE_BYTE[buf[0]]
            del buf[:1]
            self._run(c, text, single=True)
            return
        end = buf.find(b"\n")
        if end < 0 or end > MAX_LINE:          # overlong: error 3 once, skipped to its LF
            if not c.skipping:
                self._overlong(c)
            c.skipping = end < 0
            del buf[:len(buf) if end < 0 else end + 1]
            return
        line = bytes(buf[:end])
        del buf[:end + 1]
        if c.skipping:                         # the end of an overlong line
            c.skipping = False
            return
        self._run(c, line.decode("latin-1"), single=False)

    def _overlong(self, c: _Conn) -> None:
        self.stats.overlong += 1
        self.stats.errors += 1
        self.stats.lines += 1
        c.session.error = E.COMMAND_TOO_LONG

    def _run(self, c: _Conn, text: str, single: bool) -> None:
        self.stats.lines += 1
        before = c.session.error
        out = execute(self.controller, c.session, text)
        if c.session.error != before or (c.session.error and out is None):
            self.stats.errors += 1
        if isinstance(out, str):
            c.out += out.encode("latin-1", errors="replace")
        elif out is not None:
            c.stream = out
