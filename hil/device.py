"""The emulated micro-manipulator behind MAVLink: a dispatcher over its mode, drives and tables.

`Device` is transport-agnostic: it takes decoded messages of our dialect (`receive`) or raw bytes
(`feed`, through a robust `hil.framing.Receiver` that also checks MAVLink 2 signatures), advances
one controller period per `tick()`, and returns the messages it wants to send (pack them with
`Device.pack`). `hil.serve.serve` runs it over a transport, in real time or in lockstep.

`Device` holds the state and dispatches: every message to its handler in one table
(hil.handlers: message id -> function of the device and the message; the commands in a second
table), every tick to the servo, the watchdog and fault rules (hil.faults) and the telemetry due
(hil.streams, over the message builders of hil.downlink). Its other parts: the mode and its one
transition table (hil.operating_mode: DISARMED, ARMED, TRACKING, HOMING, TRIPPED), the plant and the six
drive loops (hil.servo, whose tick is the co-simulation master's `controller.axis.servo_step`),
the setpoint checks (hil.setpoint, against the device's capability: controller.capability),
the parameter table (hil.params, its ranges hil.input_bounds), the STATUSTEXT rules
(hil.statustext, hil.throttle) and signing (hil.signing); its counters and per-run state are hil.device_state's. The device starts DISARMED
at the scene's home pose with the drives holding it. Every text a user reads numbers the legs
1..6, as the tables and plots do.

Setpoints (LEG_SETPOINT)
------------------------
A setpoint is refused (STATUSTEXT, counted, never applied) when a length, rate or force is not
finite, a rate, force or force rate is beyond the device's capability (Capability.setpoint_rate,
setpoint_force, setpoint_force_rate; the text names the leg, the value and the bound), a length
is outside [SP_LEN_MIN, SP_LEN_MAX] (the stroke less the servo's overshoot room at each end,
controller.capability.overshoot_room), forward kinematics finds no pose for the lengths (Newton
from the last accepted pose), cond(J) at that pose exceeds the parameter SP_COND_MAX, or the
pose violates a joint cone or a leg or obstacle clearance of the scene's [joints] and
[clearance] tables (Capability.geometric; the text names the limit, the leg or pair, and the
margin). A valid setpoint is the event SETPOINT: applied
while armed, ignored and counted while disarmed (hil.operating_mode). Rates are used with
STEWART_SETPOINT_FLAG_RATE_VALID, forces
with STEWART_SETPOINT_FLAG_FORCE_VALID (the feed-forward of hil.servo; di/dt from the force rate
with STEWART_SETPOINT_FLAG_FORCE_RATE_VALID, else 0). HOLD holds the current leg lengths.

POSE_SETPOINT carries a pose in a frame of the scene's [frames] (STEWART_FRAME: platform, pivot,
tool, user) and, with STEWART_POSE_SETPOINT_FLAG_RATE_VALID, its rates. It is refused when a
flag other than HOLD and RATE_VALID is set, the frame is unknown, a field is not finite, or a
position coordinate, an angle or a rate is past its bound (hil.input_bounds); else it becomes
the LEG_SETPOINT of the leg lengths of its platform pose and, with RATE_VALID, the leg rates of
its platform motion (hil.pose_setpoint), checked and followed as above (forward kinematics
starts at that pose), with no force.

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
With a signing key, frames pass `hil.signing.Verifier` (the signature before any timestamp is
stored) before they are decoded, and every frame sent is signed (hil.signing.sign_outgoing).

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
from typing import Any, Callable, Iterable

import numpy as np

from controller.axis import AxisControllers, MotorCurrents
from controller.capability import Capability, with_axis
from controller.config import ControllerConfig, controller_config
from controller.design import PidGains
from controller.plants import PlantStepError
from hil import faults, handlers, input_bounds, operating_mode, params, streams, throttle
from hil import mavlink_stewart as ms
from hil import statustext as texts
from hil.device_state import DeviceCounters, DeviceState
from hil.errors import DeviceError
from hil.framing import Receiver, pack
from hil.operating_mode import Event, Mode
from hil.observe import Latest, publish_to, take_snapshot
from hil.sensors import SensorConfig, Sensors
from hil.servo import Servo
from hil.signing import SignedDecoder, Verifier, sign_outgoing, wall_timestamp
from hil.truth import check_truth
from stewart_fmu.errors import IntegrationError, StewartError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model

__all__ = ["Device", "DeviceCounters", "DeviceError", "DeviceState"]

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
        self.rate, self.dt = self.config.rate, self.config.dt
        self.settings = _settings(watchdog, telemetry)
        self.lockstep = bool(lockstep)
        self.counters = DeviceCounters()
        self.mav = ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.verifier: Verifier | None = None
        if signing_key is not None:   # the clock looked up per check: tests replace it after
            self.verifier = sign_outgoing(self.mav, signing_key, lambda: self.signing_clock(),
                                          self._signing_refused)
        self.rx = Receiver(ms, self.mav if self.verifier is None else SignedDecoder(
            ms.MAVLink(None, srcSystem=system_id, srcComponent=component_id), self.verifier,
            self._signing_refused))
        self.limiter = throttle.StatusLimiter(self.config.dt)
        self.servo = Servo(model, self.config, truth)
        # the servo's parts, built once: its plant, drive loops, motors and designed gains
        self.plant = self.servo.plant
        self.ctrl: AxisControllers = self.servo.ctrl
        self.motors: MotorCurrents = self.servo.motors
        self.design_gains: PidGains = self.servo.design_gains
        # what the device reports of its legs (hil.sensors); None: the plant's own numbers
        self.sensors = _sensors(sensors, self.servo, self.rate, truth if truth is not None
                                else model)
        self.leg_min = model.leg_min if model.leg_min is not None else 0.0
        self.leg_max = model.leg_max if model.leg_max is not None else math.inf
        self.home_lengths = inverse_kinematics(model, model.home, with_cond=False).lengths.copy()
        # what the device accepts (controller.capability), the servo's overshoot room kept free
        self.capability = _capability(self.servo, model)
        self.param_ranges = input_bounds.param_ranges(self.servo.design_motor, self.design_gains)
        self.state = DeviceState(np.asarray(model.home, dtype=float).copy())
        self.k = 0                       # ticks done; device time = k / rate
        self.load = 0                    # per mille of the tick period (set by serve)
        self.last_fault: str | None = None   # the last numerical fault, in full
        # real time (set by serve): the monotonic wall clock the watchdog runs on; None: ticks
        self.clock: Callable[[], float] | None = None
        # observers (hil.observe): a snapshot every observe_every ticks into observer
        self.observer: Latest | None = None
        self.observe_every = 1
        self.params = params.parameters(self.servo, self.settings, self.param_ranges,
                                        self.capability, self.rate)

    #: The signing clock (10 us units since 2015): the wall clock; tests may replace it.
    signing_clock = staticmethod(wall_timestamp)

    def _signing_refused(self, why: str) -> None:
        self.counters.signing_rejected += 1

    # --- state ---------------------------------------------------------------------------

    @property
    def mode(self) -> Mode:
        """The device's mode (hil.operating_mode)."""
        return self.state.mode

    @property
    def armed(self) -> bool:
        return operating_mode.armed(self.state.mode)

    @property
    def watchdog_state(self) -> int:
        """The watchdog's state as DRIVE_STATUS sends it (STEWART_WATCHDOG_*)."""
        return operating_mode.WATCHDOG_STATE[self.state.mode]

    @property
    def watchdog(self) -> float:
        """s without a valid setpoint before the watchdog trips (parameter WDG_TIMEOUT)."""
        return self.settings.watchdog

    @property
    def rates(self) -> dict[str, float]:
        """Telemetry rates (Hz) by stream name (parameters SR_*)."""
        return self.settings.rates

    @property
    def gains(self) -> PidGains:
        return self.servo.ctrl.gains

    @property
    def l_ref(self) -> np.ndarray:
        """The leg lengths the drives follow now."""
        return self.servo.l_ref

    @property
    def time(self) -> float:
        """Device time (s): ticks / rate."""
        return self.k / self.rate

    def fire(self, event: Event) -> str | None:
        """Move the mode as hil.operating_mode.transition says; the refusal (mode unchanged) or None."""
        t = operating_mode.transition(self.state.mode, event)
        if t.refusal is None:
            self.state.mode = t.mode
            if t.mode is Mode.DISARMED:
                self.state.ignored_said = False
        return t.refusal

    def pack(self, msg: Any) -> bytes:
        """The MAVLink 2 frame of `msg` from this device (signed when a key is set)."""
        return pack(self.mav, msg)

    # --- observers -----------------------------------------------------------------------

    observe = publish_to
    snapshot = take_snapshot

    # --- input ---------------------------------------------------------------------------

    def feed(self, data: bytes) -> list[Any]:
        """Bytes from the link: decode every intact frame and `receive` it; the replies."""
        return self._receive_all(self.rx.feed(data))

    def flush(self) -> list[Any]:
        """The line went idle: give up a partial frame (the Receiver's flush); the replies."""
        return self._receive_all(self.rx.flush())

    def _receive_all(self, msgs: Iterable[Any]) -> list[Any]:
        """Count each decoded (with a key: authenticated) frame for this system (no target
        field, or target 0 or ours: what hil.peer needs), `receive` it; the replies."""
        out: list[Any] = []
        for msg in msgs:
            target = getattr(msg, "target_system", None)
            if target is None or target in (0, self.mav.srcSystem):
                self.counters.frames_valid += 1
            out += self.receive(msg)
        return out

    def receive(self, msg: Any) -> list[Any]:
        """Handle one decoded message of our dialect (hil.handlers.HANDLERS); the replies."""
        handler = handlers.HANDLERS.get(msg.get_msgId())
        if handler is None:
            return []
        try:
            out = handler(self, msg)
        except Exception as exc:  # the device keeps serving whatever a message holds
            self.counters.handler_errors += 1
            out = self.say_once(ms.MAV_SEVERITY_ERROR,
                                f"{msg.get_type()} dropped: {type(exc).__name__}", key="handler")
        return texts.limit(self, out)

    # --- time ----------------------------------------------------------------------------

    def tick(self, step: int | None = None) -> list[Any]:
        """Advance one controller period; the telemetry due (in lockstep: with `step`)."""
        out: list[Any] = []
        if self.state.mode is Mode.TRACKING and faults.watchdog_expired(self):
            out += faults.watchdog_trip(self)
        if self.state.mode is Mode.HOMING and self.servo.homing_reference(self.k, self.rate):
            self.fire(Event.HOMING_DONE)
        good_q = self.plant.outputs.q.copy()
        try:
            self.servo.tick()
        except PlantStepError as exc:
            out += faults.plant_fault(self, str(exc))
        except (IntegrationError, StewartError, ArithmeticError, ValueError,
                np.linalg.LinAlgError) as exc:
            out += faults.numeric_fault(self, good_q, exc)
        self.k += 1
        self.counters.ticks += 1
        if self.sensors is not None:
            o = self.plant.outputs
            self.sensors.sample(o.lengths, o.rates, self.plant.rack_force,
                                self.servo.motors.current)
        if self.observer is not None and self.k % self.observe_every == 0:
            self.observer.publish(self.snapshot())
        out += streams.due_messages(self, step)
        return texts.limit(self, out)

    # --- output: telemetry (hil.streams), STATUSTEXT (hil.statustext) -----------------------

    heartbeat = streams.heartbeat
    sys_status = streams.sys_status
    leg_state = streams.leg_state
    drive_status = streams.drive_status
    home_position = streams.home_position
    local_position = streams.local_position

    @property
    def link_errors(self) -> int:
        """Frames dropped on input: framing rejects (CRC, length, unknown id...) + signing."""
        # a signing rejection is also a decode error of the Receiver: counted there, once
        return self.rx.stats.rejected

    statustext = texts.statustext
    say_once = texts.say_once
    say = texts.say


