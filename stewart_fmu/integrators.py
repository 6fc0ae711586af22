"""Time integration of the plant: y = (q, qd), y' = (qd, forward_dynamics(q, qd, sigma)).

With a compliant transmission y = (q, qd, s, sd) has 24 entries (see transmission.py); every
method works on y of either length.

Compiled one-step methods advance a whole communication step in one call (the per-step Python
overhead is what limits a co-simulation at 1 ms): "rk4" (classic Runge-Kutta, fixed internal
step), "euler" (semi-implicit, symplectic Euler, fixed internal step, order 1) and "dopri5"
(Dormand-Prince 5(4) with error control, FSAL). scipy's solve_ivp methods
("RK45", "DOP853", "Radau", "BDF", "LSODA") are offered too, for stiff cases and as references.
The input force is held constant over a communication step (zero-order hold).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from . import model as M
from .dynamics import forward_sample, workspace  # the compiled per-sample forward kernel
from .status import OK, STEP_TOO_SMALL, TOO_MANY_STEPS
from .transmission import compliant_derivative, leg_side_params

COMPILED = ("rk4", "euler", "dopri5")
FIXED_STEP = {"rk4": 4, "euler": 1}  # the fixed-step methods and their theoretical order
SCIPY = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
INTEGRATORS = COMPILED + SCIPY


@dataclass(frozen=True)
class IntegratorOptions:
    """The integrator and its controls; max_step caps the internal step (s)."""

    method: str = "rk4"
    rtol: float = 1e-8
    atol: float = 1e-10
    max_step: float = 1e-3
    max_steps: int = 10_000    # internal steps per communication step before giving up

    def __post_init__(self) -> None:
        if self.method not in INTEGRATORS:
            raise ValueError(f"integrator '{self.method}' unknown; choose one of {INTEGRATORS}")
        for name in ("rtol", "atol", "max_step"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"integrator option {name} must be finite and > 0, got {value}")


# Not inlined: a call costs nanoseconds, while inlining the whole forward kernel (and the
# compliant one) at every stage of every integrator made a cold compile take minutes.
@njit(cache=True, error_model="numpy")
def _derivative(p, pl, y, F, ws, dy) -> int:
    """dy = y' at y with the rack force F; the forward kernel's status. pl: leg_side_params(p)."""
    if p[M.P_HAS_TRANSMISSION] != 0.0:
        return compliant_derivative(p, pl, y, F, ws, dy)
    R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt = ws
    q = (y[0], y[1], y[2], y[3], y[4], y[5])
    qd = (y[6], y[7], y[8], y[9], y[10], y[11])
    out = dy[6:12].reshape((1, 6))
    status = forward_sample(p, q, qd, F, R, om, al, U, Rr, leg, JT, gen, order, rhs, Mt, out, 0)
    for k in range(6):
        dy[k] = y[6 + k]
    return status


@njit(cache=True, error_model="numpy", inline="always")
def _axpy(out, y, a, x) -> None:
    """out = y + a x, without temporaries."""
    for j in range(y.shape[0]):
        out[j] = y[j] + a * x[j]


@njit(cache=True, error_model="numpy")
def rk4_advance(p, y0, y, F, h, n) -> int:
    """y = y0 advanced over h with n classic RK4 steps; status of the first failure or OK
    (y0 is left as it was, so a failed step needs no rollback)."""
    ws, pl, ny = workspace(), leg_side_params(p), y0.shape[0]
    k = np.empty((4, ny))
    tmp = np.empty(ny)
    F = (F[0], F[1], F[2], F[3], F[4], F[5])
    dt = h / n
    y[:] = y0
    for _ in range(n):
        status = _derivative(p, pl, y, F, ws, k[0])
        for s, c in ((1, 0.5), (2, 0.5), (3, 1.0)):
            if status == OK:
                _axpy(tmp, y, c * dt, k[s - 1])
                status = _derivative(p, pl, tmp, F, ws, k[s])
        if status != OK:
            return status
        for j in range(ny):
            y[j] += dt / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
    return OK


@njit(cache=True, error_model="numpy")
def euler_advance(p, y0, y, F, h, n) -> int:
    """y = y0 advanced over h with n semi-implicit Euler steps: velocities += dt accelerations,
    then positions += dt new velocities (symplectic Euler, order 1); y holds (q, qd) or
    (q, qd, s, sd); y0 kept, status as rk4_advance."""
    ws, pl, ny = workspace(), leg_side_params(p), y0.shape[0]
    dy = np.empty(ny)
    F = (F[0], F[1], F[2], F[3], F[4], F[5])
    dt = h / n
    y[:] = y0
    for _ in range(n):
        status = _derivative(p, pl, y, F, ws, dy)
        if status != OK:
            return status
        for b in range(0, ny, 12):          # (q, qd), then (s, sd) with a transmission
            for j in range(6):
                y[b + 6 + j] += dt * dy[b + 6 + j]
                y[b + j] += dt * y[b + 6 + j]
    return OK


# Dormand-Prince 5(4) tableau (Hairer, Norsett, Wanner: Solving ODEs I, Table 5.2).
DOPRI5_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
DOPRI5_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
])
DOPRI5_E = np.array([71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])


@njit(cache=True, error_model="numpy")
def dopri5_advance(p, y0, y, F, h, h_try, rtol, atol, max_step, max_steps, A, E):
    """y = y0 advanced over h with error-controlled Dormand-Prince 5(4) steps (y0 kept).

    Returns (status, next step size to try, internal steps taken, rejected steps). A stage
    that leaves the valid region (stroke, singularity) shrinks the step; if the step cannot
    complete, that stage's status is the reported cause."""
    ws, pl, ny = workspace(), leg_side_params(p), y0.shape[0]
    y[:] = y0
    cause = OK
    K = np.empty((7, ny))
    ytmp = np.empty(ny)
    ynew = np.empty(ny)
    F = (F[0], F[1], F[2], F[3], F[4], F[5])
    t, dt = 0.0, min(h_try, max_step, h)
    status = _derivative(p, pl, y, F, ws, K[0])
    steps = rejected = 0
    while status == OK and t < h:
        if steps + rejected >= max_steps:
            return (cause if cause != OK else TOO_MANY_STEPS), dt, steps, rejected
        last = t + dt >= h * (1.0 - 1e-12)
        step = h - t if last else dt
        for s in range(1, 7):
            for j in range(ny):
                acc = 0.0
                for m in range(s):
                    acc += A[s, m] * K[m, j]
                ytmp[j] = y[j] + step * acc
            status = _derivative(p, pl, ytmp, F, ws, K[s])
            if status != OK:
                break
        if status != OK:  # a stage left the workspace: retry smaller before giving up
            if step < 1e-14 * h:
                return status, dt, steps, rejected
            cause, dt, status, rejected = status, 0.25 * step, OK, rejected + 1
            status = _derivative(p, pl, y, F, ws, K[0])
            continue
        err = 0.0
        for j in range(ny):
            ynew[j] = ytmp[j]  # stage 7 is the 5th-order solution (FSAL)
            e = 0.0
            for s in range(7):
                e += E[s] * K[s, j]
            scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
            err += (step * e / scale) ** 2
        err = np.sqrt(err / ny)
        factor = min(5.0, max(0.2, 0.9 * err ** -0.2)) if err > 0 else 5.0
        if err <= 1.0:
            y[:] = ynew
            K[0, :] = K[6, :]
            t = h if last else t + step
            steps += 1
            dt = min(step * factor, max_step) if not last else dt
        else:
            rejected += 1
            dt = step * max(0.2, factor)
            if dt < 1e-14 * max(h, 1e-300):
                return (cause if cause != OK else STEP_TOO_SMALL), dt, steps, rejected
    return status, dt, steps, rejected


