"""Whom a UDP server device answers: the peer rule that stops a datagram from hijacking it.

A server that answered whoever sent the last datagram would let one datagram of garbage from any
port redirect replies and telemetry away from the host. `PeerGuard` (used by
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
* unsigned: the device answers the sender of the last valid frame, unless the peer itself sent a
  valid frame less than PEER_HOLD s ago (a host streaming setpoints keeps its replies whatever
  another port sends; a host quiet for PEER_HOLD s can be replaced), and every change of peer
  is reported with a STATUSTEXT (WARNING) to the new and to the earlier peer, and counted
  (`DeviceCounters.peer_changes`); a change refused by the hold is counted
  (`DeviceCounters.peer_kept`).

Served in real time, every datagram from an address other than the peer first passes its
sender's token bucket (hil.throttle.SourceLimiter, on the serve loop's clock): a trickle. A
datagram over the budget is dropped before it is decoded (so it can neither cost decoding time
nor move the peer) and counted: a flood of valid frames from another port does not reach the
decoder, and the host's frames behind it in the socket are read within the tick. An address
that went over its budget within hil.throttle.FLOOD_MEMORY s never becomes the peer, signed or
not (the change is refused and counted as `peer_kept`), even when the host has gone quiet.
(That the ticks start on time whatever arrives is the serve loop's drain deadline, hil.serve.)
In lockstep there are no ticks to protect: the host drives time, and nothing is limited.
Unsigned, a flood source that spoke before any host did is the peer, and unlimited: use signing
where another local process may be hostile.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from hil import mavlink_stewart as ms
from hil.throttle import SourceLimiter

# s (the serve loop's clock): how long a valid frame of the peer keeps it; longer than a host's
# pause between commands (a restarted host on a new port waits this long to be answered)
PEER_HOLD = 0.5


def _fmt(addr: Any) -> str:
    return f"{addr[0]}:{addr[1]}" if isinstance(addr, tuple) and len(addr) == 2 else str(addr)


class PeerGuard:
    """Peer rule of one device on one unconnected UDP transport (see the module doc)."""

    def __init__(self, device: Any, transport: Any, limit: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.device, self.transport, self.clock = device, transport, clock
        transport.follow_sender = False
        self._valid = device.counters.frames_valid
        self.limiter = SourceLimiter() if limit else None
        self._peer_heard = -float("inf")    # clock time of the peer's last valid frame

    def admit(self, nbytes: int, now: float) -> bool:
        """Whether the datagram just received (`nbytes` long, at clock time `now`) is the peer's
        or within its sender's budget (hil.throttle.SourceLimiter; always, without a limiter). A
        datagram over it is dropped undecoded and counted (`DeviceCounters.flood_dropped`)."""
        lim = self.limiter
        sender = getattr(self.transport, "sender", None)
        if lim is None or sender == self.transport.peer and sender is not None:
            return True
        if lim.admit(sender, nbytes, now):
            return True
        self.device.counters.flood_dropped += 1
        return False

    @staticmethod
    def applies(transport: Any) -> bool:
        """True for a transport that answers a changing peer (hil.link.udp_server)."""
        return hasattr(transport, "follow_sender") and not getattr(transport, "connected", True)

    def after_feed(self) -> int:
        """Call after each datagram was fed to the device (before its replies are sent): follow
        the datagram's sender when it carried a valid frame. Returns the frames sent here (the
        change notice, to the new and the earlier peer)."""
        dev, tr = self.device, self.transport
        n = dev.counters.frames_valid
        valid, self._valid = n > self._valid, n
        sender = getattr(tr, "sender", None)
        if not valid or sender is None:
            return 0
        now = self.clock()
        if sender == tr.peer:
            self._peer_heard = now
            return 0
        signed = dev.verifier is not None
        flooding = self.limiter is not None and self.limiter.flooding(sender, now)
        held = (signed and dev.armed or not signed and now - self._peer_heard < PEER_HOLD
                or flooding)
        if held and tr.peer is not None:
            dev.counters.peer_kept += 1
            why = "from a flood" if flooding else "while armed" if signed else "while it streams"
            frames = [dev.pack(m) for m in dev.say(
                ms.MAV_SEVERITY_WARNING, f"peer kept {why}: {_fmt(sender)}", key="peer-kept")]
            for f in frames:
                tr.send(f)
            return len(frames)
        old, tr.peer = tr.peer, sender
        self._peer_heard = now
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
