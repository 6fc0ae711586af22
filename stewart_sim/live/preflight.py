"""What `cue-live` would do with a vehicle motion, before it is flown: the live loop itself
(live.session.make_session: the stepped washout on the telemetry grid, the reference at every
device tick, the safety envelope) on a simulated clock, the motion's samples handed to its
receiver at their own times as `telemetry-replay` sends them (live.replay.Replay), the device
an ideal one that answers every setpoint with the lengths sent.

So the envelope's verdict offline is the one the live loop reaches on a simulated clock: a
motion whose preflight has no intervention is flown by `cue-live` without one, and one it
limits is limited live by the same limits (the envelope is deterministic; on a real clock
the ticks' jitter moves the reference, see live.cue_stream). `cue` reports it beside the
offline feasibility (cueing.report.verdict).
"""
from __future__ import annotations

import math
from collections import deque
from types import SimpleNamespace

import numpy as np

from stewart_sim.cueing.motion import VehicleMotion
from stewart_sim.live.device_out import DeviceCounts
from stewart_sim.live.envelope import Interventions
from stewart_sim.live.receiver import TelemetryReceiver
from stewart_sim.live.replay import Replay
from stewart_sim.live.session import make_session
from stewart_sim.scene.load import Scene

HOLD_AFTER = 0.5   # s of ticks after the last sample (the reference extrapolates, then holds)


class _Queue:
    """A DatagramSource over datagrams put in memory."""

    def __init__(self) -> None:
        self.waiting: deque[bytes] = deque()

    def recv(self) -> bytes | None:
        return self.waiting.popleft() if self.waiting else None

    def close(self) -> None:
        self.waiting.clear()


class _IdealDevice:
    """The device end of the preflight: every setpoint taken, its lengths answered."""

    watchdog = math.inf

    def __init__(self) -> None:
        self.counts = DeviceCounts()
        self.send_time = 0.0

    def send(self, k, t, lengths, rates, force, force_rate) -> list:
        self.counts.setpoints += 1
        self.counts.states += 1
        return [SimpleNamespace(length=tuple(np.asarray(lengths, float)))]

    def hold(self) -> bool:
        return True


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def preflight(scene: Scene, motion: VehicleMotion, mode: str = "classical") -> Interventions:
    """The envelope's interventions when `cue-live` flies `motion` (sent at its own rate, from
    time 0) on a simulated clock, up to HOLD_AFTER s past its last sample (see the module
    doc); the optimal mode runs its MPC synchronously."""
    replay = Replay(motion, "native")
    source, clock, device = _Queue(), _Clock(), _IdealDevice()
    rate = scene.require_controller().rate
    session = make_session(scene, TelemetryReceiver(source, "native", clock), device,
                           1.0 / replay.period, mode=mode, synchronous=True)
    n = int(math.ceil((float(replay.t[-1]) + HOLD_AFTER) * rate)) + 1
    try:
        for k in range(n):
            clock.t = k / rate
            source.waiting.extend(replay.due(clock.t))
            session.tick(clock.t)
    finally:
        session.cue.close()
    return session.envelope.interventions
