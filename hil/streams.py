"""The device's telemetry streams: which messages a tick sends, and what each holds of its state.

Every function takes the device (`hil.device.Device`) and builds its messages with hil.downlink
(the wire format and the NED/FRD mapping): the legs as the sensors report them (hil.sensors),
the pose and drives as the plant and servo hold them. `Device` offers each builder as a method
of the same name (`dev.heartbeat()`, ...).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from hil import downlink
from hil import mavlink_stewart as ms
from hil.device_state import DeviceView


def usec(dev: DeviceView) -> int:
    """Device time in microseconds (time_usec)."""
    return int(round(dev.k * 1e6 / dev.rate))


def time_ms(dev: DeviceView) -> int:
    """Device time in milliseconds, wrapped at 32 bits (time_boot_ms)."""
    return int(dev.k * 1000 // dev.rate) & 0xFFFFFFFF


def due_messages(dev: DeviceView, step: int | None) -> list[Any]:
    """The telemetry due on the tick just made (stream rates: dev.rates); in lockstep (`step`
    given) one LEG_STATE with that step and LOCKSTEP(step) echoed."""
    k, rate, r = dev.k, dev.rate, dev.settings.rates
    out = []
    if downlink.due(k, rate, downlink.HEARTBEAT_HZ):
        out.append(heartbeat(dev))
    if downlink.due(k, rate, r["SYS_STATUS"]):
        out.append(sys_status(dev))
    if downlink.due(k, rate, r["ATTITUDE_QUATERNION"]):
        o = dev.plant.outputs
        out += [downlink.attitude(time_ms(dev), o.q, o.twist),
                downlink.attitude_euler(time_ms(dev), o.q, o.twist)]
    if downlink.due(k, rate, r["LOCAL_POSITION_NED"]):
        out.append(local_position(dev))
    if downlink.due(k, rate, r["DRIVE_STATUS"]):
        out.append(drive_status(dev))
    if step is not None:
        out += [leg_state(dev, step), ms.MAVLink_lockstep_message(usec(dev), step)]
    elif downlink.due(k, rate, r["LEG_STATE"]):
        out.append(leg_state(dev, 0))
    return out


def heartbeat(dev: DeviceView) -> Any:
    return downlink.heartbeat(dev.mode, dev.lockstep)


def sys_status(dev: DeviceView) -> Any:
    c = dev.counters
    return downlink.sys_status(dev.mode, dev.load, dev.link_errors, c.setpoints_refused,
                               c.signing_rejected, c.watchdog_trips, c.faults)


def leg_state(dev: DeviceView, step: int = 0) -> Any:
    """LEG_STATE: the legs as the sensors report them (hil.sensors)."""
    m = dev.sensors
    if m is not None:
        return downlink.leg_state(usec(dev), m.lengths, m.rates, m.force, step)
    o = dev.plant.outputs
    return downlink.leg_state(usec(dev), o.lengths, o.rates, dev.plant.rack_force, step)


def drive_status(dev: DeviceView) -> Any:
    s = dev.servo
    current = s.motors.current if dev.sensors is None else dev.sensors.current
    return downlink.drive_status(usec(dev), dev.mode, s.voltage, current,
                                 s.saturated, dev.counters.setpoints_refused,
                                 dev.rx.stats.crc_errors + dev.counters.signing_rejected)


def home_position(dev: DeviceView) -> Any:
    """HOME_POSITION: the scene's home in LOCAL_POSITION_NED's convention (hil.protocol)."""
    return downlink.home_position(np.asarray(dev.model.home, dtype=float), usec(dev))


def local_position(dev: DeviceView) -> Any:
    o = dev.plant.outputs
    return downlink.local_position(time_ms(dev), o.q, o.qd)