SCIPY_STAGE_RETRIES = 4   # a failed stage: retry with max_step / 8 each time (down to h / 4096)


class _StageFailed(Exception):
    """Raised inside solve_ivp's right-hand side to stop it at a bad state."""

    def __init__(self, status: int):
        self.status = status


def scipy_advance(model_params: np.ndarray, y0: np.ndarray, y: np.ndarray, F: np.ndarray,
                  h: float, opts: IntegratorOptions) -> tuple[int, int]:
    """y = y0 advanced over h with a solve_ivp method (y0 kept); (status, right-hand-side calls)."""
    calls = [0]

    def rhs(_t: float, state: np.ndarray) -> np.ndarray:
        calls[0] += 1
        dy = np.empty(state.shape[0])
        status = _scipy_derivative(model_params, state, F, dy)
        if status != OK:
            raise _StageFailed(status)
        return dy

    max_step = opts.max_step
    for _ in range(SCIPY_STAGE_RETRIES + 1):
        try:
            sol = solve_ivp(rhs, (0.0, h), y0, method=opts.method, rtol=opts.rtol,
                            atol=opts.atol, max_step=max_step)
        except _StageFailed as exc:
            # A trial stage left the valid region (stroke, singularity): solve_ivp cannot
            # shrink the step for that, so retry with smaller steps, as dopri5_advance does.
            status, max_step = exc.status, min(max_step, h) / 8
            continue
        if not sol.success:
            return STEP_TOO_SMALL, calls[0]
        y[:] = sol.y[:, -1]
        return OK, calls[0]
    return status, calls[0]


@njit(cache=True, error_model="numpy")
def _scipy_derivative(p, y, F, dy) -> int:
    return _derivative(p, leg_side_params(p), y, (F[0], F[1], F[2], F[3], F[4], F[5]),
                       workspace(), dy)


def derivative(params: np.ndarray, y: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, int]:
    """(y', status) of the plant at state y (12 or 24 entries) with the rack force F."""
    dy = np.empty(y.shape[0])
    return dy, _scipy_derivative(params, np.ascontiguousarray(y, dtype=float),
                                 np.ascontiguousarray(F, dtype=float), dy)
