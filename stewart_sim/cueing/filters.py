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
the interpolation of the input itself (second order in h for a smooth input).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm


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


def top_derivative(den: np.ndarray, states: np.ndarray, u: np.ndarray) -> np.ndarray:
    """z^{(n)} = u - a . (z, ..., z^{(n-1)}) for states (N, n) and input (N,)."""
    den = np.asarray(den, dtype=float)
    return u - states @ den[:0:-1]


def foh_states(dens: list[np.ndarray], u: np.ndarray, h: float) -> list[np.ndarray]:
    """States (N, n_j) of the filters 1 / d_j(s), each driven by its column of u (N, m),
    started at rest (zero state) and propagated exactly for the piecewise-linear input."""
    return [foh_state(d, u[:, j], h) for j, d in enumerate(dens)]


def foh_state(den: np.ndarray, u: np.ndarray, h: float) -> np.ndarray:
    """States (N, n) of 1 / d(s) driven by u (N,), from rest, exact for the piecewise-linear
    input: expm of h [[A, B, 0], [0, 0, 1], [0, 0, 0]] gives Ad and the input's two weights."""
    A, B = companion(den)
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n] = A * h
    M[:n, n] = B[:, 0] * h
    M[n, n + 1] = 1.0
    E = expm(M)
    Ad, g1 = E[:n, :n], E[:n, n + 1]
    g0 = E[:n, n] - g1
    X = np.zeros((u.shape[0], n))
    X[1:] = linear_recurrence(Ad, np.outer(u[:-1], g0) + np.outer(u[1:], g1))
    return X


def linear_recurrence(Ad: np.ndarray, drive: np.ndarray, block: int = 32) -> np.ndarray:
    """x_1..x_K of x_{k+1} = Ad x_k + drive_k from x_0 = 0 (drive (K, n)), in blocks: within a
    block the response from a zero start is one product with the block-Toeplitz matrix of
    the powers Ad^(i-j); the block starts are carried sequentially (K / block steps). The
    same sums as the plain recursion, in another order (rounding differs in the last bits)."""
    K, n = drive.shape
    nb = -(-K // block)
    W = np.zeros((nb * block, n))
    W[:K] = drive
    P = np.empty((block + 1, n, n))
    P[0] = np.eye(n)
    for i in range(block):
        P[i + 1] = Ad @ P[i]
    i, j = np.indices((block, block))
    T = np.where((i >= j)[:, :, None, None], P[np.clip(i - j, 0, block)], 0.0)
    T = T.transpose(0, 2, 1, 3).reshape(block * n, block * n)
    Y = (W.reshape(nb, block * n) @ T.T).reshape(nb, block, n)
    starts = np.zeros((nb, n))
    carryT = P[block].T
    for b in range(nb - 1):
        starts[b + 1] = starts[b] @ carryT + Y[b, -1]
    Y += np.einsum("inm,bm->bin", P[1:], starts)
    return Y.reshape(nb * block, n)[:K]


def input_slope(u: np.ndarray, h: float) -> np.ndarray:
    """du/dt of the piecewise-linear input at its samples: the mean of the slopes either side
    (the central difference), one-sided at the ends. At a sample the interpolated input has a
    kink; the mean of its two one-sided slopes is its second-order estimate of the smooth input."""
    s = np.empty_like(u)
    s[1:-1] = (u[2:] - u[:-2]) / (2.0 * h)
    s[0] = (u[1] - u[0]) / h
    s[-1] = (u[-1] - u[-2]) / h
    return s
