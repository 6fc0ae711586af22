"""What the emulated device does with each message of our dialect: two tables of functions.

`HANDLERS` maps a MAVLink message id to the function that handles it; `COMMANDS` maps a
MAV_CMD of COMMAND_LONG / COMMAND_INT to the function that carries it out (any other command:
MAV_RESULT_UNSUPPORTED). Every function takes the device (`hil.device.Device`: its state, its
drives, its replies) and the message, and returns the messages to send back; `Device.receive`
looks the function up, calls it, and drops and counts a message whose handling raises. What each
message does is the module doc of hil.device; the mode moves only through `Device.fire`
(hil.operating_mode).
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from hil import mavlink_stewart as ms
from hil import params
from hil.device_state import DeviceView
from hil.operating_mode import Event, Mode
from hil.pose_setpoint import leg_setpoint
from hil.setpoint import check_setpoint, flagged

Handler = Callable[[DeviceView, Any], list[Any]]
Command = Callable[[DeviceView, Any], tuple[int, list[Any]]]


def on_setpoint(dev: DeviceView, msg: Any) -> list[Any]:
    """LEG_SETPOINT: refused (counted, one STATUSTEXT per STATUS_REPEAT), ignored while
    disarmed, else followed (HOLD: the lengths now)."""
    return follow(dev, msg, dev.state.last_pose)


def on_pose_setpoint(dev: DeviceView, msg: Any) -> list[Any]:
    """POSE_SETPOINT: its own checks (hil.pose_setpoint), then the LEG_SETPOINT of its leg
    lengths (and rates) checked and followed as any other (forward kinematics starts at its
    pose)."""
    why, leg, pose = leg_setpoint(msg, dev.model, dev.capability.setpoint_rate,
                                  dev.settings.cond_max)
    if why is not None:
        return refuse(dev, why)
    return follow(dev, leg, dev.state.last_pose if pose is None else pose)


def refuse(dev: DeviceView, why: str) -> list[Any]:
    """A refused setpoint: counted, one STATUSTEXT per STATUS_REPEAT."""
    dev.counters.setpoints_refused += 1
    return dev.say_once(ms.MAV_SEVERITY_WARNING, f"refused: {why}", key="refused")


def follow(dev: DeviceView, msg: Any, guess: np.ndarray) -> list[Any]:
    """A LEG_SETPOINT checked (forward kinematics from `guess`): refused, ignored while
    disarmed, else followed (HOLD: the lengths now)."""
    flags = msg.flags
    hold = bool(flags & ms.STEWART_SETPOINT_FLAG_HOLD)
    why, pose = (None, None) if hold else check_setpoint(
        msg, flags, dev.capability, dev.model, guess, dev.settings.cond_max)
    if why is not None:
        return refuse(dev, why)
    state = dev.state
    was = state.mode
    why = dev.fire(Event.SETPOINT)
    if why is not None:
        dev.counters.setpoints_ignored += 1
        if state.ignored_said:
            return []
        state.ignored_said = True
        return dev.statustext(ms.MAV_SEVERITY_WARNING, why)
    dev.counters.setpoints_accepted += 1
    out = []
    if was is Mode.TRIPPED:
        out = dev.statustext(ms.MAV_SEVERITY_NOTICE, "watchdog: setpoints resumed")
    state.last_setpoint_k = dev.k
    state.last_setpoint_wall = dev.clock() if dev.clock is not None else 0.0
    state.setpoint_sequence = msg.sequence
    if hold:
        dev.servo.hold()
        return out
    state.last_pose = pose
    force = flagged(flags, ms.STEWART_SETPOINT_FLAG_FORCE_VALID, msg.force)
    dev.servo.follow(np.array(msg.length, dtype=float),
                     flagged(flags, ms.STEWART_SETPOINT_FLAG_RATE_VALID, msg.rate), pose, force,
                     None if force is None else
                     flagged(flags, ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID, msg.force_rate))
    return out


def on_command(dev: DeviceView, msg: Any) -> list[Any]:
    """COMMAND_LONG / COMMAND_INT: COMMAND_ACK, then what the command says (COMMANDS)."""
    if not for_me(dev, msg):
        return []
    dev.counters.commands += 1
    cmd = msg.command
    run = COMMANDS.get(cmd)
    result, out = (ms.MAV_RESULT_UNSUPPORTED, []) if run is None else run(dev, msg)
    if result != ms.MAV_RESULT_ACCEPTED:
        dev.counters.commands_refused += 1
    ack = ms.MAVLink_command_ack_message(cmd, result, 0, 0, msg.get_srcSystem(),
                                         msg.get_srcComponent())
    return [ack] + out


def arm_disarm(dev: DeviceView, msg: Any) -> tuple[int, list[Any]]:
    """ARM (param1 1: hold the lengths now; "armed" and HOME_POSITION when it was
    disarmed), DISARM (param1 0: hold; "disarmed: holding" when it was armed)."""
    param1 = msg.param1
    was_armed = dev.armed
    if param1 == 1.0:
        dev.fire(Event.ARM)
        dev.servo.hold()
        out = [] if was_armed else (dev.statustext(ms.MAV_SEVERITY_INFO, "armed")
                                    + [dev.home_position()])
        return ms.MAV_RESULT_ACCEPTED, out
    if param1 == 0.0:
        dev.fire(Event.DISARM)
        dev.servo.hold()
        out = dev.statustext(ms.MAV_SEVERITY_INFO, "disarmed: holding") if was_armed else []
        return ms.MAV_RESULT_ACCEPTED, out
    return ms.MAV_RESULT_DENIED, dev.say_once(
        ms.MAV_SEVERITY_WARNING, f"arm/disarm param1 {param1:.3g} refused: must be 0 or 1",
        key="arm-denied")


def go_home(dev: DeviceView, msg: Any) -> tuple[int, list[Any]]:
    """RETURN_TO_LAUNCH: a quintic in leg space to the scene's home lengths, then hold."""
    why = dev.fire(Event.HOME)
    if why is not None:
        return ms.MAV_RESULT_TEMPORARILY_REJECTED, dev.statustext(ms.MAV_SEVERITY_WARNING, why)
    stroke = (dev.leg_max - dev.leg_min) if math.isfinite(dev.leg_max) else 1.0
    dev.servo.start_homing(dev.home_lengths, dev.k, dev.rate, stroke)
    return ms.MAV_RESULT_ACCEPTED, dev.statustext(ms.MAV_SEVERITY_INFO, "homing")


