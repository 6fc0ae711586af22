"""Vehicle telemetry datagrams decoded into one sample of the cueing input (motion.py's frame and
units): time, specific force, angular velocity and, when the sender gives it, the attitude.

Native format (`encode` / `decode_native`), little-endian, fixed size:

    offset  size  field
    0       3     magic b"STW"
    3       1     version, 1
    4       8*7   float64 t (s), fx, fy, fz (m/s^2), wx, wy, wz (rad/s)
    60      8*3   optional float64 roll, pitch, yaw (rad)

60 bytes without attitude, 84 with it; any other size is refused. Specific force and angular
velocity are in the vehicle frame, x forward, y left, z up (at rest on level ground f = (0, 0,
+9.81)), the columns MOTION_COLUMNS of a motion CSV. The attitude is the vehicle frame's
Z-Y-X (yaw, pitch, roll) angles in a z-up world frame, each a right-handed rotation about our
axes (so a positive pitch lowers the nose).

OutSim (`decode_outsim`): the packet Live for Speed sends with "OutSim Opts 0" (and games that
copied it), 64 bytes, or 68 with the optional trailing ID:

    offset  type        field
    0       uint32      Time (ms)
    4       float32[3]  AngVel (rad/s)
    16      float32     Heading (anticlockwise from above, about Z)
    20      float32     Pitch (anticlockwise from the right, about X)
    24      float32     Roll (anticlockwise from the front, about Y)
    28      float32[3]  Accel (m/s^2)
    40      float32[3]  Vel (m/s)
    52      int32[3]    Pos (1 m = 65536)
    64      int32       ID (optional)

LFS's axes are X right, Y forward, Z up, and AngVel and Accel are given in its world axes (X, Y
on the ground). The car's orientation is taken as R = Rz(Heading) Rx(Pitch) Ry(Roll) (car axes
to world, heading 0 facing world +Y; LFS names the three angles' axes, not their order).
Accel is the acceleration, so the specific force is Accel - g with g = (0, 0, -9.81) in the
world, rotated into the car (R^T), and so is AngVel. The car's axes (right, forward, up) then
map onto ours as x = forward, y = -right, z = up; the attitude reported is roll = Roll,
pitch = -Pitch (LFS's positive pitch raises the nose), yaw = Heading. Vel and Pos are not used
(a sample needs neither) and are not checked.

Bad input (wrong size, magic or version, a non-finite value, a specific force or angular
velocity beyond motion.py's VALUE_BOUNDS, a time beyond +-TIME_BOUND) raises TelemetryError with
a one-line reason; no other exception leaves a decoder, whatever the bytes.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.scene import DEFAULT_GRAVITY
from stewart_sim.cueing.motion import VALUE_BOUNDS

NATIVE_MAGIC = b"STW"
NATIVE_VERSION = 1
_NATIVE_HEADER = struct.Struct("<3sB")
_NATIVE_BODY = struct.Struct("<7d")
_NATIVE_ATTITUDE = struct.Struct("<3d")
NATIVE_SIZES = (_NATIVE_HEADER.size + _NATIVE_BODY.size,
                _NATIVE_HEADER.size + _NATIVE_BODY.size + _NATIVE_ATTITUDE.size)  # 60, 84

# Live for Speed's OutSimPack (InSim.txt, "OutSim - MOTION SIMULATOR SUPPORT": "X and Y axes
# are on the ground, Z is up"), its layout as quoted in
# https://lfs.net/forum/thread/775-Motion-Data-with-External-View and in
# https://app.unpkg.com/node-insim@4.7.0/files/dist/types/out/OutSimPack.d.ts (sizes 64, 68);
# heading 0 is "world y direction" as InSim's CarContact says
# (https://simbroadcasts.github.io/node-insim/classes/packets.CarContact.html).
# Codemasters' GRID, DiRT 2 and F1 2010 send an output "designed to be compatible" with it
# (http://www.lfsforum.net/showthread.php?t=73997). BeamNG.drive's own OutSim template was
# deprecated in its 0.32 protocol overhaul for its MotionSim protocol, a different packet
# (https://forum.beamng.tech/t/confirmation-of-measurement-scale-in-beamng-tech/78).
_OUTSIM = struct.Struct("<I3f3f3f3f3i")
OUTSIM_SIZES = (_OUTSIM.size, _OUTSIM.size + 4)  # 64, 68 with the ID


# s: a telemetry time's bound (OutSim's whole range, and Unix time to 2106); float64 resolves
# 1 us there, so a grid of a 1 kHz telemetry rate stays distinct (and steps always advance)
TIME_BOUND = float(2 ** 32)

# what a refused datagram was (TelemetryError.kind), the keys of the live receiver's counts
REFUSAL_KINDS = ("malformed", "truncated", "non_finite", "absurd")


class TelemetryError(StewartError, ValueError):
    """A telemetry datagram is malformed or its values are not a vehicle's motion; `kind` is one
    of REFUSAL_KINDS: malformed (wrong type, size, magic or version), truncated (shorter than
    the format's smallest datagram), non_finite (a NaN or infinity), absurd (beyond the bounds
    of a vehicle's motion)."""

    def __init__(self, message: str, kind: str = "malformed") -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class TelemetrySample:
    """One telemetry sample in the cueing input's frame (vehicle x forward, y left, z up)."""

    t: float                                            # s
    specific_force: tuple[float, float, float]          # m/s^2; at rest (0, 0, +9.81)
    angular_velocity: tuple[float, float, float]        # rad/s
    attitude: tuple[float, float, float] | None = None  # roll, pitch, yaw (rad)

    def __post_init__(self) -> None:
        fields = [("t", (self.t,)), ("specific force", self.specific_force),
                  ("angular velocity", self.angular_velocity)]
        if self.attitude is not None:
            fields.append(("attitude", self.attitude))
        for name, values in fields:
            try:
                as_floats = tuple(float(v) for v in values)
            except (TypeError, ValueError):
                raise TelemetryError(f"telemetry: {name} must be numbers") from None
            if len(as_floats) != (1 if name == "t" else 3):
                raise TelemetryError(f"telemetry: {name} must have 3 components, "
                                     f"got {len(as_floats)}")
            bad = [v for v in as_floats if not math.isfinite(v)]
            if bad:
                raise TelemetryError(f"telemetry: {name}: non-finite value {bad[0]!r}",
                                     "non_finite")
            if name == "t" and abs(as_floats[0]) > TIME_BOUND:
                raise TelemetryError(f"telemetry: t: {as_floats[0]!r} s beyond the bound "
                                     f"{TIME_BOUND:g} s", "absurd")
            if name in ("specific force", "angular velocity"):
                key, unit = ("f", "m/s^2") if name == "specific force" else ("w", "rad/s")
                big = [v for v in as_floats if abs(v) > VALUE_BOUNDS[key]]
                if big:
                    raise TelemetryError(f"telemetry: {name}: {big[0]!r} beyond the bound "
                                         f"{VALUE_BOUNDS[key]:g} {unit}", "absurd")
            attribute = {"t": "t", "specific force": "specific_force",
                         "angular velocity": "angular_velocity", "attitude": "attitude"}[name]
            object.__setattr__(self, attribute, as_floats[0] if name == "t" else as_floats)


def encode(sample: TelemetrySample) -> bytes:
    """The native datagram of a sample (60 bytes, 84 with its attitude)."""
    out = (_NATIVE_HEADER.pack(NATIVE_MAGIC, NATIVE_VERSION)
           + _NATIVE_BODY.pack(sample.t, *sample.specific_force, *sample.angular_velocity))
    if sample.attitude is not None:
        out += _NATIVE_ATTITUDE.pack(*sample.attitude)
    return out


def _as_bytes(data: object, what: str) -> bytes:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TelemetryError(f"{what}: a datagram must be bytes, got {type(data).__name__}")
    return bytes(data)


def decode_native(data: bytes) -> TelemetrySample:
    """A native datagram (see the module doc) -> its sample; TelemetryError when malformed."""
    raw = _as_bytes(data, "native telemetry")
    if len(raw) not in NATIVE_SIZES:
        raise TelemetryError(f"native telemetry: {len(raw)} bytes, expected "
                             f"{NATIVE_SIZES[0]} or {NATIVE_SIZES[1]}",
                             "truncated" if len(raw) < NATIVE_SIZES[0] else "malformed")
    magic, version = _NATIVE_HEADER.unpack_from(raw, 0)
    if magic != NATIVE_MAGIC:
        raise TelemetryError(f"native telemetry: magic {magic!r}, expected {NATIVE_MAGIC!r}")
    if version != NATIVE_VERSION:
        raise TelemetryError(f"native telemetry: version {version}, expected {NATIVE_VERSION}")
    body = _NATIVE_BODY.unpack_from(raw, _NATIVE_HEADER.size)
    attitude = (_NATIVE_ATTITUDE.unpack_from(raw, NATIVE_SIZES[0])
                if len(raw) == NATIVE_SIZES[1] else None)
    return TelemetrySample(body[0], body[1:4], body[4:7], attitude)


def _car_to_world(heading: float, pitch: float, roll: float) -> np.ndarray:
    """LFS's car axes (right, forward, up) to its world axes: Rz(heading) Rx(pitch) Ry(roll)."""
    ch, sh = math.cos(heading), math.sin(heading)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    rz = np.array([[ch, -sh, 0.0], [sh, ch, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    ry = np.array([[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]])
    return rz @ rx @ ry


def decode_outsim(data: bytes) -> TelemetrySample:
    """An OutSim packet (Live for Speed, 64 or 68 bytes; see the module doc) -> its sample in the
    vehicle frame; TelemetryError when malformed."""
    raw = _as_bytes(data, "OutSim telemetry")
    if len(raw) not in OUTSIM_SIZES:
        raise TelemetryError(f"OutSim telemetry: {len(raw)} bytes, expected "
                             f"{OUTSIM_SIZES[0]} or {OUTSIM_SIZES[1]}",
                             "truncated" if len(raw) < OUTSIM_SIZES[0] else "malformed")
    fields = _OUTSIM.unpack_from(raw, 0)
    time_ms, ang_vel, (heading, pitch, roll), accel = (fields[0], fields[1:4], fields[4:7],
                                                         fields[7:10])
    for name, values in (("AngVel", ang_vel), ("Heading, Pitch, Roll", (heading, pitch, roll)),
                         ("Accel", accel)):
        bad = [v for v in values if not math.isfinite(v)]
        if bad:
            raise TelemetryError(f"OutSim telemetry: {name}: non-finite value {bad[0]!r}",
                                 "non_finite")
    to_car = _car_to_world(heading, pitch, roll).T
    gravity = np.array(DEFAULT_GRAVITY, dtype=float)
    f_car = to_car @ (np.array(accel, dtype=float) - gravity)
    w_car = to_car @ np.array(ang_vel, dtype=float)

    def ours(v: np.ndarray) -> tuple[float, float, float]:
        # car (right, forward, up) -> vehicle (forward, left, up)
        return float(v[1]), float(-v[0]), float(v[2])

    return TelemetrySample(time_ms / 1000.0, ours(f_car), ours(w_car),
                           (float(roll), float(-pitch), float(heading)))


def encode_outsim(sample: TelemetrySample) -> bytes:
    """The OutSim packet (64 bytes, no ID) of a sample: decode_outsim's mapping inverted, the
    attitude (0 when the sample has none) as Heading, Pitch, Roll, the values as float32 and
    the time in whole milliseconds (so a round trip keeps about 7 digits and 1 ms)."""
    roll, pitch, yaw = sample.attitude if sample.attitude is not None else (0.0, 0.0, 0.0)
    heading, lfs_pitch = yaw, -pitch
    to_world = _car_to_world(heading, lfs_pitch, roll)

    def car(v: tuple[float, float, float]) -> np.ndarray:
        # vehicle (forward, left, up) -> car (right, forward, up)
        return np.array([-v[1], v[0], v[2]], dtype=float)

    accel = to_world @ car(sample.specific_force) + np.array(DEFAULT_GRAVITY, dtype=float)
    ang_vel = to_world @ car(sample.angular_velocity)
    time_ms = round(sample.t * 1000.0)
    if not 0 <= time_ms < 1 << 32:
        raise TelemetryError(f"OutSim telemetry: time {sample.t!r} s is not 0 .. 2^32 ms")
    return _OUTSIM.pack(time_ms, *ang_vel, heading, lfs_pitch, roll, *accel, 0.0, 0.0, 0.0,
                        0, 0, 0)
