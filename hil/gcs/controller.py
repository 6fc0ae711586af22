"""The GCS controller in front of one `hil.device.Device`: its state and its per-tick step.

It holds what a PI hexapod controller holds (the commanded target, referenced, servo, the
system velocity, the travel range, the data recorder) and drives the device only through its
public input: MAVLink messages of our dialect given to `Device.receive` (arm, disarm, home,
LEG_SETPOINT) and nothing else, so the device's modes, bounds, watchdog and faults all apply.
`step()` runs once per device tick, before it (hil.gcs.tcp_transport calls it): it follows the device's
mode (referencing done, a fault that disarmed it), sends the move's setpoint for the tick
(hil.gcs.move_path) and records (hil.gcs.recorder). Commands come from hil.gcs.command_set.

Referencing (FRF) is the device's homing: arm, then MAV_CMD_NAV_RETURN_TO_LAUNCH (a quintic in
leg space to the scene's home); the axes count as referenced when the device reports ARMED
again, and the target is then 0 0 0 0 0 0 (the reference pose, hil.gcs.axes). Servo on/off
(SVO) is arm/disarm; the six axes switch together (the device has one mode). A fault of the
device (it disarms itself: an end stop, a numerical failure) or a setpoint it refuses ends the
move and is a motion error (1024) for every connection's next ERR?.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil.device import Device
from hil.gcs import errors as E
from hil.gcs.axes import AXES, MM_PER_M, Frame
from hil.gcs.coordinate_systems import Enabled, Systems
from hil.gcs.move_path import Mover
from hil.gcs.recorder import Recorder, Sample, leg_mm
from hil.operating_mode import Mode
from stewart_fmu.reach import Engine

VLS_DEFAULT = 10.0      # mm/s (and deg/s) system velocity at start
VLS_MIN = 1e-3
ONT_TOLERANCE = 1e-3    # mm or deg: an axis within this of its target, not moving, is on target
OUTBOX = 64             # replies to commands kept for the next step (the newest)
RANGE_MAX = (1000.0,) * 3 + (89.0,) * 3     # mm, deg: the travel-range search's bounds
RANGE_SCAN = 512        # steps out to RANGE_MAX in which each end of the travel range is sought
RANGE_STEPS = 40        # bisections of the step where it lies
RANGES_KEPT = 16        # travel ranges kept, one per frame (SPI, KEN)


class Session:
    """One connection's error register (ERR? reads and clears it; PI keeps the last error) and
    the reason of the last refusal (`why`: which limit a refused move leaves; GCS has no way to
    send it, PI's ERR? answers the code alone)."""

    def __init__(self) -> None:
        self.error = E.NO_ERROR
        self.why = ""
        self.seen_motion_errors = 0


class GcsController:
    """See the module doc."""

    def __init__(self, device: Device, velocity: float = VLS_DEFAULT) -> None:
        self.device = device
        self.zero = Frame(device.model.home)         # ZERO: the pivot's frame (SPI)
        self.systems = Systems()                     # KSW/KST/KLN/KEN
        self.frame: Frame | Enabled = self.zero      # what POS? and MOV speak in
        self.mover = Mover(device, self.frame)
        self.recorder = Recorder(device.rate)
        self.velocity = velocity
        self.vls_max = self.mover.speed * 1e3       # mm/s: the drive's no-load speed
        self.target = np.zeros(6)
        self.referenced = False
        self.referencing = False
        self.servo = False
        self.motion_errors = 0
        self.internal_errors = 0     # lines whose handler raised (hil.gcs.command_set.execute)
        self._ranges: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self.low, self.high = self.travel_range()
        self._k = -1
        self._refused = 0
        self._outbox: list[Any] = []     # the device's replies to commands, for the next step

    # --- the state as GCS reports it -----------------------------------------------------

    def position(self) -> np.ndarray:
        """The plant's pose in GCS coordinates (mm, deg)."""
        return self.frame.from_pose(np.asarray(self.device.snapshot().q))

    def on_target(self) -> np.ndarray:
        """Per axis: servo on, no move running, within ONT_TOLERANCE of the target."""
        if not self.servo or self.referencing or self.mover.moving:
            return np.zeros(6, dtype=bool)
        return np.abs(self.position() - self.target) <= ONT_TOLERANCE

    def moving(self) -> np.ndarray:
        """Per axis: a move or the referencing runs, or the axis settles outside tolerance."""
        if self.referencing or self.mover.moving:
            return np.ones(6, dtype=bool)
        if not self.servo:
            return np.zeros(6, dtype=bool)
        return np.abs(self.position() - self.target) > ONT_TOLERANCE

    # --- actions (checked by hil.gcs.command_set before they are called) ---------------------

    def command(self, cmd: int, p1: float = 0.0) -> list[Any]:
        """A COMMAND_LONG to the device; its replies (the first is the ack), which the next
        `step` also hands on (to a MAVLink peer beside GCS, hil.gcs.tcp_transport)."""
        out = self.device.receive(ms.MAVLink_command_long_message(
            self.device.mav.srcSystem, self.device.mav.srcComponent, cmd, 0, p1, 0, 0, 0, 0, 0, 0))
        self._outbox = (self._outbox + out)[-OUTBOX:]
        return out

    def servo_on(self) -> None:
        if not self.device.armed:
            self.command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        if self.device.armed and not self.servo:
            self.servo = True
            self.target = self.position()
            self.mover.reset(self.target)

    def servo_off(self) -> None:
        self.command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0.0)
        self.servo = self.referencing = False
        self.mover.reset(self.position())

    def reference(self) -> bool:
        """FRF: arm and home; False when the device refused to home."""
        self.servo_on()
        if not self.device.armed:
            return False
        ack = self.command(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH)
        if not ack or ack[0].result != ms.MAV_RESULT_ACCEPTED:
            return False
        self.mover.reset(self.position())
        self.referencing, self.referenced = True, False
        return True

    def check_target(self, target: np.ndarray) -> None:
        """GcsError 7 when an axis leaves its travel range (NLM?/PLM?)."""
        bad = [AXES[i] for i in range(6)
               if not (self.low[i] <= target[i] <= self.high[i])]
        if bad:
            raise E.GcsError(E.POS_OUT_OF_LIMITS, f"axes {' '.join(bad)} out of range")

    def feasible(self, target: np.ndarray) -> None:
        """VMO?: GcsError 7 when a move from the reference to `target` would be refused (the
        travel range, then every pose on the way: hil.gcs.move_path.Mover.check_path)."""
        self.check_target(target)
        self.mover.check_path(self.mover.reference, target)

    def set_pivot(self, pivot_mm: np.ndarray) -> None:
        """SPI: the pivot point (R S T, mm, in C) where U V W are 0 (PI's rule: else error 9):
        the commanded target, the path's reference and the pose (within ONT_TOLERANCE); X Y Z
        keep their values, since with no rotation the pivot moves as C's origin does. The travel
        range (NLM?/PLM?) is the new pivot's."""
        if self.systems.enabled:
            raise E.GcsError(E.SPI_NOT_WITH_CS, "a coordinate system is enabled (KEN ZERO)")
        here = self.position()
        if self.referencing or np.any(self.target[3:] != 0.0) \
                or np.any(self.mover.reference[3:] != 0.0) \
                or np.any(np.abs(here[3:]) > ONT_TOLERANCE):
            raise E.GcsError(E.SET_PIVOT_NOT_POSSIBLE, "U, V, W not all 0")
        self.zero = Frame(self.device.model.home, np.asarray(pivot_mm, dtype=float) / MM_PER_M)
        self.frame = self.mover.frame = self.zero
        self.low, self.high = self.travel_range()

    def at_rest(self) -> None:
        """GcsError 536 while a move or the referencing runs (coordinate systems change then)."""
        if self.referencing or self.mover.moving:
            raise E.GcsError(E.CS_WHILE_MOVING, "in motion")

    def reframe(self) -> None:
        """After KEN: POS?, MOV and the travel range in the enabled systems' frame; the target
        and the path's reference are the same poses, written in it."""
        old = self.frame
        self.frame = self.mover.frame = self.systems.frame(self.zero, self.device.model)
        self.target = self.frame.from_pose(old.to_pose(self.target))
        self.mover.reference = self.frame.from_pose(old.to_pose(self.mover.reference))
        self.low, self.high = self.travel_range()

    def move(self, target: np.ndarray) -> None:
        """MOV/MVR (already checked for servo and referencing): plan, then start."""
        self.check_target(target)
        path = self.mover.plan(target, self.velocity, self.device.k)
        self.mover.start(path)
        self.target = target.copy()

    def halt(self) -> None:
        """HLT: a move comes to rest smoothly along its path (hil.gcs.move_path.Mover.halt), the
        target is where it will rest; referencing is stopped as STP stops it."""
        if self.referencing or not (self.servo and self.device.armed):
            self.stop()
            return
        self.target = self.mover.halt(self.device.k)

    def stop(self) -> None:
        """STP/HLT/#24: the drives hold the lengths measured now; the target is that pose."""
        self.referencing = False
        if self.servo and self.device.armed:
            snap = self.device.snapshot()
            here = self.frame.from_pose(np.asarray(snap.q))
            self.mover.hold_here(np.asarray(snap.lengths), here)
            self.target = here

    # --- time ----------------------------------------------------------------------------

    def step(self) -> list[Any]:
        """Once per device tick, before it (idempotent within a tick): the device's replies."""
        dev = self.device
        k = dev.k
        if k == self._k:
            return []
        self._k = k
        if self.referencing and dev.mode is Mode.ARMED:
            self.referencing, self.referenced = False, True
            self.target = np.zeros(6)
            self.mover.reset(self.target)
        if self.servo and not dev.armed:          # the device disarmed itself: a fault
            self.servo = self.referencing = False
            self.motion_errors += 1
            self.mover.reset(self.position())
        out, self._outbox = self._outbox, []
        out += self.mover.step(k) if self.servo and not self.referencing else []
        if self.mover.refused != self._refused:
            self._refused = self.mover.refused
            self.motion_errors += 1
            self.target = self.position()
            self.mover.reset(self.target)
        if self.recorder.due(k):
            self.recorder.sample(self.sample())
        return out

    def sample(self) -> Sample:
        snap = self.device.snapshot()
        return Sample(snap.t, self.mover.reference.copy(),
                      self.frame.from_pose(np.asarray(snap.q)), leg_mm(self.device.l_ref),
                      leg_mm(snap.lengths), np.asarray(snap.forces, dtype=float))

    # --- the travel range ----------------------------------------------------------------

    def travel_range(self) -> tuple[np.ndarray, np.ndarray]:
        """The travel range of the frame now (`_travel_range`), kept for the last RANGES_KEPT
        frames (the pivot, the enabled work and tool, SP_COND_MAX): a client that switches
        between a few costs the device's loop one search each."""
        f = self.frame
        key = (tuple(self.zero.pivot), self.device.settings.cond_max,
               *((tuple(f.work), tuple(f.tool)) if isinstance(f, Enabled) else ()))
        if key not in self._ranges:
            if len(self._ranges) >= RANGES_KEPT:
                del self._ranges[next(iter(self._ranges))]
            self._ranges[key] = self._travel_range()
        low, high = self._ranges[key]
        return low.copy(), high.copy()

    def _reachable(self, g: np.ndarray, engine: Engine) -> np.ndarray:
        """Per GCS pose (rows of g): every leg within the device's setpoint stroke, and inside
        every limit of `engine` (its cond(J) limit SP_COND_MAX; Engine.binding spares cond's
        SVD where its bound is sure, which keeps SPI and KEN, which recompute the range, short
        on the device's loop)."""
        lengths = self.mover.lengths(g)
        b = self.device.capability
        return (np.all(lengths >= b.leg_min, axis=1) & np.all(lengths <= b.leg_max, axis=1)
                & (engine.binding(self.frame.to_pose(g)) < 0))

    def _travel_range(self) -> tuple[np.ndarray, np.ndarray]:
        """Per axis, with the other axes at 0, how far from the reference every pose on the way
        is reachable: the first unreachable one of RANGE_SCAN steps out to RANGE_MAX, then
        RANGE_STEPS bisections of that step (the twelve ends at once); rounded inwards to 1e-6
        (mm, deg). An end whose whole ray is reachable is RANGE_MAX; one whose reference is not
        is 0."""
        engine = Engine(self.device.model, cond_limit=self.device.settings.cond_max)
        ends = [(i, sign) for i in range(6) for sign in (-1.0, 1.0)]
        ok, bad = np.zeros(len(ends)), np.zeros(len(ends))
        rays = np.zeros((len(ends), RANGE_SCAN + 1, 6))     # the twelve rays in one call
        for e, (i, sign) in enumerate(ends):
            rays[e, :, i] = sign * np.linspace(0.0, RANGE_MAX[i], RANGE_SCAN + 1)
        reaches = self._reachable(rays.reshape(-1, 6), engine).reshape(len(ends), -1)
        for e, (i, sign) in enumerate(ends):
            ray, reach = rays[e], reaches[e]
            if reach.all():
                ok[e] = bad[e] = RANGE_MAX[i]
            elif reach[0]:
                first_bad = int(np.argmin(reach))
                ok[e], bad[e] = abs(ray[first_bad - 1, i]), abs(ray[first_bad, i])
        for _ in range(RANGE_STEPS):
            mid = 0.5 * (ok + bad)
            g = np.zeros((len(ends), 6))
            for e, (i, sign) in enumerate(ends):
                g[e, i] = sign * mid[e]
            reach = self._reachable(g, engine)
            ok, bad = np.where(reach, mid, ok), np.where(reach, bad, mid)
        low, high = np.zeros(6), np.zeros(6)
        for e, (i, sign) in enumerate(ends):
            (low if sign < 0 else high)[i] = sign * math.floor(ok[e] * 1e6) / 1e6
        return low, high
