"""Robust MAVLink 2 receive path: scan, length check, CRC with CRC_EXTRA, backtrack, decode."""
from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType
from typing import Any

STX_V2 = 0xFD
HEADER_LEN = 10  # STX, len, incompat, compat, seq, sysid, compid, msgid (3 bytes)
CRC_LEN = 2
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
MAX_FRAME = HEADER_LEN + 255 + CRC_LEN + SIGNATURE_LEN


def _crc16(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
    """CRC-16/MCRF4XX (X.25) as MAVLink uses it; pure Python fallback."""
    for b in data:
        tmp = b ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = (crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)
    return crc


try:  # pymavlink uses fastcrc when it is installed; so do we
    from fastcrc import crc16 as _fast  # type: ignore[import-not-found]

    def crc16(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
        """CRC-16/MCRF4XX (X.25) of `data` starting from `crc`."""
        return _fast.mcrf4xx(bytes(data), crc)
except ImportError:  # pragma: no cover - depends on the install
    def crc16(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
        """CRC-16/MCRF4XX (X.25) of `data` starting from `crc`."""
        return _crc16(data, crc)


@dataclass
class FrameStats:
    """Counters of a Receiver; bytes_in == bytes_ok + bytes_skipped + pending bytes."""

    frames_ok: int = 0
    crc_errors: int = 0
    unknown_ids: int = 0
    bad_length: int = 0
    bad_flags: int = 0
    decode_errors: int = 0
    truncated: int = 0
    bytes_in: int = 0
    bytes_ok: int = 0
    bytes_skipped: int = 0

    @property
    def rejected(self) -> int:
        """Candidate frames rejected for any reason."""
        return (self.crc_errors + self.unknown_ids + self.bad_length + self.bad_flags
                + self.decode_errors + self.truncated)


def pack(mav: Any, msg: Any) -> bytes:
    """The frame of `msg` from the sender `mav` (a dialect's MAVLink: ids, signing), carrying the
    sender's next sequence number: MAVLink's per-sender count (mod 256) by which a receiver sees
    lost frames. `msg.pack` alone sends the same number every time; every frame a device or a
    host sends is packed here."""
    frame = bytes(msg.pack(mav))
    mav.seq = (mav.seq + 1) % 256
    return frame


def frame_length(payload_len: int, signed: bool = False) -> int:
    """Bytes on the wire of a MAVLink 2 frame with `payload_len` payload bytes."""
    return HEADER_LEN + payload_len + CRC_LEN + (SIGNATURE_LEN if signed else 0)


class Receiver:
    """Byte-stream MAVLink 2 receiver that backtracks after every bad candidate frame.

    `dialect` is a pymavlink-generated v2 module (e.g. `pymavlink.dialects.v20.common`); `mav`
    optionally supplies its `MAVLink` instance (for signing keys); frames with ids the dialect
    does not know are dropped and counted. Feeding data never raises on any byte content.
    """

    def __init__(self, dialect: ModuleType, mav: Any | None = None) -> None:
        self.dialect = dialect
        self.mav = mav if mav is not None else dialect.MAVLink(None)
        # id -> (crc_extra, max payload length incl. extensions)
        self._known: dict[int, tuple[int, int]] = {
            mid: (cls.crc_extra, cls.unpacker.size) for mid, cls in dialect.mavlink_map.items()}
        self._buf = bytearray()
        self.stats = FrameStats()

    @property
    def pending(self) -> int:
        """Bytes buffered while waiting for the rest of a candidate frame."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Any]:
        """Add received bytes; return the messages of every complete good frame, in order."""
        self.stats.bytes_in += len(data)
        self._buf += data
        return self._scan(final=False)

    def flush(self) -> list[Any]:
        """Line went idle: give up an incomplete candidate at the head (truncated) and rescan."""
        return self._scan(final=True)

    def _skip(self, n: int) -> None:
        self.stats.bytes_skipped += n

    def _scan(self, final: bool) -> list[Any]:
        buf, st, out = self._buf, self.stats, []
        pos, n = 0, len(buf)
        while True:
            i = buf.find(STX_V2, pos)
            if i < 0:
                self._skip(n - pos)
                pos = n
                break
            self._skip(i - pos)
            pos = i
            if n - pos < HEADER_LEN:
                if final:  # an incomplete header at idle: drop its start byte, keep scanning
                    st.truncated += 1
                    self._skip(1)
                    pos += 1
                    continue
                break
            plen, iflags = buf[pos + 1], buf[pos + 2]
            msgid = buf[pos + 7] | (buf[pos + 8] << 8) | (buf[pos + 9] << 16)
            known = self._known.get(msgid)
            reason = None
            if iflags & ~IFLAG_SIGNED:
                reason = "bad_flags"
            elif known is None:
                reason = "unknown_ids"
            elif plen > known[1]:
                reason = "bad_length"
            if reason is None:
                assert known is not None
                total = frame_length(plen, bool(iflags & IFLAG_SIGNED))
                if n - pos < total:
                    if final:
                        reason = "truncated"
                    else:
                        break  # wait for the rest of the frame
                else:
                    end = pos + HEADER_LEN + plen
                    crc = crc16(bytes((known[0],)), crc16(memoryview(buf)[pos + 1:end]))
                    if crc != buf[end] | (buf[end + 1] << 8):
                        reason = "crc_errors"
            if reason is not None:  # backtrack: resume at the byte after this start byte
                setattr(st, reason, getattr(st, reason) + 1)
                self._skip(1)
                pos += 1
                continue
            frame = bytearray(buf[pos:pos + total])
            try:
                msg = self.mav.decode(frame)
            except Exception:  # a good CRC but undecodable or badly signed: drop whole frame
                st.decode_errors += 1
                self._skip(total)
            else:
                st.frames_ok += 1
                st.bytes_ok += total
                out.append(msg)
            pos += total
        del buf[:pos]
        return out


def max_frame_length(msg_cls: Any, signed: bool = False) -> int:
    """Largest wire size of a frame of pymavlink message class `msg_cls` (untruncated payload)."""
    return frame_length(msg_cls.unpacker.size, signed)
