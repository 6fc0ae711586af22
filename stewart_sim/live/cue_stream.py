"""Telemetry samples -> the cue on a fixed grid -> a pose reference at any tick.

The washout is stepped on the nominal telemetry grid t_0 + j h (t_0: the first sample's time
after a start or a reset; h = 1 / the nominal rate), one step per grid point. A sample at a grid
point is stepped with its own values; grid points between two accepted samples take the input
interpolated linearly between them, as the washout's filters take their input (and as
cueing.study.resample does offline). So:
- a sender at the nominal rate on the grid gives one step per sample, the offline `cue` of the
  same samples exactly;
- a gap (lost or superseded samples) is bridged by interpolated steps. The work is bounded by
  design: a tick takes at most MAX_STEPS steps (`push` with a sample, `advance` without); the
  grid points a longer gap leaves are taken by the next ticks (a backlog caught up at MAX_STEPS
  a tick, the reference extrapolating the newest step meanwhile). A sample that comes while a
  backlog remains ends the segment being interpolated: the grid points still before it take
  the input interpolated from the last step's input to it. A sample more than MAX_BACKLOG grid
  points past the last step re-anchors the washout instead: the grid restarts at the sample
  (t_0 = its time) and the washout takes one step on its values, its filters' state carried on
  (the gap is not integrated), counted in `reanchored`. The receiver's time line
  (stewart_sim.live.receiver) keeps a sample's lead over the last one within the clock time
  since it (at most the loss timeout while cueing) and a few AHEAD, so with the default
  settings (0.1 s, 100 Hz) a backlog is rare and a re-anchoring rarer; a longer --loss-timeout
  or a faster --telemetry-rate makes both likelier;
- a sender at another rate is resampled onto the grid (faster: a sample between grid points
  only moves the interpolation's end; slower: several steps per sample).
A sample within GRID_TOLERANCE h of a grid point counts as on it (decimal times in a file are
not the float sums t_0 + j h).

Between cue samples (the device ticks faster than the telemetry) the reference is causal and
C2, on the telemetry's own time: a clock time `now` is telemetry time now - offset, the offset
the lag (arrival clock time less telemetry time) averaged over the samples (each moves it by
OFFSET_GAIN of its difference; the first sets it), so the jitter of arrivals does not enter the
reference and a drifting sender's clock is followed smoothly. Each cue sample j (grid time t_j)
is extrapolated with constant acceleration, forwards or (a sample that came early) backwards,
E_j(s) = (q + qd s + qdd s^2 / 2, qd + qdd s, qdd) at s = (now - offset) - t_j, and over the
period after a new sample arrives the reference blends from the previous sample's
extrapolation to the new one's along the minimum-jerk weight w
(controller.trajectory.minimum_jerk, 0 to 1 over h):
ref = E_(j-1) + w (E_j - E_(j-1)), its derivatives by the product rule. So no new sample makes
the pose, its rate or its acceleration jump (the safety envelope passes a smooth cue unchanged,
and a jump would be an intervention), and nothing waits for a later sample (no added latency).
Its error against the cue at the samples is the extrapolation's, of order jerk h^3; right after
a step of the vehicle's input, of order the step of qdd times h^2. A sample is extrapolated over
at most max(EXTRAPOLATION h, EXTRAPOLATION_MIN) either way; beyond that the reference holds that
end state (a late sender: the loss timeout fades the platform home soon after).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from controller.trajectory import minimum_jerk
from stewart_sim.live.vehicle_datagrams import TelemetrySample

GRID_TOLERANCE = 1e-6   # of h: a sample this close to a grid point is on it
MAX_STEPS = 10          # washout steps a tick may take (the default loss timeout at 100 Hz)
MAX_BACKLOG = 100       # grid points a sample may lie past the last step (further: re-anchor)
EXTRAPOLATION = 5       # periods h a cue sample is extrapolated over at most ...
EXTRAPOLATION_MIN = 0.02   # ... or this many s, whichever is longer
OFFSET_GAIN = 0.01      # of a sample's lag difference that moves the clock offset


class Stepper(Protocol):
    """A causal washout at a fixed period: one step per vehicle sample (the classical
    cueing.washout_step.WashoutStepper)."""

    def step(self, specific_force, angular_velocity): ...

    def reset(self) -> None: ...


@dataclass(frozen=True)
class Reference:
    """A pose reference (the contract's pose coordinates) and its two derivatives."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


class CueStream:
    """The washout on the telemetry grid (see the module doc)."""

    mode = "classical"

    def __init__(self, stepper: Stepper, h: float, home: np.ndarray) -> None:
        self.stepper = stepper
        self.h = float(h)
        self.home = np.asarray(home, float)
        self.steps = 0                 # washout steps since the start (all resets)
        self.interpolated = 0          # of them on input interpolated over a gap or resampled
        self.reanchored = 0            # samples past MAX_BACKLOG grid points: the grid restarted
        self.reset()

    def reset(self) -> None:
        """Back to rest at home; the next sample starts a new grid."""
        self.stepper.reset()
        self._last: TelemetrySample | None = None
        self._from: tuple = ()         # (t, f, w): where the segment to _last starts
        self._input: tuple = ()        # (t, f, w): the newest step's grid time and input
        self._j = 0                    # the grid index of the newest step
        self._t0 = math.nan
        self.cue: Reference | None = None
        self.cue_time = math.nan       # the newest cue sample's grid time (telemetry time)
        self.previous: Reference | None = None     # the sample before it, and its time
        self.previous_time = math.nan
        self.arrived = math.nan        # the clock time the newest sample arrived
        self.offset = math.nan         # clock time less telemetry time (see the module doc)

    @property
    def started(self) -> bool:
        return self._last is not None

    def push(self, s: TelemetrySample, now: float) -> int:
        """Step the washout over the grid points up to the sample `s` (accepted at clock time
        `now`), at most MAX_STEPS of them (the rest: `advance`); returns the steps taken (0: the
        sample lies before the next grid point)."""
        lag = now - s.t
        self.offset = lag if self._last is None else self.offset + OFFSET_GAIN * (lag - self.offset)
        if self._last is None:
            self._t0, self._j = s.t, -1
            self._from = (s.t, s.specific_force, s.angular_velocity)
        elif (s.t + GRID_TOLERANCE * self.h - self._t0) / self.h - self._j >= MAX_BACKLOG + 1:
            self._t0, self._j = s.t, -1           # re-anchored: the next grid point is s.t
            self._from = (s.t, s.specific_force, s.angular_velocity)
            self.reanchored += 1
        elif self.behind:                         # a backlog: on from the newest step's input
            self._from = self._input
        else:
            a = self._last
            self._from = (a.t, a.specific_force, a.angular_velocity)
        self._last = s
        return self.advance(now)

    @property
    def behind(self) -> bool:
        """Whether grid points up to the newest sample are still to be stepped."""
        return (self._last is not None
                and self._t0 + (self._j + 1) * self.h <= self._last.t + GRID_TOLERANCE * self.h)

    def advance(self, now: float) -> int:
        """Step the washout over the grid points still before the newest sample, at most
        MAX_STEPS (called every tick; 0 when there are none)."""
        if not self.behind:
            return 0
        # the blend of `reference` starts from the newest step before these
        self.previous, self.previous_time = self.cue, self.cue_time
        (ta, fa, wa), s, taken = self._from, self._last, 0
        tol = GRID_TOLERANCE * self.h
        while taken < MAX_STEPS:
            tg = self._t0 + (self._j + 1) * self.h
            if tg > s.t + tol:
                break
            if abs(tg - s.t) <= tol:
                f, w = s.specific_force, s.angular_velocity
            else:
                x = (tg - ta) / (s.t - ta)
                f = tuple(p + x * (r - p) for p, r in zip(fa, s.specific_force))
                w = tuple(p + x * (r - p) for p, r in zip(wa, s.angular_velocity))
                self.interpolated += 1
            self._step(f, w, tg)
            self._input = (tg, f, w)
            self._j += 1
            taken += 1
        self.arrived = now
        return taken

    def _step(self, f, w, t: float) -> None:
        c = self.stepper.step(f, w)
        self.cue = Reference(np.asarray(c.q, float), np.asarray(c.qd, float),
                             np.asarray(c.qdd, float))
        self.cue_time = t
        self.steps += 1

    def extrapolated(self, c: Reference, since: float) -> Reference:
        """E(s): the cue sample c carried on with constant acceleration for `since` s (either
        way, at most max(EXTRAPOLATION h, EXTRAPOLATION_MIN))."""
        most = max(EXTRAPOLATION * self.h, EXTRAPOLATION_MIN)
        dt = min(max(since, -most), most)
        return Reference(c.q + c.qd * dt + 0.5 * c.qdd * dt * dt, c.qd + c.qdd * dt, c.qdd)

    def reference(self, now: float) -> Reference:
        """The pose reference at clock time `now` (home at rest before the first sample)."""
        c = self.cue
        if c is None:
            return Reference(self.home.copy(), np.zeros(6), np.zeros(6))
        t = now - self.offset
        new = self.extrapolated(c, t - self.cue_time)
        since = now - self.arrived
        if self.previous is None or since >= self.h:
            return new
        old = self.extrapolated(self.previous, t - self.previous_time)
        w, wd, wdd = minimum_jerk(max(since, 0.0) / self.h, self.h)
        d = [n - o for n, o in zip((new.q, new.qd, new.qdd), (old.q, old.qd, old.qdd))]
        return Reference(old.q + w * d[0], old.qd + w * d[1] + wd * d[0],
                         old.qdd + w * d[2] + 2.0 * wd * d[1] + wdd * d[0])

    def describe(self) -> str:
        return (f"washout: {self.steps} steps ({self.interpolated} on input interpolated over "
                f"gaps or another rate), {self.reanchored} re-anchored past a gap of over "
                f"{MAX_BACKLOG} steps")

    def close(self) -> None:
        pass


class OptimalStream:
    """The optimal mode's face for the live loop: live.optimal_stream.LiveOptimal (the MPC
    without preview, stepped at its own rate, solving off the loop's thread) pushed every
    accepted sample and sampled every tick, both at the loop's clock time (never decreasing).
    `reset` does nothing: the MPC keeps its own state through a fade (its window holds the last
    sample) and the live loop blends its plan in again on resume (live.fade.Blend)."""

    mode = "optimal"

    def __init__(self, mpc) -> None:
        self.mpc = mpc
        self.steps = 0
        self.interpolated = 0

    def reset(self) -> None:
        pass

    def push(self, s: TelemetrySample, now: float) -> int:
        self.mpc.push(now, s.specific_force, s.angular_velocity)
        self.steps += 1
        return 1

    def advance(self, now: float) -> int:
        """Nothing: the MPC steps at its own rate."""
        return 0

    def reference(self, now: float) -> Reference:
        q, qd, qdd = self.mpc.sample(now)
        return Reference(np.asarray(q, float), np.asarray(qd, float), np.asarray(qdd, float))

    def describe(self) -> str:
        st = self.mpc.stats()
        return (f"MPC: {st.steps} steps at {st.rate:g} Hz, {st.solves} solves, wall p50 "
                f"{st.wall_p50 * 1e3:.3g} ms, p99 {st.wall_p99 * 1e3:.3g} ms, p99.9 "
                f"{st.wall_p999 * 1e3:.3g} ms, max {st.wall_max * 1e3:.3g} ms; "
                f"{st.over_deadline} over 1/rate, {st.late} late, lead up to {st.lead_max}")

    def close(self) -> None:
        self.mpc.close()