def send_home(dev: DeviceView, msg: Any) -> tuple[int, list[Any]]:
    """GET_HOME_POSITION: HOME_POSITION after the ack."""
    return ms.MAV_RESULT_ACCEPTED, [dev.home_position()]


def request_message(dev: DeviceView, msg: Any) -> tuple[int, list[Any]]:
    """REQUEST_MESSAGE: of HOME_POSITION as GET_HOME_POSITION; of anything else unsupported."""
    if msg.param1 == ms.MAVLINK_MSG_ID_HOME_POSITION:
        return send_home(dev, msg)
    return ms.MAV_RESULT_UNSUPPORTED, []


def on_param_request_list(dev: DeviceView, msg: Any) -> list[Any]:
    if not for_me(dev, msg):
        return []
    return [params.value_message(dev.params, n) for n in dev.params]


def on_param_request_read(dev: DeviceView, msg: Any) -> list[Any]:
    if not for_me(dev, msg):
        return []
    out, why = params.read(dev.params, msg)
    return out if why is None else dev.statustext(ms.MAV_SEVERITY_WARNING, why)


def on_param_set(dev: DeviceView, msg: Any) -> list[Any]:
    if not for_me(dev, msg):
        return []
    out, why = params.set_from(dev.params, msg)
    if why is None:
        dev.counters.params_set += 1
        return out
    dev.counters.params_refused += 1
    return out + dev.statustext(ms.MAV_SEVERITY_WARNING, why)


def on_lockstep(dev: DeviceView, msg: Any) -> list[Any]:
    """LOCKSTEP(step=k): tick once (k the next step), answer again (k the last one), or refuse."""
    state = dev.state
    if not dev.lockstep:
        dev.counters.lockstep_refused += 1
        return dev.say_once(ms.MAV_SEVERITY_WARNING, "LOCKSTEP ignored: real-time mode")
    k = msg.step
    if k == state.next_step and dev.armed and state.setpoint_sequence != k:
        # Armed, a lockstep step needs its own setpoint (sequence = step): a lost setpoint
        # must not be replaced silently by the previous one. The host resends both.
        dev.counters.lockstep_refused += 1
        return dev.say_once(ms.MAV_SEVERITY_WARNING,
                            f"LOCKSTEP {k} refused: setpoint {k} missing", key="lockstep")
    if k == state.next_step:
        out = dev.tick(step=k)
        state.next_step = k + 1
        state.last_reply = out
        return out
    if k + 1 == state.next_step and state.last_reply is not None:
        dev.counters.lockstep_repeated += 1
        return list(state.last_reply)
    dev.counters.lockstep_refused += 1
    return dev.say_once(ms.MAV_SEVERITY_WARNING,
                        f"LOCKSTEP {k} refused: expected {state.next_step}", key="lockstep")


def for_me(dev: DeviceView, msg: Any) -> bool:
    """Whether a message's target fields name this system and component (or 0, any)."""
    return (msg.target_system in (0, dev.mav.srcSystem)
            and msg.target_component in (0, dev.mav.srcComponent))


#: Message id -> its handler: the one dispatch of the device's input.
HANDLERS: dict[int, Handler] = {
    ms.MAVLINK_MSG_ID_LEG_SETPOINT: on_setpoint,
    ms.MAVLINK_MSG_ID_POSE_SETPOINT: on_pose_setpoint,
    ms.MAVLINK_MSG_ID_COMMAND_LONG: on_command,
    ms.MAVLINK_MSG_ID_COMMAND_INT: on_command,      # the same commands, the same acks
    ms.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: on_param_request_list,
    ms.MAVLINK_MSG_ID_PARAM_REQUEST_READ: on_param_request_read,
    ms.MAVLINK_MSG_ID_PARAM_SET: on_param_set,
    ms.MAVLINK_MSG_ID_LOCKSTEP: on_lockstep,
}

#: MAV_CMD -> what the device does (result, messages after the ack); others: unsupported.
COMMANDS: dict[int, Command] = {
    ms.MAV_CMD_COMPONENT_ARM_DISARM: arm_disarm,
    ms.MAV_CMD_NAV_RETURN_TO_LAUNCH: go_home,
    ms.MAV_CMD_GET_HOME_POSITION: send_home,
    ms.MAV_CMD_REQUEST_MESSAGE: request_message,
}
