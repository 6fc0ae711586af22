"""Physical bounds of everything that enters the emulated device, and the STATUSTEXT rate limit.

One table (`Bounds`, built by `bounds(model, config, design)`) derived from the scene and its
drives. The motor's ratings are those of the scene's [controller.motor] table; Kf = Kt zeta / r
(N/A) and Ke' = Ke zeta / r (V s/m) are the drive's force and back-EMF constants at the rack.

=================  ==========================================  ===========================
what               bound                                       micro-manipulator scene
=================  ==========================================  ===========================
setpoint length    [leg_min + room, leg_max - room] (below)    [0.0747, 0.1853] m
setpoint rate      |ldot| <= 10 V_max / Ke' (no-load speed)    3 m/s   (V_max/Ke' = 0.3 m/s)
feed-fwd force     |F| <= 50 Kf I_max (the drive's peak)       8 kN    (Kf I_max = 160 N)
force rate         |dF/dt| <= 10 Kf V_max / L (di/dt limit)    3.84e7 N/s
CTRL_KP/KI/KD      [0, 10 x the designed gain]                 see PARAM_VALUE of the design
DRV_V_LIMIT        [0.01, 1] x the motor's voltage_limit       [0.24, 24] V
DRV_I_LIMIT        [0.01, 1] x the motor's current_limit       [0.02, 2] A
WDG_TIMEOUT        [0.01, 10] s                                (also the constructor's)
SP_COND_MAX        (1, 1e4]
SR_* (streams)     [0, min(controller rate, 1000)] Hz          [0, 1000] Hz
=================  ==========================================  ===========================

The room kept free at each end of the stroke is the servo's own overshoot: a leg that arrives
at a setpoint at the drive's no-load speed v0 = V_max / Ke' runs on until the peak force Kf I_max,
less the static leg force F_hold the drive holds at home (gravity may push the same way), stops its
moving mass m (the axis model's load plus m_d): room = m v0^2 / (2 (Kf I_max - F_hold)), 4.7 mm of
the micro-manipulator's 120 mm stroke (its worst full-stroke step overshoots 2.7 mm). The bound,
not the servo, keeps the room: the servo's tick is the co-simulation master's
(controller.axis.servo_step), so a host following the bounds gets the loop it designed, and the
room is a read-only fact a host reads (SP_LEN_MIN, SP_LEN_MAX), not a hidden change of dynamics
near the stops.

The setpoint bounds are also reported as read-only parameters (SP_RATE_MAX, SP_FORCE_MAX,
SP_FRATE_MAX, SP_LEN_MIN, SP_LEN_MAX) so a host can read them with PARAM_REQUEST_LIST.
Out-of-range values are refused: a STATUSTEXT names the value and the bound.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# Headroom over the drive's physical limits. Planned moves may ask more than a drive delivers
# (it then saturates): the project's own references for the paper's 0.1 s moves ask the
# micro-manipulator's legs for 6.5x the no-load speed and 21x the peak force (Kane feed-forward),
# and the host must be able to send them. These bounds refuse absurd values, not ambitious ones.
RATE_MARGIN = 10.0
FORCE_MARGIN = 50.0
FORCE_RATE_MARGIN = 10.0
GAIN_FACTOR = 10.0      # gains up to this many times the design's
LIMIT_FLOOR = 0.01      # drive limits down to this fraction of the motor's rating
WATCHDOG_RANGE = (0.01, 10.0)   # s
COND_MAX_LIMIT = 1e4
STREAM_MAX = 1000.0     # Hz

# STATUSTEXT rate limit (token bucket in device time): at most STATUS_RATE per second on
# average, bursts of STATUS_BURST; the last STATUS_RESERVE tokens are kept for CRITICAL and above.
STATUS_RATE = 20.0
STATUS_BURST = 30.0
STATUS_RESERVE = 10.0

# Input on a UDP server end from any address but the peer's (hil.peer, real time only): a token
# bucket of bytes per source address on the serve loop's clock. Decoding costs about 27 us a
# frame (a 21-byte HEARTBEAT) and a tick 110 us at 1 kHz on the reference machine, so a flood of
# small valid frames decoded in full is what put device time behind wall time. A stranger may
# send STRANGER_RATE in bursts of STRANGER_BURST (enough for a new host's first frames, or a
# second station's occasional request); the peer is not limited (a host streaming setpoints
# must never lose one, nor the backlog of a stall). SOURCES addresses get a bucket of their own;
# beyond, new sources share one (bounded memory), and a source idle for FLOOD_MEMORY s is
# forgotten (its bucket was full again). A source that went over its budget within FLOOD_MEMORY
# s is flooding: it never becomes the peer (hil.peer).
STRANGER_RATE = 1024.0     # bytes/s
STRANGER_BURST = 1024.0    # bytes
SOURCES = 16
FLOOD_MEMORY = STRANGER_BURST / STRANGER_RATE   # s


@dataclass(frozen=True)
class Bounds:
    """The device's input bounds (see the module doc)."""

    leg_min: float
    leg_max: float
    rate_max: float         # m/s
    force_max: float        # N
    force_rate_max: float   # N/s
    gain_max: dict[str, float]      # kp, ki, kd
    voltage_range: tuple[float, float]
    current_range: tuple[float, float]
    watchdog_range: tuple[float, float] = WATCHDOG_RANGE
    cond_max_limit: float = COND_MAX_LIMIT
    stream_max: float = STREAM_MAX

    def setpoint(self, msg: Any, flags: int, rate_flag: int, force_flag: int,
                 force_rate_flag: int) -> str | None:
        """Why a (finite) setpoint is out of bounds (legs numbered 1..6), or None. Lengths:
        checked by the caller."""
        checks = []
        if flags & rate_flag:
            checks.append(("rate", msg.rate, self.rate_max, "m/s"))
        if flags & force_flag:
            checks.append(("force", msg.force, self.force_max, "N"))
        if flags & force_rate_flag:
            checks.append(("force rate", msg.force_rate, self.force_rate_max, "N/s"))
        for what, values, bound, unit in checks:
            a = np.abs(np.asarray(values, dtype=float))
            i = int(np.argmax(a))
            if not a[i] <= bound:
                return f"leg {i + 1} {what} {values[i]:.3g} {unit}, bound {bound:.3g}"
        return None


