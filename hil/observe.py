"""A window on the running device for observers (the live view): snapshots of its state.

The real-time loop must not wait for an observer, so the device only *publishes*: every
`Device.observe(...)`-given number of ticks it builds one `Snapshot` (a few small copies and one
cond(J), a few microseconds) and swaps it into a `Latest`; readers in other threads take the
newest one whenever they like. Nothing is queued, so a slow or absent reader costs the loop
nothing more, and a reader never sees a half-updated state (a snapshot is immutable and replaced
whole under a lock held only for the swap). `publish_to` and `take_snapshot` are the device's
`Device.observe` and `Device.snapshot`.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

from hil.device_state import DeviceView
from hil.errors import DeviceError
from hil.input_bounds import check_rate
from stewart_fmu.kinematics import condition_number

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


def publish_to(dev: DeviceView, latest: Latest | None, hz: float = OBSERVE_HZ) -> None:
    """Publish a snapshot of `dev` into `latest` now and then every rate/hz ticks (at most every
    tick); None stops publishing. The cost falls on one tick in rate/hz."""
    why = check_rate(hz)
    if why is None and hz <= 0:
        why = f"rate must be > 0 Hz, got {hz!r}"
    if why:
        raise DeviceError(f"observe: {why}")
    dev.observe_every = max(1, round(dev.rate / hz))
    dev.observer = latest
    if latest is not None:
        latest.publish(dev.snapshot())


def take_snapshot(dev: DeviceView) -> Snapshot:
    """The state of `dev` now: time, pose, the pose of the setpoint followed, leg lengths, rack
    forces, cond(J) at the pose (stewart_fmu.kinematics.condition_number), armed."""
    o = dev.plant.outputs
    ref = dev.servo.reference_pose
    return Snapshot(dev.k, dev.k / dev.rate, tuple(o.q.tolist()),
                    None if ref is None else tuple(ref.tolist()), tuple(o.lengths.tolist()),
                    tuple(dev.plant.rack_force.tolist()), condition_number(dev.model, o.q),
                    dev.armed)
