"""What the emulated device sends: its MAVLink telemetry messages, built from plain values
(hil.streams takes them from the device's state), and the NED/FRD mapping.

HEARTBEAT at 1 Hz (MAV_TYPE_GENERIC, MAV_AUTOPILOT_GENERIC; base mode SAFETY_ARMED while armed,
custom mode 1 in lockstep; system status STANDBY, ACTIVE, or CRITICAL while the watchdog has
tripped); SYS_STATUS, LEG_STATE, DRIVE_STATUS, ATTITUDE_QUATERNION (with ATTITUDE beside it)
and LOCAL_POSITION_NED at the rates of TELEMETRY (Hz, 0 = off; also the parameters SR_* of
hil.params), all starting at the first tick (`due`).

Our frame N is z up; MAVLink's is NED. We map N to NED by a half turn about x: north = x,
east = -y, down = -z, and the platform frame to FRD the same way. So LOCAL_POSITION_NED is
(x, -y, -z) and its rates likewise, and the attitude quaternion of R = Rz(thz) Ry(thy) Rx(thx)
(w, x, y, z) becomes (w, x, -y, -z), i.e. roll = thx, pitch = -thy, yaw = -thz; body rates are
R^T omega with y and z negated.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil import mavlink_stewart as ms
from hil import protocol
from hil.operating_mode import WATCHDOG_STATE, Mode, armed
from stewart_fmu.rotations import euler_motion

#: Default telemetry rates (Hz); HEARTBEAT is always 1 Hz.
TELEMETRY = {"SYS_STATUS": 1.0, "LEG_STATE": 100.0, "DRIVE_STATUS": 10.0,
             "ATTITUDE_QUATERNION": 50.0, "LOCAL_POSITION_NED": 50.0}
HEARTBEAT_HZ = 1.0
CUSTOM_MODE_REALTIME, CUSTOM_MODE_LOCKSTEP = 0, 1
_CONTROL_SENSORS = (ms.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | ms.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
_U16, _U32 = 0xFFFF, 0xFFFFFFFF


def due(k: int, rate: float, hz: float) -> bool:
    """Whether a stream at `hz` goes out on the tick that made k ticks (the first tick on)."""
    if hz <= 0:
        return False
    period = max(1, round(rate / hz))
    return (k - 1) % period == 0


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


def heartbeat(mode: Mode, lockstep: bool) -> Any:
    base = ms.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (ms.MAV_MODE_FLAG_SAFETY_ARMED if armed(mode) else 0)
    if mode is Mode.TRIPPED:
        state = ms.MAV_STATE_CRITICAL
    else:
        state = ms.MAV_STATE_ACTIVE if armed(mode) else ms.MAV_STATE_STANDBY
    custom = CUSTOM_MODE_LOCKSTEP if lockstep else CUSTOM_MODE_REALTIME
    return ms.MAVLink_heartbeat_message(ms.MAV_TYPE_GENERIC, ms.MAV_AUTOPILOT_GENERIC, base,
                                        custom, state, 3)


def sys_status(mode: Mode, load: int, link_errors: int, refused: int, signing_rejected: int,
               watchdog_trips: int, faults: int) -> Any:
    """SYS_STATUS; the control sensors are unhealthy while the watchdog has tripped; the counts
    go out in the fields errors_comm and errors_count1..4, saturated at 16 bits."""
    health = _CONTROL_SENSORS
    if mode is Mode.TRIPPED:
        health &= ~(ms.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                    | ms.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
    return ms.MAVLink_sys_status_message(
        _CONTROL_SENSORS, _CONTROL_SENSORS if armed(mode) else 0, health,
        min(int(load), 1000), _U16, -1, -1, 0, min(link_errors, _U16),
        min(refused, _U16), min(signing_rejected, _U16), min(watchdog_trips, _U16),
        min(faults, _U16))


def leg_state(usec: int, lengths: np.ndarray, rates: np.ndarray, rack_force: np.ndarray,
              step: int = 0) -> Any:
    return ms.MAVLink_leg_state_message(usec, lengths.tolist(), rates.tolist(),
                                        rack_force.tolist(), step & _U32)


def drive_status(usec: int, mode: Mode, voltage: np.ndarray, current: np.ndarray,
                 saturated: np.ndarray, refused: int, crc_errors: int) -> Any:
    bits = sum(1 << i for i in range(6) if saturated[i])
    return ms.MAVLink_drive_status_message(usec, voltage.tolist(), current.tolist(), bits,
                                           WATCHDOG_STATE[mode], min(refused, _U32),
                                           min(crc_errors, _U32))


def attitude(time_ms: int, q: np.ndarray, twist: np.ndarray) -> Any:
    """ATTITUDE_QUATERNION of pose q with twist (xd, yd, zd, omega) in NED/FRD."""
    w, x, y, z = ned_attitude(q)
    body = rotation(q).T @ twist[3:]
    return ms.MAVLink_attitude_quaternion_message(time_ms, w, x, y, z, float(body[0]),
                                                  float(-body[1]), float(-body[2]))


def attitude_euler(time_ms: int, q: np.ndarray, twist: np.ndarray) -> Any:
    """ATTITUDE (roll, pitch, yaw and body rates in NED/FRD), beside ATTITUDE_QUATERNION."""
    a = attitude(time_ms, q, twist)
    roll, pitch, yaw = protocol.attitude_euler(q)
    return ms.MAVLink_attitude_message(a.time_boot_ms, roll, pitch, yaw, a.rollspeed,
                                       a.pitchspeed, a.yawspeed)


def local_position(time_ms: int, q: np.ndarray, qd: np.ndarray) -> Any:
    return ms.MAVLink_local_position_ned_message(time_ms, float(q[0]), float(-q[1]), float(-q[2]),
                                                 float(qd[0]), float(-qd[1]), float(-qd[2]))


def home_position(home: np.ndarray, usec: int) -> Any:
    """HOME_POSITION: the scene's home in LOCAL_POSITION_NED's convention (hil.protocol)."""
    return protocol.home_position(home, ned_attitude(home), usec)
