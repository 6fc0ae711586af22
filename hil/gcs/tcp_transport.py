"""The GCS server as the transport of the device's loop (hil.serve.serve), beside a MAVLink one.

`serve` calls its transport's `recv` at least once between two ticks (it drains input right
before each tick), so `GcsLink.recv` is where the GCS controller's per-tick step runs
(`GcsController.step` is idempotent within a tick: it acts once per device tick k, before tick
k) and where the TCP server is polled, for at most the time `serve` would have waited.

With an `inner` MAVLink transport (hil.link's UDP server end or pseudo-terminal) the device
speaks both: `recv` returns what arrives on the inner transport (a datagram or bytes waiting
there first; the server's wait also wakes on it), `send` goes out on it, and so do the device's
replies to the controller's own messages (acks, STATUSTEXT); the UDP peer rule (hil.peer)
reads and sets the inner transport's peer through this one. Without it those replies have
nowhere to go: they are counted (`dropped`), and `recv` returns no bytes.
"""
from __future__ import annotations

from typing import Any

from hil.device import Device
from hil.errors import LinkError
from hil.gcs.controller import GcsController
from hil.gcs.server import GcsServer

# what hil.peer reads or sets on a UDP server end: forwarded to the inner transport
_FORWARDED = frozenset({"follow_sender", "sender", "peer", "connected"})


class GcsLink:
    """hil.serve's transport for a device driven over GCS (see the module doc)."""

    def __init__(self, controller: GcsController, server: GcsServer, inner: Any = None) -> None:
        self.controller, self.server, self.inner = controller, server, inner
        self.dropped = 0          # MAVLink replies with nowhere to go
        handle = getattr(inner, "sock", None) or getattr(inner, "fd", None)
        if handle is not None:
            server.wake_on(handle)

    def __getattr__(self, name: str) -> Any:
        inner = self.__dict__.get("inner")
        if name in _FORWARDED and inner is not None:
            return getattr(inner, name)
        raise AttributeError(name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _FORWARDED:
            if self.inner is None:
                raise AttributeError(name)
            setattr(self.inner, name, value)
        else:
            object.__setattr__(self, name, value)

    def recv(self, timeout: float = 0.0) -> bytes:
        self._step()
        if self.inner is not None:
            data = self.inner.recv(0.0)
            if data:
                return data
        self.server.poll(timeout)
        self._step()
        return self.inner.recv(0.0) if self.inner is not None else b""

    def send(self, data: bytes) -> int:
        return self.inner.send(data) if self.inner is not None else 0

    def _step(self) -> None:
        out = self.controller.step()
        if self.inner is None:
            self.dropped += len(out)
            return
        for m in out:
            self.inner.send(self.controller.device.pack(m))

    def close(self) -> None:
        self.server.close()
        if self.inner is not None:
            self.inner.close()


def gcs_link(device: Device, host: str, port: int, inner: Any = None) -> GcsLink:
    """The GCS controller for `device` and its server on (host, port) (port 0: any free one),
    as hil.serve's transport, beside the MAVLink transport `inner` if given; LinkError when the
    port cannot be had."""
    controller = GcsController(device)
    try:
        server = GcsServer(controller, host, port)
    except OSError as exc:
        raise LinkError(f"--gcs {host}:{port}: cannot listen: {exc.strerror or exc}") from None
    return GcsLink(controller, server, inner)
