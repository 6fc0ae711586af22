"""The one plant step: integrate a communication step with the rack forces held, then check it.

`plant_step` is what FMI's doStep computes, for every caller: `plant.Plant` (in-process), the
exported FMU and the closed loop of `controller.cosim` all run the C core's `stewart_step`
(native/src/step.c), so they take the same integrator path and refuse the same steps.

The check is the step's power balance (native/src/energy.c): with the rack forces F held, the
work W = F . (d1 - d0) on the driven coordinates (energy.py) and dE - W = -(dissipation) <= 0
for an accurate step; allowed: ENERGY_TOL of the energy exchanged, plus the Coulomb work bound
coulomb (sum |dd| + h sum |ld1|): the friction's sign changes inside a step (a leg at rest, or
reversing) are integrated to O(1) of the work it does over the step's path, which its
displacement alone underestimates when the step ends moving (a platform starting from rest
against 150 N of Coulomb friction gains ~3e-6 J of such spurious energy in a 1 ms RK4 step). A
non-finite result (STATE_NONFINITE) or a larger gain (ENERGY_GAIN) fails the step; the caller
keeps the state at its start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .native import core
from .status import ENERGY_GAIN, OK, STATE_NONFINITE


@dataclass(frozen=True)
class StepResult:
    """What one plant step reports besides the new state."""

    status: int          # status.OK, or why the step was refused
    step_guess: float    # the adaptive method's next internal step (s)
    evaluations: int     # right-hand-side evaluations
    excess: float        # energy gained beyond the input work (J)
    allowed: float       # the gain the check allows (J)


def plant_step(params: core.NativeParams, options, y0: np.ndarray, y1: np.ndarray,
               F: np.ndarray, h: float, e0: np.ndarray, e1: np.ndarray,
               step_guess: float) -> StepResult:
    """y1 = y0 advanced by h with the rack forces F held, then checked against e0 =
    energy_terms(y0) (e1 receives those of y1). `options`: IntegratorOptions.native()."""
    return StepResult(*core.step(params, options, y0, y1, F, h, e0, e1, step_guess))


def check_step(params: core.NativeParams, y1: np.ndarray, e0: np.ndarray, e1: np.ndarray,
               F: np.ndarray, h: float) -> StepResult:
    """The check alone, for a step integrated elsewhere (scipy's methods): the same power
    balance as plant_step's, with its default tolerance."""
    finite, excess, allowed = core.step_energy(params, y1, e0, e1, F, core.ENERGY_TOL, h)
    status = STATE_NONFINITE if not finite else ENERGY_GAIN if not excess <= allowed else OK
    return StepResult(status, math.nan, 0, excess, allowed)


def fixed_substeps(h: float, max_step: float) -> int:
    """Internal steps of a fixed-step method in a communication step h (at most max_step)."""
    return max(1, math.ceil(h / max_step - 1e-9))


