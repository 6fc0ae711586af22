"""The operator's commands to a running `cue-live`: a word per line on its standard input (when
that is a terminal) or per datagram on its control port (``--control udp://127.0.0.1:PORT``,
loopback unless --remote), read without blocking once per tick.

    park     fade to neutral (the home pose) at the envelope's safe rate and hold there;
             telemetry is read and counted but moves nothing until `resume`
    resume   back to cueing from neutral (the washout restarts at rest)
    estop    emergency stop: the device is disarmed at once (its drives hold the legs where
             they are) and the session ends
    quit     park, then end the session

Anything else is counted (`unknown`) and ignored; at most MAX_COMMANDS are taken per tick.
"""
from __future__ import annotations

import os
import select
import socket
import sys
from typing import IO

from stewart_sim.live.address import AddressError

COMMANDS = ("park", "resume", "estop", "quit")
MAX_COMMANDS = 8
READ_SIZE = 64


class Control:
    """Non-blocking operator input (see the module doc)."""

    def __init__(self, stdin: IO[str] | None = None, udp: tuple[str, int] | None = None) -> None:
        self.stdin = stdin
        self.sock: socket.socket | None = None
        if udp is not None:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                self.sock.bind(udp)
            except OSError as exc:
                self.sock.close()
                raise AddressError(f"control udp://{udp[0]}:{udp[1]}: cannot listen: "
                                   f"{exc.strerror or exc}") from None
            self.sock.setblocking(False)
        self.unknown = 0

    @classmethod
    def for_terminal(cls, udp: tuple[str, int] | None = None) -> "Control":
        """stdin when it is a terminal, and the control port when given."""
        tty = sys.stdin if sys.stdin is not None and sys.stdin.isatty() else None
        return cls(tty, udp)

    @property
    def address(self) -> tuple[str, int] | None:
        return None if self.sock is None else self.sock.getsockname()

    def poll(self) -> list[str]:
        """The commands waiting (see the module doc)."""
        words: list[str] = []
        if self.stdin is not None:
            while len(words) < MAX_COMMANDS and select.select([self.stdin], [], [], 0.0)[0]:
                line = os.read(self.stdin.fileno(), READ_SIZE).decode("ascii", "replace")
                if not line:
                    self.stdin = None          # end of input: no more commands from there
                    break
                words += line.split()
        while self.sock is not None and len(words) < MAX_COMMANDS:
            try:
                data = self.sock.recv(READ_SIZE)
            except (BlockingIOError, InterruptedError, ConnectionRefusedError):
                break
            words += data.decode("ascii", "replace").split()[:1]
        out = []
        for w in words[:MAX_COMMANDS]:
            w = w.strip().lower()
            if w in COMMANDS:
                out.append(w)
            else:
                self.unknown += 1
        return out

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
