"""The one plant step: integrate a communication step with the rack forces held, then check it.

`plant_step` is what FMI's doStep computes, for every caller: `plant.Plant` (in-process and in
the FMU) and the compiled closed loop of `controller.cosim` call it, so both take the same
integrator path and refuse the same steps. The check (`check_step`) is the power balance of
`stability.step_energy`: a non-finite result (STATE_NONFINITE) or energy grown beyond the work
of the held rack forces (ENERGY_GAIN) fails the step; the caller keeps the state at its start.
"""
from __future__ import annotations

import math

from numba import njit

from .integrators import DOPRI5_A, DOPRI5_E, dopri5_advance, euler_advance, rk4_advance
from .stability import step_energy
from .status import ENERGY_GAIN, OK, STATE_NONFINITE

RK4, EULER, DOPRI5 = 0, 1, 2                      # the compiled methods, by number
METHODS = {"rk4": RK4, "euler": EULER, "dopri5": DOPRI5}
STEP_GUESS, EVALUATIONS, EXCESS, ALLOWED = 0, 1, 2, 3  # layout of plant_step's `info`
INFO_SIZE = 4


@njit(cache=True, error_model="numpy")
def plant_step(p, method, y0, y1, F, h, n_sub, rtol, atol, max_step, max_steps, e0, e1, tol,
               info) -> int:
    """y1 = y0 advanced by h (n_sub fixed steps, or dopri5 from the step guess info[0]) with the
    rack forces F held, then checked against e0 = energy_terms(y0) (e1 receives those of y1).
    info: [step guess (in/out), evaluations, excess energy (J), allowed (J)]. Returns a status."""
    if method == DOPRI5:
        status, info[STEP_GUESS], steps, rejected = dopri5_advance(
            p, y0, y1, F, h, info[STEP_GUESS], rtol, atol, max_step, max_steps, DOPRI5_A, DOPRI5_E)
        info[EVALUATIONS] = 1 + 6 * (steps + rejected)
    elif method == RK4:
        status = rk4_advance(p, y0, y1, F, h, n_sub)
        info[EVALUATIONS] = 4 * n_sub
    else:
        status = euler_advance(p, y0, y1, F, h, n_sub)
        info[EVALUATIONS] = n_sub
    if status != OK:
        return status
    return check_step(p, y1, e0, e1, F, tol, h, info)


@njit(cache=True, error_model="numpy")
def check_step(p, y1, e0, e1, F, tol, h, info) -> int:
    """The step's check alone (for integrators outside plant_step, e.g. scipy's)."""
    finite, info[EXCESS], info[ALLOWED] = step_energy(p, y1, e0, e1, F, tol, h)
    if not finite:
        return STATE_NONFINITE
    if not info[EXCESS] <= info[ALLOWED]:
        return ENERGY_GAIN
    return OK


def fixed_substeps(h: float, max_step: float) -> int:
    """Internal steps of a fixed-step method in a communication step h (at most max_step)."""
    return max(1, math.ceil(h / max_step - 1e-9))
