"""The live pipeline's addresses on the command line, checked before any work (the host and
port by hil.address.host_port, the parser the device's own --udp uses).

Telemetry: ``udp://HOST:PORT``. HOST must be a loopback address (127.0.0.0/8 or ``localhost``)
unless the caller passes `remote=True` (the commands' ``--remote`` option): telemetry from
another machine, or sent to one, is then allowed explicitly (any IPv4 address, 0.0.0.0 to
listen on every interface). The device: ``udp:HOST:PORT`` (the emulated device, loopback only:
hil.client.connect_udp) or ``serial:DEV`` (a serial port or pseudo-terminal).
"""
from __future__ import annotations

from dataclasses import dataclass

from hil.address import AddressError, host_port

__all__ = ["AddressError", "DeviceAddress", "device_address", "telemetry_address"]


@dataclass(frozen=True)
class DeviceAddress:
    """Where the device listens: kind "udp" (host, port) or "serial" (path in `host`)."""

    kind: str
    host: str
    port: int = 0


def telemetry_address(text: str, remote: bool = False, listen: bool = True) -> tuple[str, int]:
    """(host, port) of ``udp://HOST:PORT`` (see the module doc); `listen`: port 0 (any free
    port) allowed."""
    scheme, sep, rest = text.partition("://")
    if not sep or scheme != "udp":
        raise AddressError(f"telemetry address {text!r}: expected udp://HOST:PORT")
    return host_port(rest, "telemetry address", remote, listen)


def device_address(text: str) -> DeviceAddress:
    """``udp:HOST:PORT`` (loopback) or ``serial:DEV`` (see the module doc)."""
    kind, sep, rest = text.partition(":")
    if sep and kind == "udp" and not rest.startswith("//"):
        host, port = host_port(rest, "device address", remote=False, listen=False)
        return DeviceAddress("udp", host, port)
    if sep and kind == "serial" and rest:
        return DeviceAddress("serial", rest)
    raise AddressError(f"device address {text!r}: expected udp:HOST:PORT or serial:DEV")
