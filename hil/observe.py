"""A window on the running device for observers (the live view): snapshots of its state.

The real-time loop must not wait for an observer, so the device only *publishes*: every
`Device.observe(...)`-given number of ticks it builds one `Snapshot` (a few small copies and one
cond(J), a few microseconds) and swaps it into a `Latest`; readers in other threads take the
newest one whenever they like. Nothing is queued, so a slow or absent reader costs the loop
nothing more, and a reader never sees a half-updated state (a snapshot is immutable and replaced
whole under a lock held only for the swap).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

OBSERVE_HZ = 60.0   # default snapshot rate: a screen's frame rate; the loop runs at 1 kHz


@dataclass(frozen=True)
class Snapshot:
    """The device's state at one tick, in the contract's units (m, rad, N; docs/conventions.md)."""

    tick: int                           # ticks done; t = tick / rate
    t: float                            # device time, s
    q: tuple[float, ...]                # pose (x, y, z, thx, thy, thz) of the platform
    q_ref: tuple[float, ...] | None     # pose of the setpoint being followed (None: holding)
    lengths: tuple[float, ...]          # leg lengths, m
    forces: tuple[float, ...]           # actuator (rack) forces, N
    cond: float                         # cond(J) at q (stewart_fmu.kinematics); inf: q not finite
    armed: bool
    # specific forces at the pilot's head, m/s^2, in the platform frame, when a cueing loop
    # publishes them (None: not known, e.g. the device alone): the vehicle's (the cue asked
    # for) and the one the platform delivers at its pose and motion
    f_vehicle: tuple[float, float, float] | None = None
    f_delivered: tuple[float, float, float] | None = None


class Latest:
    """The newest Snapshot, shared between the device's thread and its readers."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._snapshot: Snapshot | None = None
        self._published = 0

    def publish(self, snapshot: Snapshot) -> None:
        """Replace the newest snapshot (called by the device, at its snapshot rate)."""
        with self._lock:
            self._snapshot = snapshot
            self._published += 1

    def latest(self) -> Snapshot | None:
        """The newest snapshot, None before the first."""
        with self._lock:
            return self._snapshot

    @property
    def published(self) -> int:
        """How many snapshots were published so far."""
        with self._lock:
            return self._published
