"""A telemetry datagram source for the live pipeline's tests (shared by test_cue_live.py and
test_live_input.py)."""
from __future__ import annotations

from collections import deque


class Queue:
    """A DatagramSource over a deque (in-process, for exact counts)."""

    def __init__(self) -> None:
        self.q: deque[bytes] = deque()

    def recv(self) -> bytes | None:
        return self.q.popleft() if self.q else None

    def close(self) -> None:
        pass
