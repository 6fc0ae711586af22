"""The excitation trajectory: a finite Fourier series per pose axis (Swevers, Ganseman, Tukel,
De Schutter and Van Brussel 1997), periodic with the fundamental w_f = 2 pi / period:

    q_j(t)   = q0_j + sum_k  a_jk / (k w_f) sin(k w_f t) - b_jk / (k w_f) cos(k w_f t)
    qd_j(t)  =        sum_k  a_jk cos(k w_f t) + b_jk sin(k w_f t)
    qdd_j(t) =        sum_k -a_jk k w_f sin(k w_f t) + b_jk k w_f cos(k w_f t)      k = 1..H

At rest at home at t = 0, by linear constraints on the coefficients (no polynomial correction,
so the series stays band-limited to H w_f):

    qd_j(0) = 0       <=>  sum_k a_jk = 0
    qdd_j(0) = 0      <=>  sum_k k b_jk = 0
    q_j(0) = home_j   <=>  q0_j = home_j + sum_k b_jk / (k w_f)

The first two hold for every x: in the position amplitudes alpha_jk = a_jk / (k w_f) and
beta_jk = b_jk / (k w_f) they read sum_k k alpha_jk = 0 and sum_k k^2 beta_jk = 0, so
alpha_j = Na x_aj and beta_j = Nb x_bj with Na, Nb orthonormal bases of the vectors orthogonal
to [1 2 .. H] and [1 4 .. H^2] (2 (H - 1) free numbers per axis, the optimiser's variables);
the third sets q0. Every multiple of the period is then at rest at home as well (the series is
periodic), so a trajectory of n whole periods starts and ends at rest at home. The optimiser's x
is dimensionless: alpha and beta are Na x_a and Nb x_b times `scale` (m for x, y, z; rad for
the angles).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from controller.trajectory import Trajectory, sample_times


@dataclass(frozen=True)
class FourierSeries:
    """The family of excitation trajectories of one scene: period (s), harmonics H, the home
    pose q(0) and the scale of each axis's amplitudes (m or rad per unit of x)."""

    period: float
    harmonics: int
    home: np.ndarray       # (6,)
    scale: np.ndarray      # (6,)

    @property
    def omega(self) -> float:
        """The fundamental w_f, rad/s."""
        return 2.0 * np.pi / self.period

    @property
    def size(self) -> int:
        """How many free numbers x has: 2 (H - 1) per axis."""
        return 12 * (self.harmonics - 1)

    def coefficients(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q0 (6,), a (6, H), b (6, H)) of x: Swevers' coefficients, at rest at home."""
        H, w = self.harmonics, self.omega
        k = np.arange(1, H + 1, dtype=float)
        xa, xb = np.asarray(x, dtype=float).reshape(2, 6, H - 1)
        # position amplitudes (m, rad) -> Swevers' a, b (velocity units): times k w_f
        na, nb = _bases(H)
        a = (xa @ na.T) * self.scale[:, None] * k * w
        b = (xb @ nb.T) * self.scale[:, None] * k * w
        q0 = self.home + (b / (k * w)).sum(axis=1)
        return q0, a, b

    def evaluate(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd (N, 6) at times t (N,)."""
        q0, a, b = self.coefficients(x)
        k = np.arange(1, self.harmonics + 1, dtype=float)
        kw = k * self.omega
        s, c = np.sin(np.outer(t, kw)), np.cos(np.outer(t, kw))   # (N, H)
        q = q0 + s @ (a / kw).T - c @ (b / kw).T
        qd = c @ a.T + s @ b.T
        qdd = -s @ (a * kw).T + c @ (b * kw).T
        return q, qd, qdd

    def trajectory(self, x: np.ndarray, periods: int, rate: float) -> Trajectory:
        """`periods` whole periods sampled at `rate` (Hz), both ends included."""
        t = sample_times(periods * self.period, rate)
        return Trajectory(t, *self.evaluate(x, t))


@functools.lru_cache(maxsize=32)
def _bases(harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """Na, Nb (H, H - 1): orthonormal bases of the vectors orthogonal to [1 2 .. H] and
    [1 4 .. H^2] (read-only: shared by every call)."""
    k = np.arange(1, harmonics + 1, dtype=float)
    out = tuple(scipy.linalg.null_space(row[None, :]) for row in (k, k * k))
    for basis in out:
        basis.flags.writeable = False
    return out
