"""The GCS server as the transport of the device's loop (hil.serve.serve).

`serve` calls its transport's `recv` at least once between two ticks (it drains input right
before each tick), so `GcsLink.recv` is where the GCS controller's per-tick step runs
(`GcsController.step` is idempotent within a tick: it acts once per device tick k, before tick
k) and where the TCP server is polled, for at most the time `serve` would have waited. The
device's MAVLink replies to the controller's messages (acks, STATUSTEXT) have no MAVLink peer
here: they are counted and dropped. `recv` returns no MAVLink bytes.
"""
from __future__ import annotations

from hil.device import Device
from hil.errors import LinkError
from hil.gcs.controller import GcsController
from hil.gcs.server import GcsServer


class GcsLink:
    """hil.serve's transport for a device driven over GCS (see the module doc)."""

    def __init__(self, controller: GcsController, server: GcsServer) -> None:
        self.controller, self.server = controller, server
        self.dropped = 0          # MAVLink replies with nowhere to go

    def recv(self, timeout: float = 0.0) -> bytes:
        self.dropped += len(self.controller.step())
        self.server.poll(timeout)
        self.dropped += len(self.controller.step())
        return b""

    def send(self, data: bytes) -> int:
        return 0

    def close(self) -> None:
        self.server.close()


def gcs_link(device: Device, host: str, port: int) -> GcsLink:
    """The GCS controller for `device` and its server on (host, port) (port 0: any free one),
    as hil.serve's transport; LinkError when the port cannot be had."""
    controller = GcsController(device)
    try:
        server = GcsServer(controller, host, port)
    except OSError as exc:
        raise LinkError(f"--gcs {host}:{port}: cannot listen: {exc.strerror or exc}") from None
    return GcsLink(controller, server)
