"""What a tick of the device does when the watchdog expires, the plant refuses a step, or a
number fails: hold, move the mode (hil.operating_mode), say so once. The device never exits on numbers.

Every function takes the device (`hil.device.Device`) and returns the STATUSTEXT to send.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil import params
from hil.device_state import DeviceView
from hil.operating_mode import Event


def watchdog_expired(dev: DeviceView) -> bool:
    """`watchdog` s without a valid setpoint: by the wall clock when served in real time
    (`clock` set: catching up after a stall must not trip it early), else by device time."""
    watchdog = dev.settings.watchdog
    if dev.clock is not None:
        return dev.clock() - dev.state.last_setpoint_wall >= watchdog
    return (dev.k - dev.state.last_setpoint_k) * dev.dt >= watchdog - 1e-9 * dev.dt


def watchdog_trip(dev: DeviceView) -> list[Any]:
    """The watchdog expired while tracking: hold the lengths measured now, one CRITICAL text."""
    dev.fire(Event.WATCHDOG_EXPIRED)
    dev.servo.hold()
    dev.counters.watchdog_trips += 1
    return dev.statustext(ms.MAV_SEVERITY_CRITICAL,
                          f"watchdog: no setpoint for {dev.settings.watchdog:g} s: holding")


def plant_fault(dev: DeviceView, why: str) -> list[Any]:
    """The plant refused the step: stop at rest where it is, drives holding; disarm."""
    dev.counters.faults += 1
    dev.servo.start_holding(dev.plant.outputs.q, dev.plant.time)
    dev.fire(Event.FAULT)
    dev.servo.hold()
    return dev.statustext(ms.MAV_SEVERITY_CRITICAL, f"fault, stopped and disarmed: {why}")


def numeric_fault(dev: DeviceView, good_q: np.ndarray, exc: BaseException) -> list[Any]:
    """A numerical failure in the loop: restart the plant at rest at the last good pose,
    drives holding it with the designed gains and the motor's rated limits, disarm, one
    CRITICAL STATUSTEXT (in chunks) that names every gain and limit restored with its value
    before and after (hil.params.restored_text); the device keeps serving."""
    dev.counters.numeric_faults += 1
    before = {n: dev.params[n].get() for n in params.DESIGN_PARAMS}
    dev.servo.restore_design()
    restored = params.restored_text(before, dev.params)
    dev.servo.restart_after_failure(good_q, dev.state.last_pose, dev.k * dev.dt)
    dev.fire(Event.FAULT)
    dev.servo.hold()
    dev.servo.idle()
    dev.last_fault = f"{type(exc).__name__}: {exc}; {restored}"
    # the first chunk (50 bytes) says what happened, the rest which values now hold
    return dev.say_once(ms.MAV_SEVERITY_CRITICAL,
                        f"numeric fault ({type(exc).__name__})"[:34] + ": hold, disarmed"
                        + f"; {restored}", key="numeric-fault")
