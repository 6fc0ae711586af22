"""MAVLink 2 signature check that changes no state before the signature is proven good.

pymavlink's `MAVLink.check_signature` stores a stream's timestamp before it compares the
signature, so one forged frame with a valid CRC, the host's (link, system, component) and
timestamp 2^48-1 locks the real host out. `Verifier.check` follows the MAVLink 2 signing spec in
the safe order:

1. the frame must be signed (incompat flag 0x01, 13-byte signature block);
2. signature = first 6 bytes of SHA-256(key + header + payload + CRC + link id + timestamp),
   compared in constant time; a mismatch is rejected with no state change;
3. the timestamp (10 us units since 2015-01-01) may be at most `AHEAD` (1 minute) ahead of the
   device's clock (the larger of the wall clock and the newest timestamp accepted);
4. per stream (link id, system, component): newer than the last accepted timestamp; a new
   stream's first timestamp may be at most 1 minute behind the device's clock;
5. only then is the stream's timestamp stored (at most `MAX_STREAMS` streams are kept).

`SignedDecoder` puts the check in front of a key-less pymavlink `MAVLink.decode` (pymavlink's
own signing then never runs on input); a refused frame raises `SigningError`, which
`hil.framing.Receiver` drops and counts. `sign_outgoing` sets a device's own pymavlink `MAVLink`
to sign what it sends and returns the `Verifier` of what it receives.
"""
from __future__ import annotations

import hashlib
import hmac
import time
from typing import Any, Callable

from hil.errors import DeviceError

SIGNING_EPOCH = 1420070400  # 2015-01-01T00:00:00Z
MINUTE = 6_000_000          # one minute in 10 us units
AHEAD = MINUTE
BEHIND = MINUTE
MAX_STREAMS = 256
IFLAG_SIGNED = 0x01
SIGNATURE_LEN = 13
HEADER_LEN = 10


class SigningError(Exception):
    """A frame refused by the signature check (unsigned, bad signature, bad timestamp)."""


def wall_timestamp() -> int:
    """Now, in MAVLink 2 signing units (10 us since 2015-01-01)."""
    return int((time.time() - SIGNING_EPOCH) * 1e5)


class Verifier:
    """Check signatures of incoming frames (see the module doc)."""

    def __init__(self, key: bytes, clock: Callable[[], int] = wall_timestamp) -> None:
        self.key = bytes(key)
        self.clock = clock
        self.streams: dict[tuple[int, int, int], int] = {}
        self.newest = 0
        self.rejected: dict[str, int] = {}

    def now(self) -> int:
        return max(self.clock(), self.newest)

    def check(self, frame: bytes | bytearray) -> str | None:
        """None when the frame is signed and acceptable (its stream's timestamp is then
        stored), else why not (nothing stored)."""
        why = self._why(frame)
        if why is not None:
            self.rejected[why] = self.rejected.get(why, 0) + 1
        return why

    def _why(self, frame: bytes | bytearray) -> str | None:
        if len(frame) < HEADER_LEN + 2 + SIGNATURE_LEN or not frame[2] & IFLAG_SIGNED:
            return "unsigned"
        block = frame[-SIGNATURE_LEN:]
        mac = hashlib.sha256(self.key + bytes(frame[:-6])).digest()[:6]
        if not hmac.compare_digest(mac, bytes(block[7:13])):
            return "bad signature"
        link_id, ts = block[0], int.from_bytes(bytes(block[1:7]), "little")
        now = self.now()
        if ts > now + AHEAD:
            return "timestamp ahead"
        stream = (link_id, frame[5], frame[6])
        last = self.streams.get(stream)
        if last is None:
            if ts + BEHIND < now:
                return "timestamp too old"
            if len(self.streams) >= MAX_STREAMS:  # forget the stalest stream
                del self.streams[min(self.streams, key=self.streams.__getitem__)]
        elif ts <= last:
            return "timestamp replayed"
        self.streams[stream] = ts
        self.newest = max(self.newest, ts)
        return None


class SignedDecoder:
    """`decode(frame)`: Verifier.check, then a key-less pymavlink decode (see the module doc)."""

    def __init__(self, mav: Any, verifier: Verifier, on_reject: Callable[[str], None]) -> None:
        self.mav, self.verifier, self.on_reject = mav, verifier, on_reject

    def decode(self, frame: bytearray) -> Any:
        why = self.verifier.check(frame)
        if why is not None:
            self.on_reject(why)
            raise SigningError(why)
        return self.mav.decode(frame)


def sign_outgoing(mav: Any, key: bytes, clock: Callable[[], int],
                  on_reject: Callable[[str], None]) -> Verifier:
    """Make `mav` (pymavlink's MAVLink) sign every frame it packs with the 32-byte `key` (link
    id 0, timestamps from the wall clock) and refuse, through `on_reject`, any unsigned frame
    its own decode meets; the Verifier of incoming frames on `clock` (10 us units)."""
    if not isinstance(key, (bytes, bytearray)) or len(key) != 32:
        raise DeviceError("signing_key must be 32 bytes")
    s = mav.signing
    s.secret_key = bytes(key)
    s.link_id = 0
    s.sign_outgoing = True
    s.timestamp = wall_timestamp()

    def reject_unsigned(_mav: Any, _msg_id: int) -> bool:
        """pymavlink asks this for every unsigned or badly signed frame: reject and count."""
        on_reject("unsigned")
        return False

    s.allow_unsigned_callback = reject_unsigned
    return Verifier(s.secret_key, clock)