def overshoot_room(axis: Any, holding_force: float) -> float:
    """m, the stroke kept free at each end (see the module doc): the distance in which the drive
    `axis` (controller.drive.AxisModel) stops its moving mass from its no-load speed with its
    peak force less `holding_force` (N); inf when the drive cannot out-push the load it holds."""
    brake = axis.peak_force - abs(holding_force)
    if not brake > 0:
        return float("inf")
    return axis.moving_mass * axis.no_load_speed ** 2 / (2.0 * brake)


def bounds(leg_min: float, leg_max: float, axis: Any, gains: Any, room: float = 0.0) -> Bounds:
    """The bounds of a device whose stroke is [leg_min, leg_max], whose drive is `axis`
    (controller.drive.AxisModel, with the scene's motor ratings) and whose designed gains are
    `gains` (controller.design.PidGains); setpoint lengths keep `room` (overshoot_room) free at
    each end of the stroke."""
    m = axis.motor
    kf, ke = axis.force_constant, axis.emf_constant
    return Bounds(
        leg_min=leg_min + room, leg_max=leg_max - room,
        rate_max=RATE_MARGIN * m.voltage_limit / ke,
        force_max=FORCE_MARGIN * kf * m.current_limit,
        force_rate_max=FORCE_RATE_MARGIN * kf * m.voltage_limit / m.inductance,
        gain_max={k: GAIN_FACTOR * getattr(gains, k) for k in ("kp", "ki", "kd")},
        voltage_range=(LIMIT_FLOOR * m.voltage_limit, m.voltage_limit),
        current_range=(LIMIT_FLOOR * m.current_limit, m.current_limit))


def in_range(lo: float, hi: float, unit: str = "", lo_open: bool = False):
    """A parameter check: None when lo <= x <= hi (lo < x with lo_open), else why not."""
    def check(x: float) -> str | None:
        ok = (lo < x if lo_open else lo <= x) and x <= hi
        if ok:
            return None
        left = "(" if lo_open else "["
        return f"must be in {left}{lo:.4g}, {hi:.4g}]{(' ' + unit) if unit else ''}"
    return check


