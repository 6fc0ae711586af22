"""A GCS move as the device's own input: a quintic in GCS coordinates, sampled each servo tick into
a LEG_SETPOINT (lengths and rates) that goes through `Device.receive` like any host's.

A move runs from the reference now (where the previous path stands; at rest after FRF or a
finished move) to the goal along the minimum-jerk profile of controller.trajectory (every
coordinate on one straight line in X Y Z U V W, the pivot on a straight line). Before it starts
the whole path is checked at PATH_SAMPLES poses: every leg within the device's own setpoint
stroke (Device.capability: the stroke less the servo's overshoot room), cond(J) within
SP_COND_MAX and every limit of the feasibility engine (stewart_fmu.reach) inside, else
GcsError 7 naming the limit (the session keeps it: hil.gcs.controller.Session) and nothing
moves. Its duration is the longest of: the translation
at the system velocity (VLS, mm/s), the rotation at the same number in deg/s, and the legs at
the drive's no-load speed (Device.capability.speed), each with the quintic's
peak rate factor. The leg rates sent are the central difference of the leg lengths along the
path (a step of FD_STEP in the path parameter, times the profile's rate). After the goal the
last setpoint is sent again every quarter of the device's watchdog, so an idle twin holds its
target with the device's watchdog armed. A setpoint the device refuses (it says why over
MAVLink) ends the move: the device is told to HOLD and the move counts as a motion error.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from controller.trajectory import QUINTIC_PEAK_RATE, minimum_jerk
from hil import mavlink_stewart as ms
from hil.device import Device
from hil.gcs import errors as E
from hil.gcs.axes import Frame
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.reach import Engine

PATH_SAMPLES = 129      # poses checked along a path before it starts
FD_STEP = 1e-6          # path-parameter step of the rates' central difference
MIN_MOVE = 0.02         # s, the shortest move
_RATES = ms.STEWART_SETPOINT_FLAG_RATE_VALID


@dataclass(frozen=True)
class Path:
    """A planned move: from `start` to `goal` (GCS, mm and deg) in `n` ticks from tick `k0`,
    along the quintic; a halt (`halt_from`: the path parameter s0 and its rate v0, 1/s, where
    HLT found the move) runs on along the same line from s0 and comes to rest smoothly."""

    start: np.ndarray
    goal: np.ndarray
    k0: int
    n: int
    halt_from: tuple[float, float] | None = None

    def at(self, k: int, rate: float) -> tuple[float, float, bool]:
        """(s, ds/dt, done) at tick k."""
        u = min(1.0, (k - self.k0) / self.n)
        duration = self.n / rate
        if self.halt_from is None:
            s, sd, _ = minimum_jerk(u, duration)
            return s, sd, u >= 1.0
        s0, v0 = self.halt_from
        # the rate falls as v0 (1 - 3u^2 + 2u^3): from v0 to rest, at rest with no acceleration
        return (s0 + v0 * duration * (u - u**3 + 0.5 * u**4),
                v0 * (1.0 - 3.0 * u**2 + 2.0 * u**3), u >= 1.0)


class Mover:
    """The device's setpoints for GCS moves (see the module doc)."""

    def __init__(self, device: Device, frame: Frame) -> None:
        self.device, self.frame = device, frame
        self.model = device.model
        self.engine = Engine(device.model)      # the geometric limits and cond(J)
        self.speed = device.capability.speed    # the drive's no-load speed
        self.reference = np.zeros(6)            # GCS: where the path stands now
        self.path: Path | None = None
        self.held: np.ndarray | None = None     # lengths of the last setpoint (resent)
        self._seq = 0
        self._last_sent = 0
        self.refused = 0                        # moves ended by a refused setpoint

    @property
    def moving(self) -> bool:
        return self.path is not None

    def reset(self, at: np.ndarray) -> None:
        """No move; the reference is `at` (GCS) and nothing is resent (the device holds)."""
        self.path, self.held = None, None
        self.reference = np.asarray(at, dtype=float).copy()

    def check_path(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """The leg lengths (m, (PATH_SAMPLES, 6)) at the poses checked on the straight line from
        `start` to `goal` (GCS); GcsError 7 naming the first limit a pose on the way leaves: the
        device's setpoint stroke or its cond(J) bound, else any limit of the feasibility engine
        (stewart_fmu.reach: the mechanism's stroke, the joints' cones, the legs' clearance, the
        obstacles, its cond(J) limit, as far as the scene has them)."""
        s = np.linspace(0.0, 1.0, PATH_SAMPLES)
        q = self.frame.to_pose(start + (goal - start) * s[:, None])
        kin = inverse_kinematics(self.model, q)
        b = self.device.capability
        lengths = kin.lengths
        if not np.all(np.isfinite(lengths)):
            raise E.GcsError(E.POS_OUT_OF_LIMITS, "a pose on the way is not finite")
        for name, bad in (("below the setpoint stroke", lengths < b.leg_min),
                          ("above the setpoint stroke", lengths > b.leg_max)):
            if bad.any():
                leg = int(np.argmax(bad.any(axis=0))) + 1
                raise E.GcsError(E.POS_OUT_OF_LIMITS, f"leg {leg} {name} on the way")
        if not np.all(kin.cond <= self.device.settings.cond_max):
            raise E.GcsError(E.POS_OUT_OF_LIMITS, "cond(J) above SP_COND_MAX on the way")
        binding = self.engine.binding(q)
        if np.any(binding >= 0):
            v = self.engine.verdict(q[int(np.argmax(binding >= 0))])
            raise E.GcsError(E.POS_OUT_OF_LIMITS,
                             f"{v.limit}{' at ' + v.where if v.where else ''} on the way")
        return lengths

    def plan(self, goal: np.ndarray, velocity: float, k: int) -> Path:
        """The move from the reference to `goal` from tick k (GcsError 7 when a pose on the way
        leaves a limit: `check_path`)."""
        start = self.reference.copy()
        d = goal - start
        lengths = self.check_path(start, goal)
        dl_ds = float(np.max(np.abs(np.diff(lengths, axis=0)))) * (PATH_SAMPLES - 1)
        duration = QUINTIC_PEAK_RATE * max(float(np.max(np.abs(d[:3]))) / velocity,
                                           float(np.max(np.abs(d[3:]))) / velocity,
                                           dl_ds / self.speed)
        n = max(1, math.ceil(max(duration, MIN_MOVE) * self.device.rate))
        return Path(start, np.asarray(goal, dtype=float).copy(), k, n)

    def start(self, path: Path) -> None:
        self.path = path

    def halt(self, k: int) -> np.ndarray:
        """HLT: the move running (if any) comes to rest along its own line, its rate falling
        smoothly to 0 in half the move's duration or less, never past the move's goal (so
        within the path checked when it started); the pose (GCS) where it will rest."""
        p = self.path
        if p is None:
            return self.reference.copy()
        if p.halt_from is not None:                # halting already: where that one rests
            s_end, _, _ = p.at(p.k0 + p.n, self.device.rate)
            return p.start + (p.goal - p.start) * s_end
        s0, v0, done = p.at(k, self.device.rate)
        if done or v0 <= 0.0:
            return p.start + (p.goal - p.start) * s0
        duration = min(0.5 * p.n / self.device.rate, 2.0 * (1.0 - s0) / v0)
        n = max(1, math.ceil(duration * self.device.rate))
        duration = n / self.device.rate
        if s0 + 0.5 * v0 * duration > 1.0:       # rounding n up: keep the end on the path
            v0 = 2.0 * (1.0 - s0) / duration
        self.path = Path(p.start, p.goal, k, n, (s0, v0))
        return p.start + (p.goal - p.start) * (s0 + 0.5 * v0 * duration)

    def hold_here(self, lengths: np.ndarray, at: np.ndarray) -> list[Any]:
        """Stop: the setpoint is `lengths` (measured now), the reference `at` (GCS)."""
        self.path = None
        self.reference = np.asarray(at, dtype=float).copy()
        return self._send(np.asarray(lengths, dtype=float), np.zeros(6))

    def step(self, k: int) -> list[Any]:
        """The setpoint for tick k (a move's sample, or the held one when it is due)."""
        p = self.path
        if p is None:
            due = max(1, int(self.device.watchdog * self.device.rate / 4))
            if self.held is not None and self.device.k - self._last_sent >= due:
                return self._send(self.held, np.zeros(6))
            return []
        s, sd, done = p.at(k, self.device.rate)
        d = p.goal - p.start
        # the pose and its two neighbours of the rates' central difference, in one go
        around = p.start + d * (s + np.array([0.0, FD_STEP, -FD_STEP]))[:, None]
        lengths = self.lengths(around)
        rates = np.zeros(6) if done else (lengths[1] - lengths[2]) * (sd / (2 * FD_STEP))
        if done:
            self.path = None
        self.reference = around[0]
        return self._send(lengths[0], rates)

    def lengths(self, g: np.ndarray) -> np.ndarray:
        """The leg lengths (m, (N, 6)) at GCS coordinates g (N, 6): |x + R p_i - a_i|."""
        x, r = self.frame.placements(g)
        legs = x[:, None, :] + np.einsum("nij,kj->nki", r, self.model.platform_joints) \
            - self.model.base_joints[None]
        return np.sqrt(np.sum(legs ** 2, axis=2))

    def _send(self, lengths: np.ndarray, rates: np.ndarray) -> list[Any]:
        dev = self.device
        refused = dev.counters.setpoints_refused
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        msg = ms.MAVLink_leg_setpoint_message(round(dev.time * 1e6), self._seq,
                                              lengths.tolist(), rates.tolist(), _RATES)
        out = dev.receive(msg)
        self._last_sent = dev.k
        if dev.counters.setpoints_refused != refused:
            self.refused += 1
            self.path, self.held = None, None
            hold = ms.MAVLink_leg_setpoint_message(round(dev.time * 1e6), self._seq, [0.0] * 6,
                                                   [0.0] * 6, ms.STEWART_SETPOINT_FLAG_HOLD)
            return out + dev.receive(hold)
        self.held = np.array(lengths, dtype=float)
        return out
