"""Time integration of the plant: y = (q, qd), y' = (qd, forward_dynamics(q, qd, sigma)).

With a compliant transmission y = (q, qd, s, sd) has 24 entries (see transmission.py); every
method works on y of either length.

The C core's methods (native/src/integrators.c) advance a whole communication step in one call
(the per-step Python overhead is what limits a co-simulation at 1 ms): "rk4" (classic Runge-Kutta, fixed internal
step), "euler" (semi-implicit, symplectic Euler, fixed internal step, order 1) and "dopri5"
(Dormand-Prince 5(4) with error control, FSAL). scipy's solve_ivp methods
("RK45", "DOP853", "Radau", "BDF", "LSODA") are offered too, for stiff cases and as references.
The input force is held constant over a communication step (zero-order hold).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .native import core
from .status import OK, STEP_TOO_SMALL

# The core's compiled methods by its names (stewart_method_name): written as a literal so that
# the command line's --help reads it without loading the core (stewart_sim.commands.constants);
# tests/stewart_fmu/test_table.py holds it equal to the core's.
COMPILED = ("rk4", "euler", "dopri5")
FIXED_STEP = {"rk4": 4, "euler": 1}  # the fixed-step methods and their theoretical order
SCIPY = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
INTEGRATORS = COMPILED + SCIPY


@dataclass(frozen=True)
class IntegratorOptions:
    """The integrator and its controls; max_step caps the internal step (s)."""

    method: str = core.DEFAULT_METHOD      # the core's defaults (stewart_default_options)
    rtol: float = core.DEFAULTS.rtol
    atol: float = core.DEFAULTS.atol
    max_step: float = core.DEFAULTS.max_step
    max_steps: int = core.DEFAULTS.max_steps  # internal steps per communication step before giving up

    def __post_init__(self) -> None:
        if self.method not in INTEGRATORS:
            raise ValueError(f"integrator '{self.method}' unknown; choose one of {INTEGRATORS}")
        for name in ("rtol", "atol", "max_step"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"integrator option {name} must be finite and > 0, got {value}")

    def native(self):
        """These options as the C core's stewart_options (compiled methods only)."""
        return core.options(self.method, self.rtol, self.atol, self.max_step, self.max_steps)


def advance(params, options: IntegratorOptions, y0: np.ndarray, y1: np.ndarray, F: np.ndarray,
            h: float) -> int:
    """y1 = y0 advanced over h with a compiled method (the core's stewart_advance, no energy
    check; Plant steps through the component's stewart_component_do_step instead); its status."""
    status, _, _ = core.advance(core.native_params(params), options.native(),
                                np.ascontiguousarray(y0, dtype=float), y1,
                                np.ascontiguousarray(F, dtype=float), h)
    return status


SCIPY_STAGE_RETRIES = 4   # a failed stage: retry with max_step / 8 each time (down to h / 4096)


class _StageFailed(Exception):
    """Raised inside solve_ivp's right-hand side to stop it at a bad state."""

    def __init__(self, status: int):
        self.status = status


def scipy_advance(model_params: np.ndarray | core.NativeParams, y0: np.ndarray, y: np.ndarray, F: np.ndarray,
                  h: float, opts: IntegratorOptions) -> tuple[int, int]:
    """y = y0 advanced over h with a solve_ivp method (y0 kept); (status, right-hand-side calls)."""
    calls, params = [0], core.native_params(model_params)
    F = np.ascontiguousarray(F, dtype=float)

    def rhs(_t: float, state: np.ndarray) -> np.ndarray:
        calls[0] += 1
        dy, status = core.derivative(params, np.ascontiguousarray(state), F)
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
            # shrink the step for that, so retry with smaller steps, as the core's dopri5 does.
            status, max_step = exc.status, min(max_step, h) / 8
            continue
        if not sol.success:
            return STEP_TOO_SMALL, calls[0]
        y[:] = sol.y[:, -1]
        return OK, calls[0]
    return status, calls[0]


def derivative(params, y: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, int]:
    """(y', status) of the plant at state y (12 or 24 entries) with the rack force F."""
    return core.derivative(core.native_params(params), np.ascontiguousarray(y, dtype=float),
                           np.ascontiguousarray(F, dtype=float))