def read_only(x: float) -> str | None:
    return "read-only (a bound of the device)"


class StatusLimiter:
    """Token bucket over STATUSTEXT messages in device time (ticks): floods are cut, counted.

    Chunks of one long text (same nonzero id) pass or go together; a message that passed once
    is marked and passes again untouched (replies repeated in lockstep, nested filtering)."""

    def __init__(self, dt: float, rate: float = STATUS_RATE, burst: float = STATUS_BURST,
                 reserve: float = STATUS_RESERVE) -> None:
        self.dt, self.rate, self.burst, self.reserve = dt, rate, burst, reserve
        self.tokens = burst
        self._k = 0
        self._chunk_ok: dict[int, bool] = {}
        self.suppressed = 0

    def filter(self, msgs: list[Any], k: int, critical: int) -> list[Any]:
        if k != self._k:
            self.tokens = min(self.burst, self.tokens + (k - self._k) * self.dt * self.rate)
            self._k = k
        out = []
        for m in msgs:
            if getattr(m, "_limited", False) or m.get_type() != "STATUSTEXT":
                out.append(m)
                continue
            cid = getattr(m, "id", 0)
            if cid and getattr(m, "chunk_seq", 0) > 0 and cid in self._chunk_ok:
                ok = self._chunk_ok[cid]
            else:
                need = 1.0 if m.severity <= critical else 1.0 + self.reserve
                ok = self.tokens >= need
                if ok:
                    self.tokens -= 1.0
                if cid:
                    if len(self._chunk_ok) > 64:
                        self._chunk_ok.clear()
                    self._chunk_ok[cid] = ok
            if ok:
                m._limited = True
                out.append(m)
            else:
                self.suppressed += 1
        return out


class SourceLimiter:
    """Token buckets of bytes per source address (see STRANGER_RATE...): a datagram over its
    source's budget is dropped before it is decoded, and counted (`dropped`, `bytes_dropped`).
    Memory: at most SOURCES + 1 buckets, whatever the number of addresses."""

    def __init__(self, sources: int = SOURCES) -> None:
        self.sources = sources
        # source -> [tokens, time of the last update, time of the last drop]
        self._buckets: dict[Any, list[float]] = {}
        self._shared: list[float] | None = None      # of the sources beyond `sources`
        self.dropped = 0
        self.bytes_dropped = 0

    def admit(self, source: Any, nbytes: int, now: float) -> bool:
        """True when `nbytes` from `source` fit its budget at clock time `now` (s); else False,
        counted."""
        rate, burst = STRANGER_RATE, STRANGER_BURST
        b = self._buckets.get(source)
        if b is None:
            if len(self._buckets) >= self.sources:
                self._forget_idle(now)
            if len(self._buckets) < self.sources:
                b = self._buckets[source] = [burst, now, -math.inf]
            else:
                if self._shared is None:
                    self._shared = [burst, now, -math.inf]
                b = self._shared
        tokens = min(burst, b[0] + max(0.0, now - b[1]) * rate)
        b[1] = now
        if nbytes <= tokens:
            b[0] = tokens - nbytes
            return True
        b[0], b[2] = tokens, now
        self.dropped += 1
        self.bytes_dropped += nbytes
        return False

    def flooding(self, source: Any, now: float) -> bool:
        """Whether `source` (or the shared bucket it falls in) went over its budget within
        FLOOD_MEMORY s of `now`."""
        b = self._buckets.get(source)
        if b is None and len(self._buckets) >= self.sources:
            b = self._shared
        return b is not None and now - b[2] < FLOOD_MEMORY

    def _forget_idle(self, now: float) -> None:
        """Forget the sources idle for FLOOD_MEMORY s: their buckets are full again and their
        last drop is older than FLOOD_MEMORY."""
        for key in [k for k, b in self._buckets.items() if now - b[1] >= FLOOD_MEMORY]:
            del self._buckets[key]

    def __len__(self) -> int:
        """The buckets held (at most `sources` + 1)."""
        return len(self._buckets) + (self._shared is not None)
