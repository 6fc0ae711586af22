"""Synthesise the example vehicle motions shipped in scenes/motions/ (the format of
stewart_sim/cueing/motion.py: t,fx,fy,fz,wx,wy,wz, vehicle frame x forward, y left, z up).

Each motion is built kinematically: an acceleration profile of the vehicle's path (smooth
steps are the project's quintic, controller.trajectory.quintic_step), the body's attitude
(suspension pitch and roll as damped second-order responses to the acceleration, or the
aircraft's commanded pitch), and from both the specific force the occupant feels,

    f = R^T (a - g),   g = (0, 0, -9.81) m/s^2,

with R the body's attitude, and the body's angular velocity in the body frame. 100 Hz.

    python tools/vehicle_motions.py     # rewrites scenes/motions/*.csv
tests/app/test_cueing_motion.py regenerates them and checks the shipped files match.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy import signal

from controller.trajectory import quintic_step
from stewart_sim.cueing.motion import VehicleMotion, write_motion

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "scenes" / "motions"
G = 9.81      # m/s^2
RATE = 100.0  # Hz


def braking_car() -> VehicleMotion:
    """A car at 80 km/h brakes at 0.8 g to a standstill: 3 s cruising, the deceleration builds
    up in 0.3 s (brake pressure), holds until the car stops, falls away in 0.15 s at the stop;
    the body dives (pitch gradient 2 deg/g, pitch mode 1.5 Hz, damping ratio 0.3) and rocks
    back after the stop; 12 s in all. Level road, heave of the body neglected."""
    t = _times(12.0)
    v0, decel, t0, t_on, t_off = 80 / 3.6, 0.8 * G, 3.0, 0.3, 0.15
    hold = v0 / decel - (t_on + t_off) / 2   # the area under the deceleration is v0
    ax = -decel * (quintic_step(t, t0, t_on)[0] - quintic_step(t, t0 + t_on + hold, t_off)[0])
    pitch, pitch_rate = _second_order(t, np.radians(2.0) * -ax / G, 1.5, 0.3)  # nose down > 0
    s_n = np.column_stack([ax, np.zeros_like(t), np.full_like(t, G)])
    f = np.einsum("nji,nj->ni", _ry(pitch), s_n)
    w = np.column_stack([np.zeros_like(t), pitch_rate, np.zeros_like(t)])
    return VehicleMotion(t, f, w)


def lane_change() -> VehicleMotion:
    """A double lane change at 72 km/h: 3.5 m to the left and back, each a full sine period of
    lateral acceleration of amplitude 0.4 g (period sqrt(2 pi 3.5 m / 0.4 g) = 2.37 s), 1.5 s
    in the left lane between them; yaw rate a_y / v (no sideslip); the body rolls out of the
    turn (roll gradient 5 deg/g, roll mode 1.5 Hz, damping ratio 0.5). 12 s in all."""
    t = _times(12.0)
    v, amp, offset, t1, gap = 20.0, 0.4 * G, 3.5, 2.0, 1.5
    period = np.sqrt(2 * np.pi * offset / amp)
    t2 = t1 + period + gap
    ay = amp * (_sine_pulse(t, t1, period) - _sine_pulse(t, t2, period))
    yaw_rate = ay / v
    roll, roll_rate = _second_order(t, np.radians(5.0) * ay / G, 1.5, 0.5)  # left side up > 0
    s_n = np.column_stack([np.zeros_like(t), ay, np.full_like(t, G)])  # in the heading frame
    f = np.einsum("nji,nj->ni", _rx(roll), s_n)
    # R = Rz(yaw) Rx(roll): w_body = Rx^T (0, 0, yaw rate) + (roll rate, 0, 0)
    w = np.column_stack([roll_rate, np.sin(roll) * yaw_rate, np.cos(roll) * yaw_rate])
    return VehicleMotion(t, f, w)


def takeoff() -> VehicleMotion:
    """An airliner's take-off: 2 s on the brakes, thrust up in 3 s to 0.3 g, falling to 0.25 g
    at rotation (drag and thrust lapse); runway bumps (vertical 1.3, 2.7, 4.1 Hz of 0.25,
    0.15, 0.10 m/s^2, growing with speed); rotation at t = 32 s at 3 deg/s (0.5 s ramps) to
    10 deg nose up, lift-off 2.5 s into it; the flight path then bends up to a 6 deg climb in
    8 s (load factor up to ~1.2 g) while the acceleration along the path falls to 0.05 g.
    45 s in all. Vertical plane: the pitch is the nose-up angle about the body's -y axis."""
    t = _times(45.0)
    t_thrust, t_rot, rot_time, rot_ramp = 2.0, 32.0, 10.0 / 3.0, 0.5
    t_lof = t_rot + 2.5
    roll_accel = (0.3 * G * quintic_step(t, t_thrust, 3.0)[0]
                  - 0.05 * G * quintic_step(t, t_thrust + 3.0, t_rot - t_thrust - 3.0)[0])
    accel = roll_accel - (roll_accel[_index(t, t_lof)] - 0.05 * G) * quintic_step(t, t_lof, 3.0)[0]
    speed = np.r_[0.0, np.cumsum((accel[1:] + accel[:-1]) / 2 * np.diff(t))]
    gamma_s, gamma_sd, _ = quintic_step(t, t_lof, 8.0)
    gamma, gamma_rate = np.radians(6.0) * gamma_s, np.radians(6.0) * gamma_sd
    # Pitch rate: 3 deg/s with 0.5 s quintic ramps; its area is 3 deg/s x rot_time = 10 deg.
    rate = np.radians(3.0) * (quintic_step(t, t_rot, rot_ramp)[0]
                              - quintic_step(t, t_rot + rot_time, rot_ramp)[0])
    pitch = np.r_[0.0, np.cumsum((rate[1:] + rate[:-1]) / 2 * np.diff(t))]
    on_ground = 1.0 - quintic_step(t, t_lof, 0.5)[0]
    phases = (0.0, 1.1, 2.3)
    bumps = sum(a * np.sin(2 * np.pi * fr * t + ph)
                for a, fr, ph in zip((0.25, 0.15, 0.10), (1.3, 2.7, 4.1), phases))
    bumps = bumps * speed / speed[_index(t, t_rot)] * on_ground
    ax_n = accel * np.cos(gamma) - speed * gamma_rate * np.sin(gamma)
    az_n = accel * np.sin(gamma) + speed * gamma_rate * np.cos(gamma) + bumps
    s_n = np.column_stack([ax_n, np.zeros_like(t), az_n + G])
    f = np.einsum("nji,nj->ni", _ry(-pitch), s_n)
    # Nose up is a rotation about -y (0.0 - rate: no negative zeros in the file).
    w = np.column_stack([np.zeros_like(t), 0.0 - rate, np.zeros_like(t)])
    return VehicleMotion(t, f, w)


