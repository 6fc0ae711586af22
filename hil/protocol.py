"""Protocol helpers of the emulated device that ground stations rely on (pure functions).

* `statustext_chunks`: a text as STATUSTEXT chunks of at most 50 bytes, split on UTF-8
  character boundaries (every chunk decodes on its own); more than one chunk share a non-zero
  `id` and count `chunk_seq` from 0. MAVLink takes a chunk with a NUL in its text as the last
  one, so when the last chunk fills all 50 bytes an empty chunk follows. (A chunk cut short
  before a multi-byte character is not full either: a receiver that ends the message at the
  first short chunk, as MAVProxy and the spec do, loses the rest of a non-ASCII text; ASCII
  text always splits into full 50-byte chunks.)
* `param_set_value`: the value of a PARAM_SET by its `param_type`. REAL32 is the float;
  the integer types up to 32 bits (UINT8, INT8, UINT16, INT16, UINT32, INT32) use MAVLink's
  *bytewise* encoding (PX4, QGroundControl, MAVSDK): the integer's little-endian bytes are the
  first bytes of the 4-byte float field, which is read as raw bytes, not as a float value.
  REAL64, (U)INT64 and unknown types are refused.
* `home_position`: HOME_POSITION of the scene's home pose in the device's frame convention
  (the one of LOCAL_POSITION_NED, see hil.downlink): x = x_home, y = -y_home, z = -z_home (m,
  our frame N mapped to NED by a half turn about x), q the home attitude in NED
  (`hil.downlink.ned_attitude`), the approach vector equal to the home position; the device has
  no global position, so latitude, longitude and altitude are 0.
* `attitude_euler`: ATTITUDE's roll, pitch, yaw (ZYX, NED/FRD) of a pose: the NED rotation is
  T Rz(thz) Ry(thy) Rx(thx) T = Rz(-thz) Ry(-thy) Rx(thx) (T = diag(1, -1, -1)), so roll =
  thx, pitch = -thy, yaw = -thz.
"""
from __future__ import annotations

import struct
from typing import Any

from hil import mavlink_stewart as ms

STATUSTEXT_LEN = 50

_INT_FORMATS = {ms.MAV_PARAM_TYPE_UINT8: "<B", ms.MAV_PARAM_TYPE_INT8: "<b",
                ms.MAV_PARAM_TYPE_UINT16: "<H", ms.MAV_PARAM_TYPE_INT16: "<h",
                ms.MAV_PARAM_TYPE_UINT32: "<I", ms.MAV_PARAM_TYPE_INT32: "<i"}
_V2_HEADER = 10


def statustext_chunks(text: str, size: int = STATUSTEXT_LEN) -> list[bytes]:
    """UTF-8 chunks of `text` of at most `size` bytes, never inside a character (see above)."""
    chunks: list[bytes] = []
    cur = bytearray()
    for ch in text:
        b = ch.encode("utf-8", "replace")
        if len(cur) + len(b) > size:
            chunks.append(bytes(cur))
            cur = bytearray()
        cur += b
    chunks.append(bytes(cur))
    if len(chunks) > 1 and len(chunks[-1]) == size:
        chunks.append(b"")   # the NUL that ends the sequence
    return chunks


def statustext_messages(severity: int, text: str, chunk_id: int) -> list[Any]:
    """STATUSTEXT messages of `text`: one with id 0, or several with id `chunk_id` (> 0)."""
    chunks = statustext_chunks(text)
    if len(chunks) == 1:
        return [ms.MAVLink_statustext_message(severity, chunks[0], 0, 0)]
    return [ms.MAVLink_statustext_message(severity, c, chunk_id, n) for n, c in enumerate(chunks)]


def _value_bytes(msg: Any) -> bytes:
    """The 4 raw bytes of PARAM_SET.param_value (from the frame when there is one)."""
    buf = getattr(msg, "_msgbuf", None)
    if buf is not None and len(buf) > _V2_HEADER and buf[0] == 0xFD:
        plen = buf[1]
        return bytes(buf[_V2_HEADER:_V2_HEADER + min(plen, 4)]).ljust(4, b"\x00")
    return struct.pack("<f", float(msg.param_value))   # built in process: the float's bytes


def param_set_value(msg: Any) -> tuple[float | None, str | None]:
    """(value, None) of a PARAM_SET by its param_type, or (None, why it is refused)."""
    t = msg.param_type
    if t == ms.MAV_PARAM_TYPE_REAL32:
        return float(msg.param_value), None
    fmt = _INT_FORMATS.get(t)
    if fmt is None:
        name = ms.enums["MAV_PARAM_TYPE"][t].name if t in ms.enums["MAV_PARAM_TYPE"] else str(t)
        return None, f"type {name.removeprefix('MAV_PARAM_TYPE_')} unsupported"
    return float(struct.unpack_from(fmt, _value_bytes(msg))[0]), None


def param_encode_int(value: int, param_type: int = ms.MAV_PARAM_TYPE_INT32) -> float:
    """The float whose bytes carry integer `value` bytewise (what a sender puts in the field)."""
    raw = struct.pack(_INT_FORMATS[param_type], int(value)).ljust(4, b"\x00")
    return struct.unpack("<f", raw)[0]


def attitude_euler(q) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in NED/FRD of pose q (see the module doc)."""
    return float(q[3]), float(-q[4]), float(-q[5])


def home_position(home, attitude_q: tuple[float, float, float, float], usec: int) -> Any:
    """HOME_POSITION of the home pose `home` (x, y, z, thx, thy, thz in our frame N)."""
    x, y, z = float(home[0]), float(-home[1]), float(-home[2])
    return ms.MAVLink_home_position_message(0, 0, 0, x, y, z, list(attitude_q), x, y, z, usec)
