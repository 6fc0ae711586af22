"""What the device says: STATUSTEXT numbered in chunks, under a repeat rule and a token bucket.

Every function takes the device (`hil.device.Device`); `Device` offers each as a method of the
same name. A text longer than 50 bytes goes out in chunks with a common id
(hil.protocol.statustext_chunks); `say_once` sends a text (or key) at most once in STATUS_REPEAT s
of device time, so a flood of bad input cannot flood the link; `limit` passes every reply
through the STATUSTEXT token bucket (hil.throttle.StatusLimiter).
"""
from __future__ import annotations

from typing import Any

from hil import mavlink_stewart as ms
from hil import protocol
from hil.device_state import DeviceView

STATUS_REPEAT = 0.1        # s: the same refusal text is not repeated within this device time
SAID_MAX = 256             # keys remembered for the repeat rule (then forgotten at once)


def statustext(dev: DeviceView, severity: int, text: str) -> list[Any]:
    """STATUSTEXT; longer than 50 bytes: chunks on UTF-8 character boundaries with a common
    id and chunk_seq 0, 1, ... (hil.protocol.statustext_chunks)."""
    msgs = protocol.statustext_messages(severity, text, dev.state.statustext_id % 0xFFFF + 1)
    if len(msgs) > 1:
        dev.state.statustext_id = msgs[0].id
    return msgs


def say_once(dev: DeviceView, severity: int, text: str, key: str | None = None) -> list[Any]:
    """A STATUSTEXT, unless one of the same key (default: the text) went out less than
    STATUS_REPEAT s of device time ago."""
    key = text if key is None else key
    said = dev.state.said
    last = said.get(key)
    if last is not None and (dev.k - last) * dev.dt < STATUS_REPEAT:
        dev.counters.statustexts_suppressed += 1
        return []
    if len(said) >= SAID_MAX:
        said.clear()
    said[key] = dev.k
    return dev.statustext(severity, text)


def say(dev: DeviceView, severity: int, text: str, key: str | None = None) -> list[Any]:
    """A STATUSTEXT of the device's own (e.g. hil.peer's notice), under the same repeat rule
    and token bucket as its replies."""
    return limit(dev, dev.say_once(severity, text, key))


def limit(dev: DeviceView, out: list[Any]) -> list[Any]:
    """The STATUSTEXT token bucket (hil.throttle.StatusLimiter) over `out`, counted."""
    n = dev.limiter.suppressed
    out = dev.limiter.filter(out, dev.k, ms.MAV_SEVERITY_CRITICAL)
    dev.counters.statustexts_rate_limited += dev.limiter.suppressed - n
    return out
