"""Warm the device's paths before it says it is ready (hil.spawn prints its ready line after).

A throwaway `Device` of the same model and controller runs every path a real-time run takes:
decode of each input message the host sends (through `Device.feed`, CRC and all), arm, valid
and refused setpoints with rates and forces, ticks with every telemetry stream (ATTITUDE,
HOME_POSITION...), packing, parameters, homing, the watchdog and disarm. The C core is loaded
and its first calls made, numpy's and pymavlink's first-call caches filled, so the first
setpoint and the first ticks of the served device cost what every later one does. The served
device's own state is not touched.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from controller.config import ControllerConfig
from hil import mavlink_stewart as ms
from hil.device import Device
from hil.framing import pack
from hil.sensors import SensorConfig
from stewart_fmu.model import Model

TICKS = 300   # enough for every stream (the slowest, SYS_STATUS and HEARTBEAT, at tick 1)


def _frames(host: Any, *msgs: Any) -> bytes:
    return b"".join(pack(host, m) for m in msgs)


def warm_up(model: Model, config: ControllerConfig, ticks: int = TICKS, *,
            truth: Model | None = None, sensors: SensorConfig | None = None) -> float:
    """Run the paths on a throwaway device (the served one's truth and sensors); the seconds
    it took."""
    t0 = time.perf_counter()
    dev = Device(model, config, watchdog=0.05, truth=truth, sensors=sensors)
    host = ms.MAVLink(None, srcSystem=255, srcComponent=190)
    l0 = dev.plant.outputs.lengths.copy()
    flags = (ms.STEWART_SETPOINT_FLAG_RATE_VALID | ms.STEWART_SETPOINT_FLAG_FORCE_VALID
             | ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID)

    def command(cmd: int, p1: float = 0.0) -> Any:
        return ms.MAVLink_command_long_message(1, 1, cmd, 0, p1, 0, 0, 0, 0, 0, 0)

    def setpoint(k: int, l: np.ndarray) -> Any:
        return ms.MAVLink_leg_setpoint_message(k * 1000, k, l.tolist(), [0.0] * 6, flags,
                                               [1.0] * 6, [0.0] * 6)

    out: list[Any] = []
    out += dev.feed(_frames(host, ms.MAVLink_param_request_list_message(1, 1),
                            ms.MAVLink_param_request_read_message(1, 1, b"SR_LEG_STATE", -1),
                            ms.MAVLink_param_set_message(1, 1, b"SR_LEG_STATE", 100.0,
                                                         ms.MAV_PARAM_TYPE_REAL32),
                            command(ms.MAV_CMD_GET_HOME_POSITION),
                            command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)))
    for k in range(ticks):
        l = l0 + 1e-5 * np.sin(k / 50.0)
        out += dev.feed(_frames(host, setpoint(k, l)))
        if k == ticks // 2:
            out += dev.feed(_frames(host, setpoint(k, l0 + 1.0)))          # refused
            out += dev.feed(_frames(host, command(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH)))
        out += dev.tick()
    for _ in range(60):                     # the watchdog trips, then holds
        out += dev.tick()
    out += dev.feed(_frames(host, command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0.0)))
    out += dev.flush()
    for m in out:
        dev.pack(m)
    return time.perf_counter() - t0
