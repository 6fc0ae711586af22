"""Whom a UDP server device answers: the peer rule that stops a datagram from hijacking it.

`hil.link.udp_server` used to answer whoever sent the last datagram, so one datagram of garbage
from any port redirected replies and telemetry away from the host. `PeerGuard` (used by
`hil.serve.serve` on an unconnected UDP transport) switches the transport's peer only when a
datagram carried at least one VALID frame for this system (good CRC, decoded, addressed to us or
unaddressed; with a signing key: correctly signed with an acceptable timestamp, see hil.signing):

* the first such frame's sender becomes the peer (before it, telemetry goes nowhere);
* signing on: only an authenticated frame can change the peer (unsigned or forged frames are
  dropped by the device, so they never count as valid), and never while the device is armed: a
  second holder of the key (or a replay from another port) cannot take the replies and the
  telemetry away from the host that is driving the platform. Such a frame is still handled
  (it is authenticated), its replies go to the peer, the refusal is counted
  (`DeviceCounters.peer_kept`) and told to the peer; after disarm the peer may move again;
* unsigned: the device answers the sender of the last valid frame, and every change of peer is
  reported with a STATUSTEXT (WARNING) to the new and to the old peer, and counted
  (`DeviceCounters.peer_changes`).
"""
from __future__ import annotations

from typing import Any

from hil import mavlink_stewart as ms


def _fmt(addr: Any) -> str:
    return f"{addr[0]}:{addr[1]}" if isinstance(addr, tuple) and len(addr) == 2 else str(addr)


class PeerGuard:
    """Peer rule of one device on one unconnected UDP transport (see the module doc)."""

    def __init__(self, device: Any, transport: Any) -> None:
        self.device, self.transport = device, transport
        transport.follow_sender = False
        self._valid = device.counters.frames_valid

    @staticmethod
    def applies(transport: Any) -> bool:
        """True for a transport that answers a changing peer (hil.link.udp_server)."""
        return hasattr(transport, "follow_sender") and not getattr(transport, "connected", True)

    def after_feed(self) -> int:
        """Call after each datagram was fed to the device (before its replies are sent): follow
        the datagram's sender when it carried a valid frame. Returns the frames sent here (the
        change notice, to the new and the old peer)."""
        dev, tr = self.device, self.transport
        n = dev.counters.frames_valid
        valid, self._valid = n > self._valid, n
        sender = getattr(tr, "sender", None)
        if not valid or sender is None or sender == tr.peer:
            return 0
        signed = dev.verifier is not None
        if signed and dev.armed and tr.peer is not None:
            dev.counters.peer_kept += 1
            frames = [dev.pack(m) for m in dev.say(
                ms.MAV_SEVERITY_WARNING, f"peer kept while armed: {_fmt(sender)}", key="peer-kept")]
            for f in frames:
                tr.send(f)
            return len(frames)
        old, tr.peer = tr.peer, sender
        if old is None:
            return 0
        dev.counters.peer_changes += 1
        msgs = dev.say(ms.MAV_SEVERITY_NOTICE if signed else ms.MAV_SEVERITY_WARNING,
                       f"peer {_fmt(old)} -> {_fmt(sender)}" + (" (signed)" if signed else ""),
                       key="peer")
        frames = [dev.pack(m) for m in msgs]
        for peer in (old, sender):
            tr.peer = peer
            for f in frames:
                tr.send(f)
        return len(frames)
