"""UDP addresses given on a command line, "HOST:PORT", checked before any socket opens: one
parser for the device's server end (`device --udp`, hil.serve.loopback_address) and the live
pipeline's telemetry and device addresses (stewart_sim/live/address.py).

HOST is an IPv4 address; it must be a loopback one (127.0.0.0/8, or "localhost" for 127.0.0.1)
unless the caller allows remote addresses (`remote`), as the live commands do with `--remote`
(any IPv4 address; 0.0.0.0 listens on every interface). PORT is 1..65535, or 0 (any free port)
for an address to listen on (`listen`).
"""
from __future__ import annotations

import ipaddress

from hil.errors import LinkError


class AddressError(LinkError, ValueError):
    """An address is malformed or not allowed; the message names it and why."""


def host_port(text: str, what: str, remote: bool = False, listen: bool = True,
              loopback_only: str = "pass --remote to use another one") -> tuple[str, int]:
    """(host, port) of "HOST:PORT" (see the module doc); `what` names the address in the
    message, `loopback_only` says what to do about a non-loopback HOST."""
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
                           f"{loopback_only}")
    try:
        port = int(port_text)
    except ValueError:
        raise AddressError(f"{what} {text!r}: port {port_text!r} is not an integer") from None
    low = 0 if listen else 1
    if not low <= port <= 65535:
        raise AddressError(f"{what} {text!r}: port must be {low}..65535"
                           f"{' (0: any free port)' if listen else ''}, got {port}")
    return str(addr), port
