"""The emulated micro-manipulator behind MAVLink: a dispatcher over its mode, drives and tables.

`Device` is transport-agnostic: it takes decoded messages of our dialect (`receive`) or raw bytes
(`feed`, through a robust `hil.framing.Receiver` that also checks MAVLink 2 signatures), advances
one controller period per `tick()`, and returns the messages it wants to send (pack them with
`Device.pack`). `hil.serve.serve` runs it over a transport, in real time or in lockstep.

Its parts: the mode and its one transition table (hil.modes: DISARMED, ARMED, TRACKING, HOMING,
TRIPPED), the plant and the six drive loops (hil.servo, whose tick is the co-simulation master's
`controller.axis.servo_step`), the telemetry messages (hil.downlink), the parameter table
(hil.params), the input bounds (hil.bounds) and the STATUSTEXT token bucket (hil.throttle). The device starts
DISARMED at the scene's home pose with the drives holding it. Every text a user reads numbers
the legs 1..6, as the tables and plots do.

Setpoints (LEG_SETPOINT)
------------------------
A setpoint is refused (STATUSTEXT, counted, never applied) when a length, rate or force is not
finite, a rate, force or force rate is beyond the bounds of hil.bounds (the text names the leg,
the value and the bound), a length is outside [SP_LEN_MIN, SP_LEN_MAX] (the stroke less the
servo's overshoot room at each end, hil.bounds.overshoot_room), forward kinematics finds no
pose for the lengths (Newton from the last accepted pose), or cond(J) at that pose exceeds the
parameter SP_COND_MAX. A valid setpoint is the event SETPOINT: applied while armed, ignored and
counted while disarmed (hil.modes). Rates are used with STEWART_SETPOINT_FLAG_RATE_VALID, forces
with STEWART_SETPOINT_FLAG_FORCE_VALID (the feed-forward of hil.servo; di/dt from the force rate
with STEWART_SETPOINT_FLAG_FORCE_RATE_VALID, else 0). HOLD holds the current leg lengths.

Watchdog and faults
-------------------
While TRACKING, when `watchdog` seconds (device time, i.e. ticks; served in real time, the
monotonic wall clock `clock` that also schedules the ticks) pass without a valid setpoint, the
device holds the leg lengths measured at that tick and sends one STATUSTEXT. If the plant refuses
a step (a leg at its end stop), the device stops the platform where it is (restarted at rest,
drives holding), disarms and says so. Any numerical failure of a tick (non-finite voltage or
torque, IntegrationError...) restarts the plant at rest at the last good pose, drives holding with
the designed gains and rated limits, disarms and sends one CRITICAL STATUSTEXT that names each gain
and limit it restored, with the value before and after: the device never exits on numbers.
With a signing key, frames pass `hil.signing.Verifier` (the signature before
any timestamp is stored) before they are decoded.

Commands (COMMAND_LONG or COMMAND_INT -> COMMAND_ACK)
------------------------------------------------------
MAV_CMD_COMPONENT_ARM_DISARM (param1 1 arm, 0 disarm); MAV_CMD_NAV_RETURN_TO_LAUNCH ("home": move
to the scene's home leg lengths along a quintic in leg space at a quarter stroke per second peak,
then hold). MAV_CMD_DO_SET_HOME is refused as unsupported: the home pose is the scene's.
MAV_CMD_GET_HOME_POSITION (or MAV_CMD_REQUEST_MESSAGE of HOME_POSITION): HOME_POSITION after the
ack (the scene's home in the convention of LOCAL_POSITION_NED, see hil.protocol); HOME_POSITION
also goes out once on arming. Other commands: MAV_RESULT_UNSUPPORTED. PARAM_* messages: hil.params.
Every frame sent carries the next sequence number (mod 256).

Lockstep
--------
With `lockstep=True` time advances only on LOCKSTEP(step=k) (when armed, only once the setpoint
with sequence k has been accepted: a lost setpoint is never replaced silently by the previous
one): the device applies what it received before (the setpoint for step k), ticks once and
answers with the telemetry due, one LEG_STATE with `step = k` and LOCKSTEP(step=k) echoed, all
stamped with the device time after the step. Steps are numbered from 0; a repeated step is
answered again without ticking (the host may resend after a loss), any other step number is
refused with a STATUSTEXT.

The machine and its sensors
---------------------------
With `truth` (a hidden true scene, checked by hil.truth.check_truth) the plant is built from it
while the drive loops, the feed-forward and the setpoint checks keep `model`, the scene the host
believes. With `sensors` (the [sensors] table, hil.sensors) what the device reports of its legs
(LEG_STATE's lengths, rates and forces, DRIVE_STATUS's currents) is quantised, noisy and late as
the table says; its drive loops, the observers and the pose telemetry use the plant's own
numbers. Ideal sensors (the default) report the plant's numbers bit for bit.

Observers
---------
`Device.observe(latest, hz)` makes every tick that ends a 1/hz interval publish a
`hil.observe.Snapshot` (time, pose, the pose of the followed setpoint, leg lengths, rack forces,
cond(J)) into a `hil.observe.Latest` that other threads read (the live view of `stewart-sim
device --view`); without an observer a tick pays one attribute test.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from controller.axis import AxisControllers, MotorCurrents
from controller.config import ControllerConfig, controller_config
from controller.design import PidGains
from controller.plants import PlantStepError
from hil import bounds, downlink, modes, params, protocol, throttle
from hil import mavlink_stewart as ms
from hil.framing import Receiver, pack
from hil.modes import Event, Mode
from hil.observe import OBSERVE_HZ, Latest, Snapshot
from hil.sensors import SensorConfig, Sensors
from hil.servo import Servo
from hil.signing import SignedDecoder, Verifier, wall_timestamp
from hil.truth import check_truth
from stewart_fmu.errors import IntegrationError, StewartError
from stewart_fmu.kinematics import condition_number, forward_kinematics, inverse_kinematics
from stewart_fmu.model import Model

STATUS_REPEAT = 0.1        # s: the same refusal text is not repeated within this device time
SIGNING_EPOCH = 1420070400  # MAVLink 2 signing timestamps count 10 us units since 2015-01-01


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
    statustexts_rate_limited: int = 0  # cut by the STATUSTEXT token bucket (hil.throttle)
    frames_valid: int = 0           # decoded (and authenticated) frames for this system
    peer_changes: int = 0           # UDP peer switches (hil.peer)
    peer_kept: int = 0              # peer changes refused: armed, hold, a flood (hil.peer)
    flood_dropped: int = 0          # datagrams over their sender's budget, undecoded (hil.peer)


class Device:
    """The emulated micro-manipulator (see the module doc)."""

    def __init__(self, model: Model, config: ControllerConfig | None = None, watchdog: float = 0.2,
                 telemetry: dict[str, float] | None = None, signing_key: bytes | None = None, *,
                 lockstep: bool = False, system_id: int = 1, component_id: int = 1,
                 truth: Model | None = None, sensors: SensorConfig | None = None) -> None:
        self.model = model
        if truth is not None:
            check_truth(model, truth)
        self.config = config if config is not None else controller_config(model)
        self.rate = self.config.rate
        self.dt = self.config.dt
        lo, hi = bounds.WATCHDOG_RANGE
        if not (math.isfinite(watchdog) and lo <= watchdog <= hi):
            raise DeviceError(f"watchdog must be a finite time in [{lo:g}, {hi:g}] s, got {watchdog!r}")
        self.settings = params.Settings(float(watchdog))
        self.lockstep = bool(lockstep)
        known = sorted(self.settings.rates)   # hil.downlink.TELEMETRY's streams
        for name, hz in (telemetry or {}).items():
            if name not in known:
                raise DeviceError(f"telemetry: unknown stream {name!r} (known: {known})")
            why = params.check_rate(hz)
            if why:
                raise DeviceError(f"telemetry {name}: {why}")
            self.settings.rates[name] = float(hz)
        self.counters = DeviceCounters()
        self.mav = ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.verifier: Verifier | None = None
        if signing_key is not None:
            self._setup_signing(signing_key)
        self.rx = Receiver(ms, self.mav if self.verifier is None else SignedDecoder(
            ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id), self.verifier,
            self._signing_refused))
        self.limiter = throttle.StatusLimiter(self.config.dt)

        self.servo = Servo(model, self.config, truth)
        self.plant = self.servo.plant
        # what the device reports of its legs (hil.sensors); None: the plant's own numbers
        self.sensors: Sensors | None = None
        if sensors is not None and not sensors.ideal:
            o = self.plant.outputs
            self.sensors = Sensors(sensors, self.rate, o.lengths, o.rates, self.plant.rack_force,
                                   self.servo.motors.current,
                                   (truth if truth is not None else model).source)
        self.leg_min = model.leg_min if model.leg_min is not None else 0.0
        self.leg_max = model.leg_max if model.leg_max is not None else math.inf
        self.home_lengths = inverse_kinematics(model, model.home, with_cond=False).lengths.copy()
        room = bounds.overshoot_room(self.servo.ctrl.axis, float(np.max(np.abs(
            self.plant.rack_force))))
        self.bounds = bounds.device_bounds(self.leg_min, self.leg_max, self.servo.ctrl.axis,
                                    self.servo.design_gains, room)
        if not self.bounds.leg_min < self.bounds.leg_max:
            raise DeviceError(f"the stroke [{self.leg_min:g}, {self.leg_max:g}] m leaves no "
                              f"setpoint once the servo's overshoot room ({room:.3g} m at each "
                              "end, hil.bounds) is kept free")

        self._mode = Mode.DISARMED        # moved only by _fire (hil.modes.transition)
        self.k = 0                       # ticks done; device time = k / rate
        self._last_setpoint_k = 0
        self._last_pose = np.asarray(model.home, dtype=float).copy()
        self._ignored_said = False       # one "setpoints ignored" per disarmed period
        self._said: dict[str, int] = {}  # refusal text -> tick it was last sent
        self._statustext_id = 0
        self._next_step = 0
        self._setpoint_sequence: int | None = None   # sequence of the last accepted setpoint
        self._last_reply: list[Any] | None = None
        self.load = 0                    # per mille of the tick period (set by serve)
        self.last_fault: str | None = None   # the last numerical fault, in full
        # real time (set by serve): the monotonic wall clock the watchdog runs on; None: ticks
        self.clock: Callable[[], float] | None = None
        self._last_setpoint_wall = 0.0
        # observers (hil.observe): a snapshot every _observe_every ticks into _observer
        self._observer: Latest | None = None
        self._observe_every = 1
        self.params = params.parameters(self.servo, self.settings, self.bounds, self.rate)

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

    # --- state ---------------------------------------------------------------------------

    @property
    def mode(self) -> Mode:
        """The device's mode (hil.modes)."""
        return self._mode

    @property
    def armed(self) -> bool:
        return modes.armed(self._mode)

    @property
    def watchdog_state(self) -> int:
        """The watchdog's state as DRIVE_STATUS sends it (STEWART_WATCHDOG_*)."""
        return modes.WATCHDOG_STATE[self._mode]

    @property
    def watchdog(self) -> float:
        """s without a valid setpoint before the watchdog trips (parameter WDG_TIMEOUT)."""
        return self.settings.watchdog

    @property
    def rates(self) -> dict[str, float]:
        """Telemetry rates (Hz) by stream name (parameters SR_*)."""
        return self.settings.rates

    @property
    def ctrl(self) -> AxisControllers:
        return self.servo.ctrl

    @property
    def motors(self) -> MotorCurrents:
        return self.servo.motors

    @property
    def gains(self) -> PidGains:
        return self.servo.ctrl.gains

    @property
    def design_gains(self) -> PidGains:
        return self.servo.design_gains

    @property
    def l_ref(self) -> np.ndarray:
        """The leg lengths the drives follow now."""
        return self.servo.l_ref

    @property
    def time(self) -> float:
        """Device time (s): ticks / rate."""
        return self.k / self.rate

    def _usec(self) -> int:
        return int(round(self.k * 1e6 / self.rate))

    def _time_ms(self) -> int:
        return int(self.k * 1000 // self.rate) & 0xFFFFFFFF

    def _fire(self, event: Event) -> str | None:
        """Move the mode as hil.modes.transition says; the refusal (mode unchanged) or None."""
        t = modes.transition(self._mode, event)
        if t.refusal is None:
            self._mode = t.mode
            if t.mode is Mode.DISARMED:
                self._ignored_said = False
        return t.refusal

    def pack(self, msg: Any) -> bytes:
        """The MAVLink 2 frame of `msg` from this device (signed when a key is set)."""
        return pack(self.mav, msg)

    # --- observers -----------------------------------------------------------------------

    def observe(self, latest: Latest | None, hz: float = OBSERVE_HZ) -> None:
        """Publish a snapshot into `latest` now and then every rate/hz ticks (at most every
        tick); None stops publishing. The cost falls on one tick in rate/hz (hil.observe)."""
        why = params.check_rate(hz)
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
        ref = self.servo.reference_pose
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

    def say(self, severity: int, text: str, key: str | None = None) -> list[Any]:
        """A STATUSTEXT of the device's own (e.g. hil.peer's notice), under the same repeat rule
        and token bucket as its replies."""
        return self._limit_statustext(self._say_once(severity, text, key))

    def _limit_statustext(self, out: list[Any]) -> list[Any]:
        """The STATUSTEXT token bucket (hil.throttle.StatusLimiter) over `out`."""
        n = self.limiter.suppressed
        out = self.limiter.filter(out, self.k, ms.MAV_SEVERITY_CRITICAL)
        self.counters.statustexts_rate_limited += self.limiter.suppressed - n
        return out

    def _for_me(self, msg: Any) -> bool:
        return (msg.target_system in (0, self.mav.srcSystem)
                and msg.target_component in (0, self.mav.srcComponent))

    def _on_setpoint(self, msg: Any) -> list[Any]:
        flags = msg.flags
        hold = bool(flags & ms.STEWART_SETPOINT_FLAG_HOLD)
        why, pose = (None, None) if hold else self._validate(msg, flags)
        if why is not None:
            self.counters.setpoints_refused += 1
            return self._say_once(ms.MAV_SEVERITY_WARNING, f"refused: {why}", key="refused")
        was = self._mode
        why = self._fire(Event.SETPOINT)
        if why is not None:
            self.counters.setpoints_ignored += 1
            if self._ignored_said:
                return []
            self._ignored_said = True
            return self._statustext(ms.MAV_SEVERITY_WARNING, why)
        self.counters.setpoints_accepted += 1
        out = []
        if was is Mode.TRIPPED:
            out = self._statustext(ms.MAV_SEVERITY_NOTICE, "watchdog: setpoints resumed")
        self._last_setpoint_k = self.k
        self._last_setpoint_wall = self.clock() if self.clock is not None else 0.0
        self._setpoint_sequence = msg.sequence
        if hold:
            self.servo.hold()
            return out
        self._last_pose = pose
        force = _flagged(flags, ms.STEWART_SETPOINT_FLAG_FORCE_VALID, msg.force)
        self.servo.follow(np.array(msg.length, dtype=float),
                          _flagged(flags, ms.STEWART_SETPOINT_FLAG_RATE_VALID, msg.rate), pose, force,
                          None if force is None else
                          _flagged(flags, ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID, msg.force_rate))
        return out

    def _validate(self, msg: Any, flags: int) -> tuple[str | None, np.ndarray | None]:
        """(why the setpoint is refused or None, its pose); legs numbered 1..6."""
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
        lo, hi = self.bounds.leg_min, self.bounds.leg_max
        bad = [i for i in range(6) if not lo <= lengths[i] <= hi]
        if bad:
            i = bad[0]
            side, bound = ("min", lo) if lengths[i] < lo else ("max", hi)
            return f"leg {i + 1} at {lengths[i]:.4g} m, stroke {side} {bound:.4g}", None
        try:
            pose = forward_kinematics(self.model, lengths, guess=self._last_pose)
        except StewartError:
            return "no pose has these lengths", None
        cond = condition_number(self.model, pose)
        if not cond <= self.settings.cond_max:
            return f"near-singular, cond {cond:.3g} > {self.settings.cond_max:g}", None
        return None, pose

    def _on_command(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        self.counters.commands += 1
        cmd = msg.command
        if cmd == ms.MAV_CMD_COMPONENT_ARM_DISARM:
            result, out = self._on_arm_disarm(msg.param1)
        elif cmd == ms.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            result, out = self._on_home()
        else:
            result, out = self._on_other_command(msg)
        if result != ms.MAV_RESULT_ACCEPTED:
            self.counters.commands_refused += 1
        ack = ms.MAVLink_command_ack_message(cmd, result, 0, 0, msg.get_srcSystem(),
                                             msg.get_srcComponent())
        return [ack] + out

    def _on_arm_disarm(self, param1: float) -> tuple[int, list[Any]]:
        """ARM (param1 1: hold the lengths now; "armed" and HOME_POSITION when it was
        disarmed), DISARM (param1 0: hold; "disarmed: holding" when it was armed)."""
        was_armed = self.armed
        if param1 == 1.0:
            self._fire(Event.ARM)
            self.servo.hold()
            out = [] if was_armed else (self._statustext(ms.MAV_SEVERITY_INFO, "armed")
                                        + [self.home_position()])
            return ms.MAV_RESULT_ACCEPTED, out
        if param1 == 0.0:
            self._disarm()
            out = self._statustext(ms.MAV_SEVERITY_INFO, "disarmed: holding") if was_armed else []
            return ms.MAV_RESULT_ACCEPTED, out
        return ms.MAV_RESULT_DENIED, self._say_once(
            ms.MAV_SEVERITY_WARNING, f"arm/disarm param1 {param1:.3g} refused: must be 0 or 1",
            key="arm-denied")

    def _on_home(self) -> tuple[int, list[Any]]:
        why = self._fire(Event.HOME)
        if why is not None:
            return ms.MAV_RESULT_TEMPORARILY_REJECTED, self._statustext(ms.MAV_SEVERITY_WARNING, why)
        stroke = (self.leg_max - self.leg_min) if math.isfinite(self.leg_max) else 1.0
        self.servo.start_homing(self.home_lengths, self.k, self.rate, stroke)
        return ms.MAV_RESULT_ACCEPTED, self._statustext(ms.MAV_SEVERITY_INFO, "homing")

    def _on_other_command(self, msg: Any) -> tuple[int, list[Any]]:
        """GET_HOME_POSITION (and REQUEST_MESSAGE of HOME_POSITION): HOME_POSITION after the
        ack; anything else unsupported."""
        if msg.command == ms.MAV_CMD_GET_HOME_POSITION or (
                msg.command == ms.MAV_CMD_REQUEST_MESSAGE
                and msg.param1 == ms.MAVLINK_MSG_ID_HOME_POSITION):
            return ms.MAV_RESULT_ACCEPTED, [self.home_position()]
        return ms.MAV_RESULT_UNSUPPORTED, []

    def _disarm(self) -> None:
        self._fire(Event.DISARM)
        self.servo.hold()

    def _on_param_request_list(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        return [params.value_message(self.params, n) for n in self.params]

    def _on_param_request_read(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        out, why = params.read(self.params, msg)
        return out if why is None else self._statustext(ms.MAV_SEVERITY_WARNING, why)

    def _on_param_set(self, msg: Any) -> list[Any]:
        if not self._for_me(msg):
            return []
        out, why = params.set_from(self.params, msg)
        if why is None:
            self.counters.params_set += 1
            return out
        self.counters.params_refused += 1
        return out + self._statustext(ms.MAV_SEVERITY_WARNING, why)

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
        if self._mode is Mode.TRACKING and self._watchdog_expired():
            self._fire(Event.WATCHDOG_EXPIRED)
            self.servo.hold()
            self.counters.watchdog_trips += 1
            out += self._statustext(ms.MAV_SEVERITY_CRITICAL,
                                    f"watchdog: no setpoint for {self.settings.watchdog:g} s: holding")
        if self._mode is Mode.HOMING and self.servo.homing_reference(self.k, self.rate):
            self._fire(Event.HOMING_DONE)
        good_q = self.plant.outputs.q.copy()
        try:
            self.servo.tick()
        except PlantStepError as exc:
            out += self._fault(str(exc))
        except (IntegrationError, StewartError, ArithmeticError, ValueError,
                np.linalg.LinAlgError) as exc:
            out += self._numeric_fault(good_q, exc)
        self.k += 1
        self.counters.ticks += 1
        if self.sensors is not None:
            o = self.plant.outputs
            self.sensors.sample(o.lengths, o.rates, self.plant.rack_force,
                                self.servo.motors.current)
        if self._observer is not None and self.k % self._observe_every == 0:
            self._observer.publish(self.snapshot())
        out += self._telemetry(step)
        return self._limit_statustext(out)

    def _numeric_fault(self, good_q: np.ndarray, exc: BaseException) -> list[Any]:
        """A numerical failure in the loop: restart the plant at rest at the last good pose,
        drives holding it with the designed gains and the motor's rated limits, disarm, one
        CRITICAL STATUSTEXT (in chunks) that names every gain and limit restored with its value
        before and after (hil.params.restored_text); the device keeps serving."""
        self.counters.numeric_faults += 1
        before = {n: self.params[n].get() for n in params.DESIGN_PARAMS}
        self.servo.restore_design()
        restored = params.restored_text(before, self.params)
        self.servo.restart_after_failure(good_q, self._last_pose, self.k * self.dt)
        self._fire(Event.FAULT)
        self.servo.hold()
        self.servo.idle()
        self.last_fault = f"{type(exc).__name__}: {exc}; {restored}"
        # the first chunk (50 bytes) says what happened, the rest which values now hold
        return self._say_once(ms.MAV_SEVERITY_CRITICAL,
                              f"numeric fault ({type(exc).__name__})"[:34] + ": hold, disarmed"
                              + f"; {restored}", key="numeric-fault")

    def _watchdog_expired(self) -> bool:
        """`watchdog` s without a valid setpoint: by the wall clock when served in real time
        (`clock` set: catching up after a stall must not trip it early), else by device time."""
        watchdog = self.settings.watchdog
        if self.clock is not None:
            return self.clock() - self._last_setpoint_wall >= watchdog
        return (self.k - self._last_setpoint_k) * self.dt >= watchdog - 1e-9 * self.dt

    def _fault(self, why: str) -> list[Any]:
        """The plant refused the step: stop at rest where it is, drives holding; disarm."""
        self.counters.faults += 1
        self.servo.start_holding(self.plant.outputs.q, self.plant.time)
        self._fire(Event.FAULT)
        self.servo.hold()
        return self._statustext(ms.MAV_SEVERITY_CRITICAL, f"fault, stopped and disarmed: {why}")

    def _telemetry(self, step: int | None) -> list[Any]:
        k, rate, r = self.k, self.rate, self.settings.rates
        out = []
        if downlink.due(k, rate, downlink.HEARTBEAT_HZ):
            out.append(self.heartbeat())
        if downlink.due(k, rate, r["SYS_STATUS"]):
            out.append(self.sys_status())
        if downlink.due(k, rate, r["ATTITUDE_QUATERNION"]):
            o = self.plant.outputs
            out += [downlink.attitude(self._time_ms(), o.q, o.twist),
                    downlink.attitude_euler(self._time_ms(), o.q, o.twist)]
        if downlink.due(k, rate, r["LOCAL_POSITION_NED"]):
            out.append(self.local_position())
        if downlink.due(k, rate, r["DRIVE_STATUS"]):
            out.append(self.drive_status())
        if step is not None:
            out += [self.leg_state(step), ms.MAVLink_lockstep_message(self._usec(), step)]
        elif downlink.due(k, rate, r["LEG_STATE"]):
            out.append(self.leg_state(0))
        return out

    # --- messages (hil.downlink builds them) --------------------------------------------

    def heartbeat(self) -> Any:
        return downlink.heartbeat(self._mode, self.lockstep)

    def sys_status(self) -> Any:
        c = self.counters
        return downlink.sys_status(self._mode, self.load, self.link_errors, c.setpoints_refused,
                                    c.signing_rejected, c.watchdog_trips, c.faults)

    @property
    def link_errors(self) -> int:
        """Frames dropped on input: framing rejects (CRC, length, unknown id...) + signing."""
        # a signing rejection is also a decode error of the Receiver: counted there, once
        return self.rx.stats.rejected

    def leg_state(self, step: int = 0) -> Any:
        """LEG_STATE: the legs as the sensors report them (hil.sensors)."""
        m = self.sensors
        if m is not None:
            return downlink.leg_state(self._usec(), m.lengths, m.rates, m.force, step)
        o = self.plant.outputs
        return downlink.leg_state(self._usec(), o.lengths, o.rates, self.plant.rack_force, step)

    def drive_status(self) -> Any:
        s = self.servo
        current = s.motors.current if self.sensors is None else self.sensors.current
        return downlink.drive_status(self._usec(), self._mode, s.voltage, current,
                                      s.saturated, self.counters.setpoints_refused,
                                      self.rx.stats.crc_errors + self.counters.signing_rejected)

    def home_position(self) -> Any:
        """HOME_POSITION: the scene's home in LOCAL_POSITION_NED's convention (hil.protocol)."""
        return downlink.home_position(np.asarray(self.model.home, dtype=float), self._usec())

    def local_position(self) -> Any:
        o = self.plant.outputs
        return downlink.local_position(self._time_ms(), o.q, o.qd)

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


def _flagged(flags: int, flag: int, values: Any) -> np.ndarray | None:
    """A setpoint's field as an array when its validity flag is set, else None."""
    return np.array(values, dtype=float) if flags & flag else None
