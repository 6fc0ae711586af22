"""The live pipeline's addresses on the command line, checked before any work.

Telemetry: ``udp://HOST:PORT``. HOST must be a loopback address (127.0.0.0/8 or ``localhost``)
unless the caller passes `remote=True` (the commands' ``--remote`` option): telemetry from
another machine, or sent to one, is then allowed explicitly (any IPv4 address, 0.0.0.0 to
listen on every interface). The device: ``udp:HOST:PORT`` (the emulated device, loopback only:
hil.client.connect_udp) or ``serial:DEV`` (a serial port or pseudo-terminal).
"""
from __future__ import annotations

import ipaddress
from dataclasses import dataclass

from stewart_fmu.errors import StewartError


class AddressError(StewartError, ValueError):
    """An address on the command line is malformed or not allowed; the message names it."""


@dataclass(frozen=True)
class DeviceAddress:
    """Where the device listens: kind "udp" (host, port) or "serial" (path in `host`)."""

    kind: str
    host: str
    port: int = 0


def _host_port(text: str, what: str, remote: bool, listen: bool) -> tuple[str, int]:
    host, sep, port_text = text.rpartition(":")
    if not sep or not host:
        raise AddressError(f"{what} {text!r}: expected HOST:PORT")
    if host == "localhost":
        host = "127.0.0.1"
    try:
        addr = ipaddress.IPv4Address(host)
    except ValueError:
        raise AddressError(f"{what} {text!r}: {host!r} is not an IPv4 address") from None
    if not addr.is_loopback and not remote:
        raise AddressError(f"{what} {text!r}: {host} is not a loopback address (127.0.0.1); "
                           "pass --remote to use another one")
    try:
        port = int(port_text)
    except ValueError:
        raise AddressError(f"{what} {text!r}: port {port_text!r} is not an integer") from None
    low = 0 if listen else 1
    if not low <= port <= 65535:
        raise AddressError(f"{what} {text!r}: port must be {low}..65535, got {port}")
    return str(addr), port


def telemetry_address(text: str, remote: bool = False, listen: bool = True) -> tuple[str, int]:
    """(host, port) of ``udp://HOST:PORT`` (see the module doc); `listen`: port 0 (any free
    port) allowed."""
    scheme, sep, rest = text.partition("://")
    if not sep or scheme != "udp":
        raise AddressError(f"telemetry address {text!r}: expected udp://HOST:PORT")
    return _host_port(rest, "telemetry address", remote, listen)


def device_address(text: str) -> DeviceAddress:
    """``udp:HOST:PORT`` (loopback) or ``serial:DEV`` (see the module doc)."""
    kind, sep, rest = text.partition(":")
    if sep and kind == "udp" and not rest.startswith("//"):
        host, port = _host_port(rest, "device address", remote=False, listen=False)
        return DeviceAddress("udp", host, port)
    if sep and kind == "serial" and rest:
        return DeviceAddress("serial", rest)
    raise AddressError(f"device address {text!r}: expected udp:HOST:PORT or serial:DEV")
