"""The link's bandwidth: frame sizes of our dialect and the message rates a serial line carries.

* `frame_sizes`: wire bytes of LEG_SETPOINT, LEG_STATE, DRIVE_STATUS, HEARTBEAT and LOCKSTEP from
  the generated dialect (`hil.framing.max_frame_length`: untruncated payload, unsigned; MAVLink 2
  may truncate trailing zero bytes, so these are the worst case).
* `loop_rate`: the highest closed-loop rate f at which both directions fit a UART (8N1, 10 bits
  a byte): host -> device one LEG_SETPOINT per step (plus one LOCKSTEP in lockstep), device ->
  host one LEG_STATE per step (plus LOCKSTEP in lockstep), DRIVE_STATUS at f / 10 and HEARTBEAT
  at 1 Hz. `rate_table` tabulates both per baud; `realtime_rates` is what a real-time run sends.
"""
from __future__ import annotations

import math

from hil import mavlink_stewart as ms
from hil.framing import max_frame_length
from hil.link import BITS_PER_BYTE, message_rates

BAUDS = (115200, 921600)
MESSAGES = {"LEG_SETPOINT": ms.MAVLink_leg_setpoint_message,
            "LEG_STATE": ms.MAVLink_leg_state_message,
            "DRIVE_STATUS": ms.MAVLink_drive_status_message,
            "HEARTBEAT": ms.MAVLink_heartbeat_message,
            "LOCKSTEP": ms.MAVLink_lockstep_message}


def frame_sizes(signed: bool = False) -> dict[str, int]:
    """Wire bytes of each message's frame, from the dialect's payload sizes."""
    return {name: max_frame_length(cls, signed) for name, cls in MESSAGES.items()}


def loop_rate(baud: float, sizes: dict[str, int], lockstep: bool = False) -> float:
    """Highest closed-loop rate (Hz) at which both directions of a `baud` UART fit."""
    byte_rate = baud / BITS_PER_BYTE
    up = sizes["LEG_SETPOINT"] + (sizes["LOCKSTEP"] if lockstep else 0)
    down = sizes["LEG_STATE"] + (sizes["LOCKSTEP"] if lockstep else 0) + sizes["DRIVE_STATUS"] / 10
    return min(byte_rate / up, (byte_rate - sizes["HEARTBEAT"]) / down)


def rate_table(bauds=BAUDS, signed: bool = False) -> dict:
    """{'sizes': name -> bytes, 'rates': baud -> name -> msg/s, 'loop': baud -> (real time Hz,
    lockstep Hz)}."""
    sizes = frame_sizes(signed)
    return {"sizes": sizes,
            "rates": {b: message_rates(b, sizes) for b in bauds},
            "loop": {b: (loop_rate(b, sizes), loop_rate(b, sizes, lockstep=True)) for b in bauds}}


#: The serial line the host assumes (connect_pty's default; a pseudo-terminal ignores it).
SERIAL_BAUD = 921600


def realtime_rates(link: str, rate: float, baud: float = SERIAL_BAUD) -> tuple[int, float]:
    """(setpoint every k controller samples, LEG_STATE rate in Hz) for a real-time run: every
    sample over UDP; over a serial line the smallest k at which setpoints up and states down
    fit the UART (loop_rate: 425 Hz at 921600 baud, so k = 3 at 1 kHz)."""
    if link != "serial":
        return 1, rate
    every = max(1, math.ceil(rate / loop_rate(baud, frame_sizes())))
    return every, rate / every