def _settings(watchdog: float, telemetry: dict[str, float] | None) -> params.Settings:
    """The watchdog and stream rates asked of the constructor, checked (DeviceError)."""
    lo, hi = input_bounds.WATCHDOG_RANGE
    if not (math.isfinite(watchdog) and lo <= watchdog <= hi):
        raise DeviceError(f"watchdog must be a finite time in [{lo:g}, {hi:g}] s, got {watchdog!r}")
    settings = params.Settings(float(watchdog))
    known = sorted(settings.rates)   # hil.downlink.TELEMETRY's streams
    for name, hz in (telemetry or {}).items():
        if name not in known:
            raise DeviceError(f"telemetry: unknown stream {name!r} (known: {known})")
        why = input_bounds.check_rate(hz)
        if why:
            raise DeviceError(f"telemetry {name}: {why}")
        settings.rates[name] = float(hz)
    return settings


def _sensors(config: SensorConfig | None, servo: Servo, rate: float,
             plant_scene: Model) -> Sensors | None:
    """The sensors of the [sensors] table (hil.sensors) on `servo`'s plant, whose scene is
    `plant_scene`; None when ideal (the plant's own numbers)."""
    if config is None or config.ideal:
        return None
    o = servo.plant.outputs
    return Sensors(config, rate, o.lengths, o.rates, servo.plant.rack_force, servo.motors.current,
                   plant_scene.source)


def _capability(servo: Servo, model: Model) -> Capability:
    """The setpoints a device of this servo accepts: the capability of `model` with the servo's
    drive (controller.capability), inset by the servo's overshoot room at the force its plant
    holds; DeviceError when the room leaves no setpoint length."""
    held = float(np.max(np.abs(servo.plant.rack_force)))
    cap = with_axis(model, servo.ctrl.axis)
    room = cap.room(held)
    out = cap.inset(room)
    if not out.leg_min < out.leg_max:
        leg_min, leg_max = cap.ends
        raise DeviceError(f"the stroke [{leg_min:g}, {leg_max:g}] m leaves no "
                          f"setpoint once the servo's overshoot room ({room:.3g} m at each "
                          "end, controller.capability) is kept free")
    return out
