"""The emulated micro-manipulator: plant, six drive servo loops and the MAVLink device logic.

`Device` is transport-agnostic: it takes decoded messages of our dialect (`receive`) or raw bytes
(`feed`, through a robust `hil.framing.Receiver` that also checks MAVLink 2 signatures), advances
one controller period per `tick()`, and returns the messages it wants to send (pack them with
`Device.pack`). `hil.serve.serve` runs it over a transport, in real time or in lockstep.

Physics and servo loops
-----------------------
The plant is `stewart_fmu.plant.Plant` (behind `controller.plants.InProcessPlant`), the drive
controllers are `controller.axis.AxisControllers` and `MotorCurrents` with the gains that
`controller.design.tune_pid` gives for the scene's [controller] table (through
`controller.design.design_axis`, which also refuses an unstable sampled loop). The device starts at
the scene's home pose with the drives holding it: `controller.feedforward.start_at_equilibrium` (the
master's bumpless start, a private function of that module, called here rather than copied) sets
the motor currents and the integrals for a static hold. One tick: measure leg lengths and rates,
PID voltages (+ optional feed-forward), advance the motor currents, step the plant by the
controller period with the mean motor torques.

Setpoints (LEG_SETPOINT)
------------------------
A setpoint is refused (STATUSTEXT, counted, never applied) when a length, rate or force is not
finite, a length is outside [leg_min, leg_max], forward kinematics finds no pose for the lengths
(Newton from the last accepted pose), or cond(J) at that pose exceeds the parameter SP_COND_MAX.
A valid setpoint feeds the watchdog; it is applied only while armed (while disarmed it is
ignored, counted, with one STATUSTEXT per disarmed period). Rates are used with
STEWART_SETPOINT_FLAG_RATE_VALID, forces with STEWART_SETPOINT_FLAG_FORCE_VALID as the voltage
R i + L di/dt + Ke' ldot_ref with i = F / Kf (di/dt from the force rate with
STEWART_SETPOINT_FLAG_FORCE_RATE_VALID, else 0): the master's feed-forward. When a feed-forward
stream begins or ends the integral takes over its static part (bumpless transfer). HOLD holds
the current leg lengths.

Bounds (hil.limits)
-------------------
Setpoint rates, forces and force rates are also refused beyond the drive-derived bounds of
`hil.limits` (the STATUSTEXT names the leg, the value and the bound); every parameter has a
range (PARAM_SET out of range: PARAM_VALUE with the unchanged value and a STATUSTEXT); the bounds
are read-only parameters SP_LEN_MIN/MAX, SP_RATE_MAX, SP_FORCE_MAX, SP_FRATE_MAX. STATUSTEXT
floods are cut by a token bucket. With a signing key, frames pass `hil.signing.Verifier` (the
signature before any timestamp is stored) before they are decoded.

Watchdog and safe states
------------------------
Disarmed: the drives hold the leg lengths measured at disarm (and at start). Armed: the watchdog
starts with the first valid setpoint; when `watchdog` seconds (device time, i.e. ticks; served in
real time, the monotonic wall clock `clock` that also schedules the ticks) pass
without one, the device holds the leg lengths measured at that tick and sends one STATUSTEXT;
the next valid setpoint (or a re-arm) resumes. If the plant refuses a step (a leg at its end
stop), the device stops the platform where it is (restarted at rest, drives holding), disarms
and says so. Any numerical failure of a tick (non-finite voltage or torque, IntegrationError...)
restarts the plant at rest at the last good pose, drives holding with the designed gains and
rated limits, disarms and sends one CRITICAL STATUSTEXT: the device never exits on numbers.

Commands (COMMAND_LONG or COMMAND_INT -> COMMAND_ACK)
------------------------------------------------------
MAV_CMD_COMPONENT_ARM_DISARM (param1 1 arm, 0 disarm); MAV_CMD_NAV_RETURN_TO_LAUNCH ("home":
while armed, move to the scene's home leg lengths along a quintic in leg space at a quarter
stroke per second peak, then hold; a host setpoint takes over). MAV_CMD_DO_SET_HOME is refused
as unsupported: the home pose is the scene's. MAV_CMD_GET_HOME_POSITION (or
MAV_CMD_REQUEST_MESSAGE of HOME_POSITION): HOME_POSITION after the ack (the scene's home in the
convention of LOCAL_POSITION_NED, see hil.protocol); HOME_POSITION also goes out once on arming.
Other commands: MAV_RESULT_UNSUPPORTED. PARAM_SET honours param_type: REAL32, and the integer
types up to 32 bits in MAVLink's bytewise encoding; other types are refused (the unchanged
PARAM_VALUE and a STATUSTEXT). Every frame sent carries the next sequence number (mod 256).

Lockstep
--------
With `lockstep=True` time advances only on LOCKSTEP(step=k) (when armed, only once the setpoint
with sequence k has been accepted: a lost setpoint is never replaced silently by the previous
one): the device applies what it received
before (the setpoint for step k), ticks once and answers with the telemetry due, one LEG_STATE
with `step = k` and LOCKSTEP(step=k) echoed, all stamped with the device time after the step.
Steps are numbered from 0; a repeated step is answered again without ticking (the host may
resend after a loss), any other step number is refused with a STATUSTEXT.

Observers
---------
`Device.observe(latest, hz)` makes every tick that ends a 1/hz interval publish a
`hil.observe.Snapshot` (time, pose, the pose of the followed setpoint, leg lengths, rack forces,
cond(J)) into a `hil.observe.Latest` that other threads read (the live view of `stewart-sim
device --view`); without an observer a tick pays one attribute test.

Telemetry and frames
--------------------
HEARTBEAT at 1 Hz (MAV_TYPE_GENERIC, MAV_AUTOPILOT_GENERIC; base mode SAFETY_ARMED while armed,
custom mode 1 in lockstep; system status STANDBY, ACTIVE, or CRITICAL while the watchdog has
tripped); SYS_STATUS, LEG_STATE, DRIVE_STATUS, ATTITUDE_QUATERNION (with ATTITUDE beside it)
and LOCAL_POSITION_NED at the rates of `telemetry` (Hz, 0 = off; also parameters SR_*), all starting at the first tick.
Our frame N is z up; MAVLink's is NED. We map N to NED by a half turn about x: north = x,
east = -y, down = -z, and the platform frame to FRD the same way. So LOCAL_POSITION_NED is
(x, -y, -z) and its rates likewise, and the attitude quaternion of R = Rz(thz) Ry(thy) Rx(thx)
(w, x, y, z) becomes (w, x, -y, -z), i.e. roll = thx, pitch = -thy, yaw = -thz; body rates are
R^T omega with y and z negated.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from controller.axis import AxisControllers, MotorCurrents
from controller.config import ControllerConfig, controller_config
from controller.design import PidGains, design_axis
from controller.feedforward import start_at_equilibrium
from controller.plants import InProcessPlant, PlantStepError
from controller.trajectory import QUINTIC_PEAK_RATE, Trajectory, leg_references, minimum_jerk
from hil import mavlink_stewart as ms
from hil.framing import Receiver
from hil.observe import OBSERVE_HZ, Latest, Snapshot
from hil import limits, protocol
from hil.signing import SignedDecoder, Verifier, wall_timestamp
from stewart_fmu.errors import IntegrationError, StewartError
from stewart_fmu.kinematics import condition_number, forward_kinematics, inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.rotations import euler_motion

#: Default telemetry rates (Hz); HEARTBEAT is always 1 Hz.
TELEMETRY = {"SYS_STATUS": 1.0, "LEG_STATE": 100.0, "DRIVE_STATUS": 10.0,
             "ATTITUDE_QUATERNION": 50.0, "LOCAL_POSITION_NED": 50.0}
#: Parameter names of the stream rates.
STREAM_PARAMS = {"SR_SYS_STATUS": "SYS_STATUS", "SR_LEG_STATE": "LEG_STATE",
                 "SR_DRIVE_STATUS": "DRIVE_STATUS", "SR_ATTITUDE": "ATTITUDE_QUATERNION",
                 "SR_POSITION": "LOCAL_POSITION_NED"}
HEARTBEAT_HZ = 1.0
COND_MAX = 100.0           # default SP_COND_MAX: cond(J) (scaled) above this counts as singular
HOMING_SPEED = 0.25        # peak homing leg rate, stroke fractions per second
HOMING_MIN_TIME = 0.2      # s
STATUS_REPEAT = 0.1        # s: the same refusal text is not repeated within this device time
STATUSTEXT_LEN = 50
SIGNING_EPOCH = 1420070400  # MAVLink 2 signing timestamps count 10 us units since 2015-01-01
CUSTOM_MODE_REALTIME, CUSTOM_MODE_LOCKSTEP = 0, 1
_CONTROL_SENSORS = (ms.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | ms.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
_U16, _U32 = 0xFFFF, 0xFFFFFFFF


class DeviceError(StewartError):
    """The device cannot be built as asked (bad watchdog, telemetry rate, signing key)."""


@dataclass
class DeviceCounters:
    """What the device counted since start (link-level counts live in `Device.rx.stats`)."""

    ticks: int = 0
    setpoints_accepted: int = 0
    setpoints_refused: int = 0
    setpoints_ignored: int = 0      # valid, but the device was disarmed
    statustexts_suppressed: int = 0
    commands: int = 0
    commands_refused: int = 0
    params_set: int = 0
    params_refused: int = 0
    lockstep_refused: int = 0
    lockstep_repeated: int = 0
    signing_rejected: int = 0       # unsigned or badly signed frames with a key set
    watchdog_trips: int = 0
    faults: int = 0                 # plant steps refused (end stop)
    overruns: int = 0               # real-time ticks late by more than one period (serve)
    numeric_faults: int = 0         # numerical failures in the loop (safe hold, disarmed)
    handler_errors: int = 0         # messages whose handling raised (dropped, device serving)
    statustexts_rate_limited: int = 0  # cut by the STATUSTEXT token bucket (hil.limits)
    frames_valid: int = 0           # decoded (and authenticated) frames for this system
    peer_changes: int = 0           # UDP peer switches (hil.peer)


def _quat_zyx(thx: float, thy: float, thz: float) -> tuple[float, float, float, float]:
    """(w, x, y, z) of R = Rz(thz) Ry(thy) Rx(thx)."""
    cx, sx = math.cos(thx / 2), math.sin(thx / 2)
    cy, sy = math.cos(thy / 2), math.sin(thy / 2)
    cz, sz = math.cos(thz / 2), math.sin(thz / 2)
    return (cx * cy * cz + sx * sy * sz, sx * cy * cz - cx * sy * sz,
            cx * sy * cz + sx * cy * sz, cx * cy * sz - sx * sy * cz)


def ned_attitude(q: np.ndarray) -> tuple[float, float, float, float]:
    """Attitude quaternion (w, x, y, z) in NED/FRD of pose q (see the module doc)."""
    w, x, y, z = _quat_zyx(float(q[3]), float(q[4]), float(q[5]))
    return w, x, -y, -z


def rotation(q: np.ndarray) -> np.ndarray:
    """R = Rz Ry Rx of pose q, from the compiled convention."""
    Q = np.asarray(q, dtype=float).reshape(1, 6)
    R, om, al = np.empty((1, 3, 3)), np.empty((1, 3)), np.empty((1, 3))
    euler_motion(Q, np.zeros((1, 6)), np.zeros((1, 6)), R, om, al)
    return R[0]


@dataclass
class _Param:
    get: Callable[[], float]
    set: Callable[[float], None]
    check: Callable[[float], str | None]   # None if acceptable, else why not


class Device:
    """The emulated micro-manipulator (see the module doc)."""

    def __init__(self, model: Model, config: ControllerConfig | None = None, watchdog: float = 0.2,
                 telemetry: dict[str, float] | None = None, signing_key: bytes | None = None, *,
                 lockstep: bool = False, system_id: int = 1, component_id: int = 1) -> None:
        self.model = model
        self.config = config if config is not None else controller_config(model)
        self.rate = self.config.rate
        self.dt = self.config.dt
        lo, hi = limits.WATCHDOG_RANGE
        if not (math.isfinite(watchdog) and lo <= watchdog <= hi):
            raise DeviceError(f"watchdog must be a finite time in [{lo:g}, {hi:g}] s, got {watchdog!r}")
        self.watchdog = float(watchdog)
        self.lockstep = bool(lockstep)
        self.rates = dict(TELEMETRY)
        for name, hz in (telemetry or {}).items():
            if name not in TELEMETRY:
                raise DeviceError(f"telemetry: unknown stream {name!r} (known: {sorted(TELEMETRY)})")
            why = self._check_rate(hz)
            if why:
                raise DeviceError(f"telemetry {name}: {why}")
            self.rates[name] = float(hz)
        self.counters = DeviceCounters()
        self.mav = ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.verifier: Verifier | None = None
        if signing_key is not None:
            self._setup_signing(signing_key)
        self.rx = Receiver(ms, self.mav if self.verifier is None else SignedDecoder(
            ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id), self.verifier,
            self._signing_refused))
        self.limiter = limits.StatusLimiter(self.config.dt)

        axis, gains, self.analysis = design_axis(model, self.config)
        self.ctrl = AxisControllers(gains, axis, self.dt)
        self.motors = MotorCurrents(axis, self.dt)
        self.port = InProcessPlant(model)
        self.plant = self.port.plant
        self.leg_min = model.leg_min if model.leg_min is not None else 0.0
        self.leg_max = model.leg_max if model.leg_max is not None else math.inf
        self.home_lengths = inverse_kinematics(model, model.home, with_cond=False).lengths.copy()
        self.cond_max = COND_MAX
        self.design_gains, self.design_motor = self.ctrl.gains, self.ctrl.axis.motor
        self.bounds = limits.bounds(self.leg_min, self.leg_max, self.ctrl.axis, self.ctrl.gains)
        self._ff_static: np.ndarray | None = None   # R i + Ke ldot_ref of the feed-forward in use
        # the pose of the setpoint being followed (observers' ghost); None while holding or homing
        self.reference_pose: np.ndarray | None = None
        self._start_holding(np.asarray(model.home, dtype=float), 0.0)

        self.k = 0                       # ticks done; device time = k / rate
        self.armed = False
        self.watchdog_state = ms.STEWART_WATCHDOG_IDLE
        self._last_setpoint_k = 0
        self._last_pose = np.asarray(model.home, dtype=float).copy()
        self._homing: tuple[np.ndarray, np.ndarray, int, int] | None = None  # l0, l1, k0, n
        self._ignored_said = False
        self._said: dict[str, int] = {}  # refusal text -> tick it was last sent
        self._statustext_id = 0
        self._next_step = 0
        self._setpoint_sequence: int | None = None   # sequence of the last accepted setpoint
        self._last_reply: list[Any] | None = None
        self._v = np.zeros(6)
        self._sat = np.zeros(6, dtype=bool)
        self.load = 0                    # per mille of the tick period (set by serve)
        self.last_fault: str | None = None   # the last numerical fault, in full
        # real time (set by serve): the monotonic wall clock the watchdog runs on; None: ticks
        self.clock: Callable[[], float] | None = None
        self._last_setpoint_wall = 0.0
        # observers (hil.observe): a snapshot every _observe_every ticks into _observer
        self._observer: Latest | None = None
        self._observe_every = 1
        self.params = self._parameters()

    # --- set-up --------------------------------------------------------------------------

    def _setup_signing(self, key: bytes) -> None:
        if not isinstance(key, (bytes, bytearray)) or len(key) != 32:
            raise DeviceError("signing_key must be 32 bytes")
        s = self.mav.signing
        s.secret_key = bytes(key)
        s.link_id = 0
        s.sign_outgoing = True
        s.timestamp = int((time.time() - SIGNING_EPOCH) * 1e5)
        s.allow_unsigned_callback = self._reject_unsigned
        self.verifier = Verifier(s.secret_key, self._signing_clock)

    def _signing_clock(self) -> int:
        """The device's signing clock (10 us units since 2015): the wall clock (tests may
        replace `signing_clock`)."""
        return self.signing_clock()

    signing_clock = staticmethod(wall_timestamp)

    def _signing_refused(self, why: str) -> None:
        self.counters.signing_rejected += 1

    def _reject_unsigned(self, mav: Any, msg_id: int) -> bool:
        """pymavlink asks this for every unsigned or badly signed frame: reject and count."""
        self.counters.signing_rejected += 1
        return False

    def _start_holding(self, q: np.ndarray, t0: float) -> None:
        """(Re)start the plant at rest at pose q, drives holding it (the master's bumpless start)."""
        traj = Trajectory(np.array([t0, t0 + self.dt]), np.tile(q, (2, 1)), np.zeros((2, 6)),
                          np.zeros((2, 6)))
        self.plant.reset()
        start_at_equilibrium(self.model, traj, leg_references(self.model, traj),
                              self.ctrl.gains, self.ctrl, self.motors, np.zeros(6), self.port)
        self._ff_static = None
        self._hold()

    def _hold(self) -> None:
        """References: the leg lengths measured now, at rest, no feed-forward."""
        self.l_ref = self.plant.outputs.lengths.copy()
        self.reference_pose = None
        self.ldot_ref = np.zeros(6)
        self._set_feedforward(None, None)
        self._homing = None

    def _set_feedforward(self, v_ff: np.ndarray | None, static: np.ndarray | None) -> None:
        """Bumpless transfer: when a feed-forward stream begins (or ends: hold, watchdog, homing,
        a setpoint without force) the integral hands its static part R i + Ke ldot_ref over (or
        takes it back), as controller.feedforward.start_at_equilibrium does at the start of a run."""
        ki = self.ctrl.gains.ki
        if ki > 0 and (static is None) != (self._ff_static is None):
            old = 0.0 if self._ff_static is None else self._ff_static
            self.ctrl.integral += (old - (0.0 if static is None else static)) / ki
        self.v_ff = np.zeros(6) if v_ff is None else v_ff
        self._ff_static = static

    @staticmethod
    def _check_rate(hz: float) -> str | None:
        if isinstance(hz, bool) or not isinstance(hz, (int, float)) or not math.isfinite(hz) or hz < 0:
            return f"rate must be a finite number >= 0 Hz, got {hz!r}"
        return None

    def _parameters(self) -> dict[str, _Param]:
        b = self.bounds

        def gain(name: str) -> _Param:
            return _Param(lambda: getattr(self.ctrl.gains, name), lambda x: self._set_gain(name, x),
                          limits.in_range(0.0, b.gain_max[name]))

        def motor(field: str, rng: tuple[float, float], unit: str) -> _Param:
            return _Param(lambda: getattr(self.ctrl.axis.motor, field),
                          lambda x: self._set_motor(field, x), limits.in_range(*rng, unit))

        def bound(value: float) -> _Param:
            return _Param(lambda: value, lambda x: None, limits.read_only)

        def stream(name: str) -> _Param:
            return _Param(lambda: self.rates[name], lambda x: self.rates.__setitem__(name, x),
                          lambda x: self._check_rate(x) or limits.in_range(
                              0.0, min(self.rate, b.stream_max), "Hz")(x))

        params = {"CTRL_KP": gain("kp"), "CTRL_KI": gain("ki"), "CTRL_KD": gain("kd"),
                  "DRV_V_LIMIT": motor("voltage_limit", b.voltage_range, "V"),
                  "DRV_I_LIMIT": motor("current_limit", b.current_range, "A"),
                  "WDG_TIMEOUT": _Param(lambda: self.watchdog,
                                        lambda x: setattr(self, "watchdog", x),
                                        limits.in_range(*b.watchdog_range, "s")),
                  "SP_COND_MAX": _Param(lambda: self.cond_max, lambda x: setattr(self, "cond_max", x),
                                        limits.in_range(1.0, b.cond_max_limit, lo_open=True))}
        params.update({p: stream(s) for p, s in STREAM_PARAMS.items()})
        params.update({"SP_LEN_MIN": bound(b.leg_min), "SP_LEN_MAX": bound(b.leg_max),
                       "SP_RATE_MAX": bound(b.rate_max), "SP_FORCE_MAX": bound(b.force_max),
                       "SP_FRATE_MAX": bound(b.force_rate_max)})
        return params

    def _set_gain(self, name: str, x: float) -> None:
        old = self.ctrl.gains
        new = replace(old, **{name: x})
        if name == "ki" and old.ki > 0 and x > 0:  # keep ki * integral: bumpless
            self.ctrl.integral *= old.ki / x
        self.ctrl.gains = new

    def _set_motor(self, field: str, x: float) -> None:
        axis = self.ctrl.axis
        axis = replace(axis, motor=replace(axis.motor, **{field: x}))
        self.ctrl.axis = self.motors.axis = axis

    @property
    def gains(self) -> PidGains:
        return self.ctrl.gains

    @property
    def time(self) -> float:
        """Device time (s): ticks / rate."""
        return self.k / self.rate

    def _usec(self) -> int:
        return int(round(self.k * 1e6 / self.rate))

    def pack(self, msg: Any) -> bytes:
        """The MAVLink 2 frame of `msg` from this device (signed when a key is set)."""
        frame = bytes(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256   # MAVLink's per-sender sequence, every frame
        return frame

    # --- observers -----------------------------------------------------------------------

    def observe(self, latest: Latest | None, hz: float = OBSERVE_HZ) -> None:
        """Publish a snapshot into `latest` now and then every rate/hz ticks (at most every
        tick); None stops publishing. The cost falls on one tick in rate/hz (hil.observe)."""
        why = self._check_rate(hz)
        if why is None and hz <= 0:
            why = f"rate must be > 0 Hz, got {hz!r}"
        if why:
            raise DeviceError(f"observe: {why}")
        self._observe_every = max(1, round(self.rate / hz))
        self._observer = latest
        if latest is not None:
            latest.publish(self.snapshot())

    def snapshot(self) -> Snapshot:
        """The state now: time, pose, the pose of the setpoint followed, leg lengths, rack
        forces, cond(J) at the pose (stewart_fmu.kinematics.condition_number), armed."""
        o = self.plant.outputs
        ref = self.reference_pose
        return Snapshot(self.k, self.k / self.rate, tuple(o.q.tolist()),
                        None if ref is None else tuple(ref.tolist()), tuple(o.lengths.tolist()),
                        tuple(self.plant.rack_force.tolist()), condition_number(self.model, o.q),
                        self.armed)

    # --- input ---------------------------------------------------------------------------

    def feed(self, data: bytes) -> list[Any]:
        """Bytes from the link: decode every intact frame and `receive` it; the replies."""
        out: list[Any] = []
        for msg in self.rx.feed(data):
            self._count_valid(msg)
            out += self.receive(msg)
        return out

    def _count_valid(self, msg: Any) -> None:
        """Count a decoded (with a key: authenticated) frame that is for this system (no target
        field, or target 0 or ours): what hil.peer needs to follow or refuse a new peer."""
        target = getattr(msg, "target_system", None)
        if target is None or target in (0, self.mav.srcSystem):
            self.counters.frames_valid += 1

    def flush(self) -> list[Any]:
        """The line went idle: give up a partial frame (the Receiver's flush); the replies."""
        out: list[Any] = []
        for msg in self.rx.flush():
            self._count_valid(msg)
            out += self.receive(msg)
        return out

    def receive(self, msg: Any) -> list[Any]:
        """Handle one decoded message of our dialect; the messages to send back."""
        handler = self._handlers.get(msg.get_msgId())
        if handler is None:
            return []
        try:
            out = handler(self, msg)
        except Exception as exc:  # the device keeps serving whatever a message holds
            self.counters.handler_errors += 1
            out = self._say_once(ms.MAV_SEVERITY_ERROR,
                                 f"{msg.get_type()} dropped: {type(exc).__name__}", key="handler")
        return self._limit_statustext(out)

    def _limit_statustext(self, out: list[Any]) -> list[Any]:
        """The STATUSTEXT token bucket (hil.limits.StatusLimiter) over `out`."""
        n = self.limiter.suppressed
        out = self.limiter.filter(out, self.k, ms.MAV_SEVERITY_CRITICAL)
        self.counters.statustexts_rate_limited += self.limiter.suppressed - n
        return out

    def _for_me(self, msg: Any) -> bool:
        return (msg.target_system in (0, self.mav.srcSystem)
                and msg.target_component in (0, self.mav.srcComponent))

    def _on_setpoint(self, msg: Any) -> list[Any]:
        flags = msg.flags
        why, pose = None, None
        if not flags & ms.STEWART_SETPOINT_FLAG_HOLD:
            why, pose = self._validate(msg, flags)
        if why is not None:
            self.counters.setpoints_refused += 1
            return self._say_once(ms.MAV_SEVERITY_WARNING, f"refused: {why}", key="refused")
        if not self.armed:
            self.counters.setpoints_ignored += 1
            if self._ignored_said:
                return []
            self._ignored_said = True
            return self._statustext(ms.MAV_SEVERITY_WARNING, "setpoints ignored: disarmed (arm first)")
        self.counters.setpoints_accepted += 1
        out = []
        if self.watchdog_state == ms.STEWART_WATCHDOG_TRIPPED:
            out = self._statustext(ms.MAV_SEVERITY_NOTICE, "watchdog: setpoints resumed")
        self.watchdog_state = ms.STEWART_WATCHDOG_OK
        self._last_setpoint_k = self.k
        self._last_setpoint_wall = self.clock() if self.clock is not None else 0.0
        self._setpoint_sequence = msg.sequence
        if flags & ms.STEWART_SETPOINT_FLAG_HOLD:
            self._hold()
            return out
        self._homing = None
        self._last_pose = pose
        self.reference_pose = pose
        self.l_ref = np.array(msg.length, dtype=float)
        self.ldot_ref = (np.array(msg.rate, dtype=float) if flags & ms.STEWART_SETPOINT_FLAG_RATE_VALID
                         else np.zeros(6))
        if flags & ms.STEWART_SETPOINT_FLAG_FORCE_VALID:
            ax = self.ctrl.axis
            i = np.array(msg.force, dtype=float) / ax.force_constant
            di = (np.array(msg.force_rate, dtype=float) / ax.force_constant
                  if flags & ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID else 0.0)
            self._set_feedforward(ax.voltage(i, di, self.ldot_ref),
                                  ax.voltage(i, 0.0, self.ldot_ref))
        else:
            self._set_feedforward(None, None)
        return out

    def _validate(self, msg: Any, flags: int) -> tuple[str | None, np.ndarray | None]:
        """(why the setpoint is refused or None, its pose)."""
        lengths = np.array(msg.length, dtype=float)
        if not np.all(np.isfinite(lengths)):
            return "non-finite length", None
        if flags & ms.STEWART_SETPOINT_FLAG_RATE_VALID and not np.all(np.isfinite(msg.rate)):
            return "non-finite rate", None
        if flags & ms.STEWART_SETPOINT_FLAG_FORCE_VALID and not np.all(np.isfinite(msg.force)):
            return "non-finite force", None
        if (flags & ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID
                and not np.all(np.isfinite(msg.force_rate))):
            return "non-finite force rate", None
        why = self.bounds.setpoint(msg, flags, ms.STEWART_SETPOINT_FLAG_RATE_VALID,
                                   ms.STEWART_SETPOINT_FLAG_FORCE_VALID,
                                   ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID)
        if why is not None:
            return why, None
        bad = [i for i in range(6) if not self.leg_min <= lengths[i] <= self.leg_max]
        if bad:
            i = bad[0]
            return f"leg {i} at {lengths[i]:.4g} m, stroke [{self.leg_min:g}, {self.leg_max:g}]", None
        try:
            pose = forward_kinematics(self.model, lengths, guess=self._last_pose)
        except StewartError:
            return "no pose has these lengths", None
        cond = condition_number(self.model, pose)
        if not cond <= self.cond_max:
            return f"near-singular, cond {cond:.3g} > {self.cond_max:g}", None
        return None, pose

    def _on_command(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        self.counters.commands += 1
        cmd, out = msg.command, []
        if cmd == ms.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1.0:
                if not self.armed:
                    out = self._statustext(ms.MAV_SEVERITY_INFO, "armed") + [self.home_position()]
                self.armed = True
                self._hold()
                self.watchdog_state = ms.STEWART_WATCHDOG_IDLE
                result = ms.MAV_RESULT_ACCEPTED
            elif msg.param1 == 0.0:
                if self.armed:
                    out = self._statustext(ms.MAV_SEVERITY_INFO, "disarmed: holding")
                self._disarm()
                result = ms.MAV_RESULT_ACCEPTED
            else:
                result = ms.MAV_RESULT_DENIED
                out = self._say_once(ms.MAV_SEVERITY_WARNING,
                                     f"arm/disarm param1 {msg.param1:.3g} refused: must be 0 or 1",
                                     key="arm-denied")
        elif cmd == ms.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            if self.armed:
                self._start_homing()
                out = self._statustext(ms.MAV_SEVERITY_INFO, "homing")
                result = ms.MAV_RESULT_ACCEPTED
            else:
                result = ms.MAV_RESULT_TEMPORARILY_REJECTED
                out = self._statustext(ms.MAV_SEVERITY_WARNING, "home refused: disarmed")
        else:
            result, out = self._on_other_command(msg)
        if result != ms.MAV_RESULT_ACCEPTED:
            self.counters.commands_refused += 1
        ack = ms.MAVLink_command_ack_message(cmd, result, 0, 0, msg.get_srcSystem(),
                                             msg.get_srcComponent())
        return [ack] + out

    def _on_other_command(self, msg: Any) -> tuple[int, list[Any]]:
        """GET_HOME_POSITION (and REQUEST_MESSAGE of HOME_POSITION): HOME_POSITION after the
        ack; anything else unsupported."""
        if msg.command == ms.MAV_CMD_GET_HOME_POSITION or (
                msg.command == ms.MAV_CMD_REQUEST_MESSAGE
                and msg.param1 == ms.MAVLINK_MSG_ID_HOME_POSITION):
            return ms.MAV_RESULT_ACCEPTED, [self.home_position()]
        return ms.MAV_RESULT_UNSUPPORTED, []

    def _disarm(self) -> None:
        self.armed = False
        self._hold()
        self.watchdog_state = ms.STEWART_WATCHDOG_IDLE
        self._ignored_said = False

    def _start_homing(self) -> None:
        l0 = self.plant.outputs.lengths.copy()
        d = float(np.max(np.abs(self.home_lengths - l0)))
        stroke = (self.leg_max - self.leg_min) if math.isfinite(self.leg_max) else 1.0
        duration = max(HOMING_MIN_TIME, QUINTIC_PEAK_RATE * d / (HOMING_SPEED * stroke))
        self._homing = (l0, self.home_lengths.copy(), self.k, max(1, round(duration * self.rate)))
        self.reference_pose = None   # the reference moves in leg space, not along a pose
        self.watchdog_state = ms.STEWART_WATCHDOG_IDLE
        self._set_feedforward(None, None)

    def _homing_reference(self) -> None:
        l0, l1, k0, n = self._homing
        u = min(1.0, (self.k - k0) / n)
        s, sd, _ = minimum_jerk(u, n / self.rate)
        self.l_ref = l0 + (l1 - l0) * s
        self.ldot_ref = (l1 - l0) * sd
        if u >= 1.0:
            self._homing = None
            self.ldot_ref = np.zeros(6)

    def _param_value(self, name: str) -> Any:
        names = list(self.params)
        return ms.MAVLink_param_value_message(name.encode(), float(self.params[name].get()),
                                              ms.MAV_PARAM_TYPE_REAL32, len(names), names.index(name))

    def _on_param_request_list(self, msg: Any) -> list[Any]:
        return [self._param_value(n) for n in self.params] if self._for_me(msg) else []

    def _on_param_request_read(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        names = list(self.params)
        if msg.param_index >= 0:
            if msg.param_index < len(names):
                return [self._param_value(names[msg.param_index])]
            return self._statustext(ms.MAV_SEVERITY_WARNING, f"no parameter index {msg.param_index}")
        name = _param_name(msg.param_id)
        if name in self.params:
            return [self._param_value(name)]
        return self._statustext(ms.MAV_SEVERITY_WARNING, f"no parameter {name}")

    def _on_param_set(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        name = _param_name(msg.param_id)
        p = self.params.get(name)
        if p is None:
            self.counters.params_refused += 1
            return self._statustext(ms.MAV_SEVERITY_WARNING, f"no parameter {name}")
        x, why = protocol.param_set_value(msg)
        if why is not None:
            self.counters.params_refused += 1
            return [self._param_value(name)] + self._statustext(
                ms.MAV_SEVERITY_WARNING, f"{name} refused: {why}")
        why = "must be finite" if not math.isfinite(x) else p.check(x)
        if why is not None:
            self.counters.params_refused += 1
            return [self._param_value(name)] + self._statustext(
                ms.MAV_SEVERITY_WARNING, f"{name} {x:g} refused: {why}")
        p.set(x)
        self.counters.params_set += 1
        return [self._param_value(name)]

    def _on_lockstep(self, msg: Any) -> list[Any]:
        if not self.lockstep:
            self.counters.lockstep_refused += 1
            return self._say_once(ms.MAV_SEVERITY_WARNING, "LOCKSTEP ignored: real-time mode")
        k = msg.step
        if k == self._next_step and self.armed and self._setpoint_sequence != k:
            # Armed, a lockstep step needs its own setpoint (sequence = step): a lost setpoint
            # must not be replaced silently by the previous one. The host resends both.
            self.counters.lockstep_refused += 1
            return self._say_once(ms.MAV_SEVERITY_WARNING,
                                  f"LOCKSTEP {k} refused: setpoint {k} missing", key="lockstep")
        if k == self._next_step:
            out = self.tick(step=k)
            self._next_step = k + 1
            self._last_reply = out
            return out
        if k + 1 == self._next_step and self._last_reply is not None:
            self.counters.lockstep_repeated += 1
            return list(self._last_reply)
        self.counters.lockstep_refused += 1
        return self._say_once(ms.MAV_SEVERITY_WARNING,
                              f"LOCKSTEP {k} refused: expected {self._next_step}", key="lockstep")

    _handlers = {ms.MAVLINK_MSG_ID_LEG_SETPOINT: _on_setpoint,
                 ms.MAVLINK_MSG_ID_COMMAND_LONG: _on_command,
                 ms.MAVLINK_MSG_ID_COMMAND_INT: _on_command,   # the same commands, same acks
                 ms.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: _on_param_request_list,
                 ms.MAVLINK_MSG_ID_PARAM_REQUEST_READ: _on_param_request_read,
                 ms.MAVLINK_MSG_ID_PARAM_SET: _on_param_set,
                 ms.MAVLINK_MSG_ID_LOCKSTEP: _on_lockstep}

    # --- time ----------------------------------------------------------------------------

    def tick(self, step: int | None = None) -> list[Any]:
        """Advance one controller period; the telemetry due (in lockstep: with `step`)."""
        out: list[Any] = []
        if (self.armed and self.watchdog_state == ms.STEWART_WATCHDOG_OK
                and self._watchdog_expired()):
            self._hold()
            self.watchdog_state = ms.STEWART_WATCHDOG_TRIPPED
            self.counters.watchdog_trips += 1
            out += self._statustext(ms.MAV_SEVERITY_CRITICAL,
                                    f"watchdog: no setpoint for {self.watchdog:g} s: holding")
        if self._homing is not None:
            self._homing_reference()
        outputs = self.plant.outputs
        l, ldot = outputs.lengths, outputs.rates
        good_q = outputs.q.copy()
        try:
            v, sat = self.ctrl.step(self.l_ref, self.ldot_ref, l, ldot, self.v_ff)
            torque, limited = self.motors.step(v, ldot)
            if not (np.all(np.isfinite(v)) and np.all(np.isfinite(torque))):
                raise FloatingPointError("non-finite motor voltage or torque")
            self._v, self._sat = v, sat | limited
            self.port.step(self.plant.time, self.dt, torque)
        except PlantStepError as exc:
            out += self._fault(str(exc))
        except (IntegrationError, StewartError, ArithmeticError, ValueError,
                np.linalg.LinAlgError) as exc:
            out += self._numeric_fault(good_q, exc)
        self.k += 1
        self.counters.ticks += 1
        if self._observer is not None and self.k % self._observe_every == 0:
            self._observer.publish(self.snapshot())
        out += self._telemetry(step)
        return self._limit_statustext(out)

    def _numeric_fault(self, good_q: np.ndarray, exc: BaseException) -> list[Any]:
        """A numerical failure in the loop: restart the plant at rest at the last good pose,
        drives holding it with the designed gains and the motor's rated limits, disarm, one
        CRITICAL STATUSTEXT; the device keeps serving."""
        self.counters.numeric_faults += 1
        self.ctrl.gains = self.design_gains
        self._set_motor("voltage_limit", self.design_motor.voltage_limit)
        self._set_motor("current_limit", self.design_motor.current_limit)
        t = self.plant.time if math.isfinite(self.plant.time) else self.k * self.dt
        q = good_q if np.all(np.isfinite(good_q)) else self._last_pose
        try:
            self._start_holding(q, t)
        except (StewartError, ArithmeticError, ValueError, np.linalg.LinAlgError):
            self._start_holding(np.asarray(self.model.home, dtype=float), t)
        self._disarm()
        self._v, self._sat = np.zeros(6), np.zeros(6, dtype=bool)
        self.last_fault = f"{type(exc).__name__}: {exc}"
        return self._say_once(ms.MAV_SEVERITY_CRITICAL,
                              f"numeric fault ({type(exc).__name__})"[:34] + ": hold, disarmed",
                              key="numeric-fault")

    def _watchdog_expired(self) -> bool:
        """`watchdog` s without a valid setpoint: by the wall clock when served in real time
        (`clock` set: catching up after a stall must not trip it early), else by device time."""
        if self.clock is not None:
            return self.clock() - self._last_setpoint_wall >= self.watchdog
        return (self.k - self._last_setpoint_k) * self.dt >= self.watchdog - 1e-9 * self.dt

    def _fault(self, why: str) -> list[Any]:
        """The plant refused the step: stop at rest where it is, drives holding; disarm."""
        self.counters.faults += 1
        q, t = self.plant.outputs.q, self.plant.time
        self._start_holding(q, t)
        self._disarm()
        return self._statustext(ms.MAV_SEVERITY_CRITICAL, f"fault, stopped and disarmed: {why}")

    def _due(self, hz: float) -> bool:
        if hz <= 0:
            return False
        period = max(1, round(self.rate / hz))
        return (self.k - 1) % period == 0

    def _telemetry(self, step: int | None) -> list[Any]:
        out = []
        if self._due(HEARTBEAT_HZ):
            out.append(self.heartbeat())
        r = self.rates
        if self._due(r["SYS_STATUS"]):
            out.append(self.sys_status())
        if self._due(r["ATTITUDE_QUATERNION"]):
            out += [self.attitude(), self.attitude_euler()]
        if self._due(r["LOCAL_POSITION_NED"]):
            out.append(self.local_position())
        if self._due(r["DRIVE_STATUS"]):
            out.append(self.drive_status())
        if step is not None:
            out += [self.leg_state(step), ms.MAVLink_lockstep_message(self._usec(), step)]
        elif self._due(r["LEG_STATE"]):
            out.append(self.leg_state(0))
        return out

    # --- messages ------------------------------------------------------------------------

    def heartbeat(self) -> Any:
        base = ms.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (ms.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        if self.watchdog_state == ms.STEWART_WATCHDOG_TRIPPED:
            state = ms.MAV_STATE_CRITICAL
        else:
            state = ms.MAV_STATE_ACTIVE if self.armed else ms.MAV_STATE_STANDBY
        mode = CUSTOM_MODE_LOCKSTEP if self.lockstep else CUSTOM_MODE_REALTIME
        return ms.MAVLink_heartbeat_message(ms.MAV_TYPE_GENERIC, ms.MAV_AUTOPILOT_GENERIC, base,
                                            mode, state, 3)

    def sys_status(self) -> Any:
        c = self.counters
        health = _CONTROL_SENSORS
        if self.watchdog_state == ms.STEWART_WATCHDOG_TRIPPED:
            health &= ~(ms.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                        | ms.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                        | ms.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
        return ms.MAVLink_sys_status_message(
            _CONTROL_SENSORS, _CONTROL_SENSORS if self.armed else 0, health,
            min(int(self.load), 1000), _U16, -1, -1, 0, min(self.link_errors, _U16),
            min(c.setpoints_refused, _U16), min(c.signing_rejected, _U16),
            min(c.watchdog_trips, _U16), min(c.faults, _U16))

    @property
    def link_errors(self) -> int:
        """Frames dropped on input: framing rejects (CRC, length, unknown id...) + signing."""
        # a signing rejection is also a decode error of the Receiver: counted there, once
        return self.rx.stats.rejected

    def leg_state(self, step: int = 0) -> Any:
        o = self.plant.outputs
        return ms.MAVLink_leg_state_message(self._usec(), o.lengths.tolist(), o.rates.tolist(),
                                            self.plant.rack_force.tolist(), step & _U32)

    def drive_status(self) -> Any:
        bits = sum(1 << i for i in range(6) if self._sat[i])
        return ms.MAVLink_drive_status_message(
            self._usec(), self._v.tolist(), self.motors.current.tolist(), bits, self.watchdog_state,
            min(self.counters.setpoints_refused, _U32),
            min(self.rx.stats.crc_errors + self.counters.signing_rejected, _U32))

    def attitude(self) -> Any:
        o = self.plant.outputs
        q = o.q
        w, x, y, z = ned_attitude(q)
        body = rotation(q).T @ o.twist[3:]
        return ms.MAVLink_attitude_quaternion_message(self._time_ms(), w, x, y, z, float(body[0]),
                                                      float(-body[1]), float(-body[2]))

    def attitude_euler(self) -> Any:
        """ATTITUDE (roll, pitch, yaw and body rates in NED/FRD), beside ATTITUDE_QUATERNION."""
        a = self.attitude()
        roll, pitch, yaw = protocol.attitude_euler(self.plant.outputs.q)
        return ms.MAVLink_attitude_message(a.time_boot_ms, roll, pitch, yaw, a.rollspeed,
                                           a.pitchspeed, a.yawspeed)

    def home_position(self) -> Any:
        """HOME_POSITION: the scene's home in LOCAL_POSITION_NED's convention (hil.protocol)."""
        home = np.asarray(self.model.home, dtype=float)
        return protocol.home_position(home, ned_attitude(home), self._usec())

    def local_position(self) -> Any:
        o = self.plant.outputs
        q, qd = o.q, o.qd
        return ms.MAVLink_local_position_ned_message(self._time_ms(), float(q[0]), float(-q[1]),
                                                     float(-q[2]), float(qd[0]), float(-qd[1]),
                                                     float(-qd[2]))

    def _time_ms(self) -> int:
        return int(self.k * 1000 // self.rate) & _U32

    def _statustext(self, severity: int, text: str) -> list[Any]:
        """STATUSTEXT; longer than 50 bytes: chunks on UTF-8 character boundaries with a common
        id and chunk_seq 0, 1, ... (hil.protocol.statustext_chunks)."""
        msgs = protocol.statustext_messages(severity, text, self._statustext_id % 0xFFFF + 1)
        if len(msgs) > 1:
            self._statustext_id = msgs[0].id
        return msgs

    def _say_once(self, severity: int, text: str, key: str | None = None) -> list[Any]:
        """A STATUSTEXT, unless one of the same key (default: the text) went out less than
        STATUS_REPEAT s of device time ago (so a flood of bad input cannot flood the link)."""
        key = text if key is None else key
        last = self._said.get(key)
        if last is not None and (self.k - last) * self.dt < STATUS_REPEAT:
            self.counters.statustexts_suppressed += 1
            return []
        if len(self._said) >= 256:
            self._said.clear()
        self._said[key] = self.k
        return self._statustext(severity, text)


def _param_name(param_id: Any) -> str:
    if isinstance(param_id, bytes):
        param_id = param_id.decode("ascii", "replace")
    return str(param_id).rstrip("\x00")
