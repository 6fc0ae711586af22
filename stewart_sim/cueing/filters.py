"""Linear filters of the washout as state space, and their exact response to sampled input.

A filter N(s) / d(s) with monic d(s) = s^n + a_{n-1} s^{n-1} + ... + a_0 is realised in
controllable canonical form on z = u / d(s): the state is (z, z', ..., z^{(n-1)}) and
z^{(n)} = u - a . state. Every output the washout needs is a derivative of z, so position,
velocity and acceleration of one filter are read off one state (no finite differences).

Discretisation: the input is taken as piecewise linear between its samples (first-order hold,
"triangle hold"; Franklin, Powell & Workman, Digital Control of Dynamic Systems, 3rd ed.,
ch. 6), and the state is propagated EXACTLY for that input through the matrix exponential of
the augmented system [x; u; delta_u] (the same formula as scipy.signal.lsim with interp=True):

    x_{k+1} = Ad x_k + G0 u_k + G1 u_{k+1},   Ad = e^{A h}.

The samples are those of the continuous filter driven by the interpolated input, so the
outputs at the samples are consistent with each other to rounding; the only approximation is
the interpolation of the input itself (second order in h for a smooth input). The recursion
needs u_{k+1} only to reach x_{k+1}: it is causal, so the washout steps it sample by sample
(washout_step.py), offline as live.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm


def high_pass_denominator(frequency: float, damping: float, order: int,
                          first_order: float = 0.0) -> np.ndarray:
    """d(s) of the washout's high-pass s^order / d(s): order 1: s + w; order 2:
    s^2 + 2 zeta w s + w^2; order 3: (s^2 + 2 zeta w s + w^2)(s + w_b)."""
    if order == 1:
        return np.array([1.0, frequency])
    second = np.array([1.0, 2.0 * damping * frequency, frequency ** 2])
    return second if order == 2 else np.convolve(second, [1.0, first_order])


def companion(den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of 1 / d(s) in controllable canonical form, d = [1, a_{n-1}, ..., a_0]
    (highest power first, monic): state (z, ..., z^{(n-1)}), z^{(n)} = u - a . state."""
    den = np.asarray(den, dtype=float)
    n = den.size - 1
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -den[:0:-1]
    B = np.zeros((n, 1))
    B[-1, 0] = 1.0
    return A, B


def foh_matrices(den: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Ad, g0, g1) of 1 / d(s) for the period h, exact for the piecewise-linear input:
    x_{k+1} = Ad x_k + g0 u_k + g1 u_{k+1}. expm of h [[A, B, 0], [0, 0, 1/h], [0, 0, 0]]
    (the input and its increment over the period appended to the state) gives Ad and the
    input's two weights."""
    A, B = companion(den)
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n] = A * h
    M[:n, n] = B[:, 0] * h
    M[n, n + 1] = 1.0
    E = expm(M)
    Ad, g1 = E[:n, :n], E[:n, n + 1]
    return Ad, E[:n, n] - g1, g1


class FilterBank:
    """Filters 1 / d_j(s) side by side, filter j driven by input j, stepped one sample at a
    time. The state is the filters' states end to end, each (z, ..., z^(n_j - 1)) of its own
    z = u_j / d_j(s); each step gives it with every z_j^(n_j) = u_j - a_j . state_j (the
    filters' top derivatives) appended, from one matrix product (block-diagonal)."""

    def __init__(self, dens: list[np.ndarray], h: float) -> None:
        dens = [np.asarray(d, dtype=float) for d in dens]
        sizes = [d.size - 1 for d in dens]
        n, m = sum(sizes), len(dens)
        self.offsets = tuple(int(o) for o in np.cumsum([0] + sizes[:-1]))
        self.size = n
        # x_{k+1} = [Ad | G0 | G1] (x_k, u_k, u_{k+1}); top_{k+1} = u_{k+1} - C x_{k+1}
        step = np.zeros((n, n + 2 * m))
        C = np.zeros((m, n))
        for j, (den, o, k) in enumerate(zip(dens, self.offsets, sizes)):
            Ad, g0, g1 = foh_matrices(den, h)
            step[o:o + k, o:o + k] = Ad
            step[o:o + k, n + j] = g0
            step[o:o + k, n + m + j] = g1
            C[j, o:o + k] = den[:0:-1]
        top = -C @ step
        top[:, n + m:] += np.eye(m)
        self._matrix = np.vstack([step, top])
        self._m = m

    def advance(self, x: np.ndarray, u_prev: list[float], u: list[float]) -> np.ndarray:
        """(x_{k+1}, top_{k+1}) from the state x_k, the input going linearly from u_prev to u
        over the period."""
        return self._matrix @ np.concatenate((x, u_prev, u))

    def start(self, u: list[float]) -> np.ndarray:
        """(x_0, top_0) at rest (zero state) with the input u: (0, u)."""
        return np.concatenate((np.zeros(self.size), u))