MOTIONS = {"braking_car": braking_car, "lane_change": lane_change, "takeoff": takeoff}


def _times(duration: float) -> np.ndarray:
    return np.arange(round(duration * RATE) + 1) / RATE


def _index(t: np.ndarray, at: float) -> int:
    return int(np.searchsorted(t, at))


def _sine_pulse(t: np.ndarray, start: float, period: float) -> np.ndarray:
    """One full period of sin(2 pi (t - start) / period), zero elsewhere."""
    inside = (t >= start) & (t <= start + period)
    return np.where(inside, np.sin(2 * np.pi * (t - start) / period), 0.0)


def _second_order(t: np.ndarray, u: np.ndarray, freq: float, damping: float):
    """y'' + 2 zeta w y' + w^2 y = w^2 u from rest: (y, y')."""
    w = 2 * np.pi * freq
    sys = signal.StateSpace([[0.0, 1.0], [-w * w, -2 * damping * w]], [[0.0], [w * w]],
                            np.eye(2), np.zeros((2, 1)))
    _, y, _ = signal.lsim(sys, u, t)
    return y[:, 0], y[:, 1]


def _ry(angle: np.ndarray) -> np.ndarray:
    """Rotations about y, (N, 3, 3)."""
    c, s, z, o = np.cos(angle), np.sin(angle), np.zeros_like(angle), np.ones_like(angle)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


def _rx(angle: np.ndarray) -> np.ndarray:
    """Rotations about x, (N, 3, 3)."""
    c, s, z, o = np.cos(angle), np.sin(angle), np.zeros_like(angle), np.ones_like(angle)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1),
                     np.stack([z, s, c], -1)], -2)


def main() -> int:
    for name, make in MOTIONS.items():
        print(write_motion(OUT / f"{name}.csv", make()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
