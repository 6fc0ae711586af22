"""The live view of the emulated device (`stewart-sim device SCENE ... --view [PORT]`).

A stdlib `ThreadingHTTPServer` in a daemon thread, bound to 127.0.0.1 only (never a wildcard
address: the device and its picture stay on this machine), serves two things:

* ``/``: the page, the same 3D picture as the static view (stewart_sim.view.html
  `live_view_html` over the scene's `view_geometry`), which polls ``/state``;
* ``/state``: the device's newest snapshot (hil.observe.Snapshot) as JSON
  ``{"t", "q", "q_ref", "lengths", "forces", "cond", "armed", "tick", "f_vehicle",
  "f_delivered"}`` in the contract's units (s, m, rad, N, m/s^2; q_ref is null while the device
  holds, f_vehicle and f_delivered (specific forces at the pilot's head, platform frame) are
  null unless a cueing loop publishes them, a non-finite number is null).

The device publishes snapshots from its real-time loop (`hil.device.Device.observe`); this
server only reads the newest one, so however often a browser polls, the loop does not wait for
it. The JSON of a snapshot is built once and reused until the next one. Requests whose Host is
not this loopback address are refused (403): a web page elsewhere cannot reach the view through
a name that resolves to 127.0.0.1 (DNS rebinding). HTTP/1.1 keep-alive lets a polling page reuse
one connection (one handler thread) rather than open one per poll.
"""
from __future__ import annotations

import json
import math
import socket
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import TracebackType

from controller.config import ControllerConfig
from hil.observe import Latest, Snapshot
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model
from stewart_sim.view.geometry import view_geometry
from stewart_sim.view.html import live_view_html

LOOPBACK = "127.0.0.1"
STATE_PATH = "/state"
POLL = 0.1           # s: how soon shutdown() is seen by the server loop
IDLE_TIMEOUT = 10.0  # s: a keep-alive connection idle this long is closed (its thread ends)


class ViewError(StewartError):
    """The live view cannot listen as asked (port taken, not allowed)."""


def state_document(snapshot: Snapshot | None) -> dict:
    """The JSON object of `snapshot` (see the module doc); before the first one: t null."""
    if snapshot is None:
        return {"t": None, "q": None, "q_ref": None, "lengths": None, "forces": None,
                "cond": None, "armed": False, "tick": None, "f_vehicle": None,
                "f_delivered": None}
    return {"t": snapshot.t, "q": _finite(snapshot.q),
            "q_ref": None if snapshot.q_ref is None else _finite(snapshot.q_ref),
            "lengths": _finite(snapshot.lengths), "forces": _finite(snapshot.forces),
            "cond": _finite((snapshot.cond,))[0], "armed": snapshot.armed, "tick": snapshot.tick,
            "f_vehicle": _optional(snapshot.f_vehicle),
            "f_delivered": _optional(snapshot.f_delivered)}


def _finite(values: tuple[float, ...]) -> list[float | None]:
    """JSON has no inf or nan: such a value becomes null."""
    return [v if math.isfinite(v) else None for v in values]


def _optional(values: tuple[float, ...] | None) -> list[float | None] | None:
    """An optional vector: null when absent, else as `_finite`."""
    return None if values is None else _finite(values)


def live_page(model: Model, controller: ControllerConfig) -> str:
    """The page served at ``/``: the static view's 3D picture of `model` (its drives' peak force
    from `controller`, the device's), fed by ``/state``."""
    return live_view_html(view_geometry(model, controller=controller), state_url=STATE_PATH)


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    timeout = IDLE_TIMEOUT
    server: _Server

    def do_GET(self) -> None:  # noqa: N802 (the http.server name)
        if self.headers.get("Host") not in self.server.hosts:
            self._send(HTTPStatus.FORBIDDEN, "text/plain; charset=utf-8",
                       b"the live view answers only at its loopback address\n")
            return
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            self._send(HTTPStatus.OK, "text/html; charset=utf-8", self.server.page)
        elif path == STATE_PATH:
            self._send(HTTPStatus.OK, "application/json", self.server.state_bytes())
        else:
            self._send(HTTPStatus.NOT_FOUND, "text/plain; charset=utf-8", b"not found\n")

    def _send(self, status: HTTPStatus, content_type: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args) -> None:  # noqa: A002 (the http.server name)
        """Quiet: the device's terminal is for the device."""


class _Server(ThreadingHTTPServer):
    daemon_threads = True   # a connection left open never keeps the process alive

    def __init__(self, port: int, page: bytes, latest: Latest) -> None:
        super().__init__((LOOPBACK, port), _Handler)
        self.page, self.latest = page, latest
        bound = self.server_address[1]
        self.hosts = {f"{LOOPBACK}:{bound}", f"localhost:{bound}"}
        self._lock = threading.Lock()
        self._cached: tuple[Snapshot | None, bytes] | None = None
        self._open: set[socket.socket] = set()   # connections being served (keep-alive)

    def finish_request(self, request, client_address) -> None:
        with self._lock:
            self._open.add(request)
        try:
            super().finish_request(request, client_address)
        finally:
            with self._lock:
                self._open.discard(request)

    def hang_up(self) -> None:
        """End every open connection (a polling page's keep-alive): their threads see EOF."""
        with self._lock:
            for conn in self._open:
                try:
                    conn.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def state_bytes(self) -> bytes:
        snap = self.latest.latest()
        with self._lock:
            if self._cached is None or self._cached[0] is not snap:
                self._cached = (snap, json.dumps(state_document(snap)).encode())
            return self._cached[1]


class LiveView:
    """The live view's server: bound at construction (so a taken port fails before the device
    starts), serving from `start()` until `close()` (or the end of a `with` block)."""

    def __init__(self, page: str, latest: Latest, port: int = 0) -> None:
        if not (isinstance(port, int) and 0 <= port <= 65535):
            raise ViewError(f"--view: port must be 1-65535 (0: any free one), got {port!r}")
        try:
            self._server = _Server(port, page.encode(), latest)
        except OSError as exc:
            raise ViewError(f"--view: cannot listen on {LOOPBACK}:{port}: "
                            f"{exc.strerror or exc}") from None
        self._thread: threading.Thread | None = None

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) listened on."""
        host, port = self._server.server_address[:2]
        return str(host), int(port)

    @property
    def url(self) -> str:
        host, port = self.address
        return f"http://{host}:{port}/"

    def start(self) -> None:
        """Serve in a daemon thread."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._server.serve_forever, args=(POLL,),
                                            daemon=True, name="live-view")
            self._thread.start()

    def close(self) -> None:
        """Stop serving, end open connections and release the port (idempotent)."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join()
            self._thread = None
        self._server.hang_up()
        self._server.server_close()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
