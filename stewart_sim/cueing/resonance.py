"""Does a platform trajectory reach the mechanism's first mode? The lowest natural frequency
over the trajectory's poses (stewart_fmu.stiffness, the scene's [stiffness]) against the
spectrum of the legs' accelerations along it; `cue` and `size` both ask (the rigid model they
judge a motion with holds only below the first mode).

The content: each leg's length acceleration (m/s^2, one unit for translations and rotations,
what the legs' springs carry), less the straight line through its first and last samples (so
that the transform sees no jump at the window's ends), its energy spectrum summed over the six
legs. One mode f1 driven through its legs amplifies content at f by 1 / (1 - (f/f1)^2): at
f1 / sqrt(2) and above (to f1 sqrt(2)) the platform moves twice or more what the rigid model
says, its error as large as the content itself. The motion *reaches the first mode* when
SIGNIFICANT (1 %) or more of the energy (10 % of the RMS) lies at or above f1 / sqrt(2).
A step in acceleration (a cue's onset) spreads a tail of a few tenths of a percent up to the
sampling's Nyquist frequency; the shipped motions' cues keep 0.011-0.55 % there on the
motion simulator (docs/guides/stiffness-and-modes.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import UnstablePoseError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.stiffness import modes_map, regular_poses

BAND = 1.0 / math.sqrt(2.0)   # the band's lower edge, a fraction of f1: amplification 2 there
SIGNIFICANT = 0.01            # of the energy at or above BAND f1: the motion reaches the mode
MAX_POSES = 10_000            # poses whose modes are computed (evenly spaced samples)


@dataclass(frozen=True)
class Resonance:
    """The first mode along a trajectory and the trajectory's content near it."""

    lowest_hz: float     # the first mode's lowest frequency over the poses sampled (0: buckles)
    lowest_t: float      # s: where
    poses: int           # poses whose modes were computed (inside the stroke, regular)
    fraction: float      # of the legs' acceleration energy at or above BAND lowest_hz
    bandwidth_hz: float  # the frequency below which 99 % of that energy lies
    nyquist_hz: float    # half the sampling rate: no content above it is seen
    note: str | None = None   # why the first mode is not a frequency (the legs buckle)

    @property
    def edge_hz(self) -> float:
        return BAND * self.lowest_hz

    @property
    def reaches(self) -> bool:
        """The content reaches the first mode (or the platform is not stable on its legs)."""
        return self.note is not None or self.fraction >= SIGNIFICANT

    def line(self, name: str) -> str:
        """One line, the warning when the content reaches the mode, else the figures."""
        if self.note is not None:
            return f"warning: {name}: {self.note}"
        figures = (f"{100 * self.fraction:.3g} % of the legs' acceleration energy at or above "
                   f"{self.edge_hz:.3g} Hz (f1 / sqrt(2)); the first mode f1 down to "
                   f"{self.lowest_hz:.4g} Hz (t = {self.lowest_t:.3f} s); 99 % of the energy "
                   f"below {self.bandwidth_hz:.3g} Hz")
        if self.reaches:
            return (f"warning: {name} reaches the first mode: {figures} (the rigid model "
                    f"errs there by 100 % or more; {100 * SIGNIFICANT:g} % counts)")
        return f"{name} stays below the first mode: {figures}"


def resonance(model: Model, t, q, qd, qdd) -> Resonance | None:
    """The first mode over the trajectory's poses inside the stroke (at most MAX_POSES evenly
    spaced) and the legs' acceleration content against it; None when the scene has no
    [stiffness] or no pose is inside the stroke."""
    if model.stiffness is None:
        return None
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    step = max(1, -(-t.size // MAX_POSES))
    rows = np.arange(0, t.size, step)
    rows = rows[regular_poses(model, q[rows])]
    if rows.size == 0:
        return None
    spectrum = content(model, t, q, qd, qdd)
    try:
        lowest = modes_map(model, q[rows]).lowest_hz
    except UnstablePoseError as exc:
        return Resonance(0.0, math.nan, int(rows.size), math.nan, spectrum.bandwidth(0.99),
                         spectrum.nyquist,
                         f"not stable on its elastic legs along the motion: {exc}")
    k = int(np.argmin(lowest))
    f1 = float(lowest[k])
    return Resonance(f1, float(t[rows[k]]), int(rows.size), spectrum.above(BAND * f1),
                     spectrum.bandwidth(0.99), spectrum.nyquist)


@dataclass(frozen=True)
class Spectrum:
    """An energy spectrum: frequencies (Hz) and the energy in each bin (any unit, summed), of
    samples `step` s apart."""

    f: np.ndarray
    energy: np.ndarray
    step: float

    @property
    def nyquist(self) -> float:
        return 0.5 / self.step

    def above(self, edge: float) -> float:
        """The fraction of the energy at or above `edge` Hz (0 for a motion without any)."""
        total = float(self.energy.sum())
        return float(self.energy[self.f >= edge].sum()) / total if total > 0 else 0.0

    def bandwidth(self, share: float) -> float:
        """The lowest frequency below which `share` of the energy lies (0 without any)."""
        total = float(self.energy.sum())
        if not total > 0:
            return 0.0
        k = int(np.searchsorted(np.cumsum(self.energy) / total, share))
        return float(self.f[min(k, self.f.size - 1)])


def content(model: Model, t, q, qd, qdd) -> Spectrum:
    """The energy spectrum of the legs' accelerations along the trajectory (resampled onto a
    uniform grid of as many samples when its steps differ), each leg less the line through its
    end values, summed over the legs."""
    t = np.asarray(t, dtype=float)
    accel = inverse_kinematics(model, q, qd, qdd, with_cond=False).accelerations
    uniform = np.linspace(t[0], t[-1], t.size)
    if not np.allclose(t, uniform, rtol=0.0, atol=1e-9 * (t[-1] - t[0])):
        accel = np.column_stack([np.interp(uniform, t, accel[:, i]) for i in range(6)])
    ramp = np.linspace(0.0, 1.0, t.size)[:, None]
    accel = accel - (accel[0] + ramp * (accel[-1] - accel[0]))
    energy = np.sum(np.abs(np.fft.rfft(accel, axis=0)) ** 2, axis=1)
    energy[1:(t.size + 1) // 2] *= 2.0     # the negative frequencies' share (not 0 nor Nyquist's)
    step = (t[-1] - t[0]) / (t.size - 1)
    return Spectrum(np.fft.rfftfreq(t.size, step), energy, float(step))
