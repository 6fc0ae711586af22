"""Leg setpoints to the device over MAVLink (hil.client), in real time or in lockstep.

`DeviceOut.open` connects (``udp:HOST:PORT``: hil.client.connect_udp, loopback; ``serial:DEV``:
hil.client.connect_pty, a serial port or pseudo-terminal), arms the device and raises its
LEG_STATE stream to its controller rate (parameter SR_LEG_STATE), so every tick's measured leg
lengths come back for the record. `send(k, ...)` sends LEG_SETPOINT k with the lengths, rates,
the feed-forward force and its rate. In real time it returns at once with whatever LEG_STATE
has arrived since; in lockstep (a device started with --lockstep: a simulated clock, for
tests) it sends LOCKSTEP(k) in the same datagram and waits (bounded: hil.client's timeout and
resends) for LEG_STATE(step=k), as hil.client.run_lockstep does, so the device ticks once per
setpoint and the whole chain runs on the host's simulated clock. `hold()` parks the device's
own way: DISARM, after which its drives hold the lengths measured at that moment.

`start` also reads the device's watchdog (parameter WDG_TIMEOUT: the time after which the
device holds its legs when no setpoint comes) into `watchdog`: the live loop takes a device
that sends no LEG_STATE back for that long as lost (stewart_sim.live.session).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil.client import RETRIES, TIMEOUT, Client, connect_pty, connect_udp
from hil.errors import LinkError
from stewart_sim.live.address import DeviceAddress


HOLD_WAIT = 0.2     # s for the DISARM's acknowledgement, per try
HOLD_TRIES = 5


@dataclass
class DeviceCounts:
    setpoints: int = 0
    states: int = 0
    statustexts: list[str] = field(default_factory=list)
    resends: int = 0


class DeviceOut:
    """The device end of the live loop (see the module doc)."""

    def __init__(self, client: Client, lockstep: bool = False, timeout: float = TIMEOUT,
                 retries: int = RETRIES) -> None:
        self.client = client
        self.lockstep = lockstep
        self.timeout, self.retries = timeout, retries
        self.counts = DeviceCounts()
        self.send_time = 0.0                # monotonic s just after the last setpoint left
        self.watchdog = math.inf            # the device's WDG_TIMEOUT (s), read by start()
        self._states: list[Any] = []
        client.on_message = self._note

    @classmethod
    def open(cls, where: DeviceAddress, lockstep: bool = False) -> "DeviceOut":
        """Connect to the device at `where` (not yet armed)."""
        transport = (connect_udp(where.host, where.port) if where.kind == "udp"
                     else connect_pty(where.host))
        return cls(Client(transport), lockstep)

    def _note(self, m: Any, now: float) -> None:
        t = m.get_type()
        if t == "LEG_STATE":
            self._states.append(m)
            self.counts.states += 1
        elif t == "STATUSTEXT":
            self.counts.statustexts.append(str(m.text))

    def start(self, rate: float) -> None:
        """Arm, ask for LEG_STATE at `rate` Hz and read the device's watchdog (LinkError when
        the device refuses)."""
        self.watchdog = self.client.get_param("WDG_TIMEOUT")
        if not self.client.arm():
            raise LinkError("the device refused to arm: "
                            + (self.counts.statustexts[-1] if self.counts.statustexts
                               else "no reason given"))
        self.client.set_param("SR_LEG_STATE", rate)
        self.client.drain()
        self._states.clear()

    def send(self, k: int, t: float, l: np.ndarray, ldot: np.ndarray, force: np.ndarray,
             force_rate: np.ndarray) -> list[Any]:
        """LEG_SETPOINT k (see the module doc); the LEG_STATEs that came since the last call."""
        msg = self.client.setpoint_message(k, t, l, ldot, force, force_rate)
        if not self.lockstep:
            self.client.send(msg)
            self.send_time = time.monotonic()
            self.counts.setpoints += 1
            self.client.poll(0.0)
        else:
            step = ms.MAVLink_lockstep_message(int(round(t * 1e6)), k)
            for _ in range(self.retries + 1):
                self.client.send_together(msg, step)
                self.send_time = time.monotonic()
                if self.client.wait_for(lambda m: m.get_type() == "LEG_STATE" and m.step == k,
                                        self.timeout) is not None:
                    break
                self.counts.resends += 1
            else:
                raise LinkError(f"lockstep: no LEG_STATE for step {k} after "
                                f"{self.retries + 1} tries of {self.timeout:g} s")
            self.counts.setpoints += 1
        out, self._states = self._states, []
        return out

    def poll(self) -> list[Any]:
        """The LEG_STATEs that came since the last call (no setpoint sent)."""
        self.client.poll(0.0)
        out, self._states = self._states, []
        return out

    def hold(self) -> bool:
        """DISARM: the drives hold where the legs are (True when acknowledged; bounded:
        HOLD_TRIES tries of HOLD_WAIT s, a device that is gone does not hold the exit up)."""
        try:
            return self.client.command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, timeout=HOLD_WAIT,
                                       retries=HOLD_TRIES - 1) == ms.MAV_RESULT_ACCEPTED
        except LinkError:
            return False

    def close(self) -> None:
        self.client.on_message = None
        self.client.close()
