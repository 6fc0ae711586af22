"""Stiffness and instability: the linearised plant's spectral radius, the explicit stability
limit it sets, the default integrator that respects it, and the advice an unstable step gets
(the step's power-balance check itself is the C core's, below).

The check is the step's power balance (native/src/energy.c, stewart_step_energy): with the rack
forces F held, the work W = F . (d1 - d0) on the driven coordinates (energy.py) and
dE - W = -(dissipation) <= 0 for an accurate step; allowed: ENERGY_TOL of the energy exchanged,
plus the Coulomb work bound coulomb (sum |dd| + h sum |ld1|): the friction's sign changes inside
a step (a leg at rest, or reversing) are integrated to O(1) of the work it does over the step's
path, which its displacement alone underestimates when the step ends moving (a platform starting
from rest against 150 N of Coulomb friction gains ~3e-6 J of such spurious energy in a 1 ms RK4
step). A non-finite result (STATE_NONFINITE) or a larger gain (ENERGY_GAIN) fails the step; the
component (native/src/component.c) keeps the state at its start.

The stiff modes of this plant are linear in the state near any point (viscous friction c / m,
transmission springs sqrt(k / m), damper c / m), so the spectral radius rho of the Jacobian of
y' = f(y) bounds the step of an explicit method: RK4 is stable for |h lambda| below ~2.78 on the
negative real axis (2.785) and the imaginary axis (2.828). Coulomb friction is left out of the
Jacobian (a jump, not a stiffness).
"""
from __future__ import annotations

import math

import numpy as np

from . import model as M
from .dynamics import inverse_dynamics
from .integrators import IntegratorOptions, derivative
from .model import Model
from .native import core
from .status import OK
from .transmission import initial_state

RK4_LIMIT = 2.78          # |h lambda| at RK4's stability boundary (real and imaginary axes)
DEFAULT_H_RHO = 0.5       # the default RK4 step keeps h rho <= 0.5: stiff modes resolved, not just stable
DEFAULT_MAX_STEP = IntegratorOptions().max_step
ENERGY_TOL = core.ENERGY_TOL  # energy gained beyond the input work, relative to the energy exchanged (1e-3)
_FD = 1e-7                # relative finite-difference step of the Jacobian


def hold_state(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """(y, F): home at rest with the rack forces that hold it (the spring preloaded)."""
    F = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))
    return initial_state(model, model.home, np.zeros(6), F), F


def spectral_radius(model: Model, y: np.ndarray, F: np.ndarray) -> float:
    """max |lambda| of the Jacobian of y' = f(y, F) (central differences, Coulomb left out);
    NaN when a neighbouring state cannot be evaluated (stroke, singularity) or the Jacobian is
    not finite (a state or force beyond what float64 holds: there is no step to advise)."""
    p = model.params.copy()
    p[M.P_COULOMB:M.P_COULOMB + 6] = 0.0   # every leg's
    # packed for the core once for the 2 n derivatives below (the model's own when unchanged)
    packed = model.native if np.array_equal(p, model.params) else core.native_params(p)
    scale = np.maximum(np.abs(y), model.characteristic_length)
    cols = []
    for j in range(y.shape[0]):
        e = np.zeros_like(y)
        e[j] = _FD * scale[j]
        hi, s1 = derivative(packed, y + e, F)
        lo, s2 = derivative(packed, y - e, F)
        if s1 != OK or s2 != OK:  # a neighbour leaves the valid region: no estimate
            return math.nan
        with np.errstate(over="ignore", invalid="ignore"):   # refused below
            cols.append((hi - lo) / (2.0 * e[j]))
    jacobian = np.column_stack(cols)
    if not np.all(np.isfinite(jacobian)):   # forces or a state too large to difference
        return math.nan
    return float(np.max(np.abs(np.linalg.eigvals(jacobian))))


def stable_step(model: Model, y: np.ndarray | None = None, F: np.ndarray | None = None) -> float:
    """The largest stable RK4 step (s) at y (default: the hold at home): RK4_LIMIT / rho."""
    if y is None or F is None:
        y, F = hold_state(model)
    rho = spectral_radius(model, y, F)
    return RK4_LIMIT / rho if rho > 0 else math.inf   # NaN or 0: no limit known


def default_options(model: Model) -> IntegratorOptions:
    """RK4 with its step capped at 1 ms and at h rho <= DEFAULT_H_RHO at the hold (stiff scenes)."""
    h = stable_step(model) * DEFAULT_H_RHO / RK4_LIMIT
    return IntegratorOptions(method="rk4", max_step=min(DEFAULT_MAX_STEP, h))


def internal_step(options: IntegratorOptions, h: float) -> float:
    """The step the method takes inside a communication step h (its cap for adaptive ones)."""
    if options.method == "rk4":
        return h / max(1, math.ceil(h / options.max_step - 1e-9))
    return min(h, options.max_step)


def advice(model: Model, y: np.ndarray, F: np.ndarray) -> tuple[float, str]:
    """(stable RK4 step at y, advice text) for an integration that went unstable."""
    h = stable_step(model, y, F)
    if not math.isfinite(h):
        return h, "use 'Radau' or 'BDF', or a smaller max_step"
    return h, (f"the plant is stiff here (RK4 stability limit {h:.3g} s): use 'Radau' or "
               f"'BDF', or 'rk4' with max_step below {h:.3g} s")

