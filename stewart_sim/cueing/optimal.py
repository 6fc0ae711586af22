"""Model-predictive motion cueing: the platform motion that minimises the perceived-motion error
within the mechanism's real limits, over a receding horizon, solved by OSQP.

The formulation follows Dagdelen et al. 2009 ("Model-based predictive motion cueing strategy for
vehicle driving simulators", Control Engineering Practice 17: 995-1003) and Garrett and Best
2013 ("Model predictive driving simulator motion cueing algorithm with actuator-based
constraints", Vehicle System Dynamics 51: 1151-1172), with the limits taken from our own model:

* Prediction (mpc_model.py): the pose and its Euler-angle rates as double integrators driven by
  the accelerations u = qdd (zero-order hold at the MPC rate), and the vestibular models
  (otolith, semicircular canals) driven by the delivered-minus-vehicle specific force and
  angular velocity, gravity tilt included. One vestibular state therefore carries the perceived
  error, exactly discretised.
* Cost over the horizon: the perceived error per axis in units of its perception threshold
  (weight 1 / threshold^2), a washout term on position, velocity, yaw and the angular rates
  (never on roll and pitch: a sustained tilt is the cue of a sustained specific force), 100x
  on the horizon's last step (what lies beyond the horizon must not be left drifting), the
  input effort, and an exact penalty on the stroke slack.
* Constraints: the six leg lengths within the stroke minus a margin, the rack forces within
  Kf I_max (stewart_fmu.dynamics.inverse_dynamics: every effect the scene declares, the drives'
  reflected inertia included), the drive voltage R sigma / Kf + Ke' ldot within V_max minus a
  margin (controller.drive's motor; the inductive L di/dt is left out: L/R = 10 ms on the
  shipped simulator, within one MPC step), forces at both ends of every step, voltages at
  their ends, and the tilt rate: the platform's roll and pitch rates may differ from the
  vehicle's by at most the tilt-rate limit (the rotation the occupant feels that the vehicle
  does not make stays below the canals' threshold).
* Non-linearity (a real-time iteration of sequential QP): each step re-linearises the leg rows
  (value and Jacobians, mpc_model.leg_linearisation) at every point of the previous solution's
  prediction, shifted by one step; the QP's pattern is built once and OSQP gets new values
  (a refactorisation) and vectors. The delivered specific force and angular velocity are
  felt at the scene's [cueing] head (mpc_model.py), linearised at home in the cost (the head's
  tangential term, linear in the accelerations, is in it exactly at home), their remainder (the
  tilt's sine, the centripetal term) evaluated on the same prediction as a known input: at a
  steady state the prediction is the state, so a sustained specific force f ends as the tilt
  asin(f / g), not its small-angle f / g.
* The stroke is soft (a slack with a linear and a quadratic penalty, exact when the hard
  problem is feasible), so a prediction that cannot stop in time still has a solution; the
  slack used is reported. Force, voltage and tilt rate are hard; a step OSQP does not solve
  flies the previous plan (counted in the diagnostics' status).
* Preview: with `preview=True` (default) the future vehicle motion over the horizon is known
  (a recorded motion, as in Garrett and Best's offline case); with False the current vehicle
  motion is held over the horizon (the real-time case of Dagdelen et al.).

* Move blocking (`blocking` r > 1, the live mode's lever): the QP predicts on a grid of r MPC
  steps with each acceleration held over its block, a QP about r times smaller; the state is
  still advanced and the QP re-solved every MPC step, the blocks refined to the steps
  (refine_plan). r = 1 (default) is the formulation above unchanged.

The rate, horizon, margins, weights and solver settings are OptimalOptions
(cueing_config.py): the scene's [cueing.optimal] table, read by cueing_config.optimal_options.

The applied accelerations are integrated exactly (piecewise constant), so the returned q, qd,
qdd are consistent at any sample rate; the cue is resampled at the motion's own times.

OptimalStepper holds the QP and the state and takes one MPC step given the vehicle window;
optimal_cueing is the loop over it on a recorded motion, optimal_stream.LiveOptimal steps it
live on telemetry.
"""
from __future__ import annotations

import time
from typing import Callable
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from controller.capability import Capability, capability
from controller.config import ControllerConfig
from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model

from stewart_sim.scene.cueing_config import CueingConfig, OptimalOptions
from .motion import VehicleMotion
from .mpc_model import (
    NP,
    NU,
    LegLinearisation,
    Linearisation,
    PredictionModel,
    delivered,
    leg_linearisation,
    linearise,
    prediction_model,
)
from .vestibular import (
    CANAL_THRESHOLD,
    OTOLITH_THRESHOLD,
    canal_num_den,
    otolith_num_den,
)
from .washout import Cue

# f_x, f_y, f_z, omega_x, omega_y, omega_z: the models perception() runs
VESTIBULAR_CHANNELS = tuple(otolith_num_den(k) for k in range(3)) + tuple(
    canal_num_den(k) for k in range(3))


# rho adapted every 25 iterations, not after a fraction of the setup time (OSQP's default):
# the same problem then takes the same path whatever the machine's load.
OSQP_SETTINGS = {"adaptive_rho_interval": 25, "rho": 0.01, "polishing": True}
REFINE_ITERATIONS = 500


@dataclass(frozen=True)
class Diagnostics:
    """How the receding-horizon solves went: per MPC step, and totals."""

    t: np.ndarray                    # (M,) MPC step times, s
    iterations: np.ndarray           # (M,) OSQP iterations
    solve_time: np.ndarray           # (M,) s, OSQP's own solve time
    status: tuple[str, ...]          # (M,) OSQP status of each step
    polished: np.ndarray             # (M,) bool: solved exactly on its active set (else to
                                     # the tolerance, or its tenth after a failed polish)
    slack: np.ndarray                # (M,) stroke slack of the applied step, m (0: kept)
    predicted_error: np.ndarray      # (M, 6) perceived error of the applied step (model)
    limits: tuple[str, ...]          # the limits imposed: "stroke", "force", "voltage", "tilt_rate"
    wall_time: float                 # s, the whole run
    variables: int
    constraints: int

    @property
    def status_counts(self) -> dict[str, int]:
        names, counts = np.unique(np.asarray(self.status), return_counts=True)
        return {str(n): int(c) for n, c in zip(names, counts)}


@dataclass(frozen=True)
class Plan:
    """The applied moves on the MPC grid: state at t_k (dq, qd) and the acceleration held on
    [t_k, t_k+1). Integrated exactly by `sample`."""

    t: np.ndarray     # (M,)
    dq: np.ndarray    # (M, 6) pose minus home
    qd: np.ndarray    # (M, 6)
    qdd: np.ndarray   # (M, 6)

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dq, qd, qdd) at times t: q = q_k + qd_k tau + qdd_k tau^2 / 2 on each step."""
        dt = self.t[1] - self.t[0] if self.t.size > 1 else 1.0
        k = np.clip(np.floor((t - self.t[0]) / dt + 1e-9).astype(int), 0, self.t.size - 1)
        return held_move(self.dq[k], self.qd[k], self.qdd[k], (t - self.t[k])[:, None])


def held_move(dq: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dq, qd, qdd) a time tau into a step that starts at (dq, qd) with qdd held."""
    return dq + qd * tau + 0.5 * qdd * tau**2, qd + qdd * tau, qdd


def interval_means(t: np.ndarray, y: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Mean of the sampled signal y (N, m) (linear between samples, held past the ends) over
    each [edges[j], edges[j+1]): the zero-order-hold input that carries the same impulse."""
    t_ext = np.r_[t, max(edges[-1], t[-1]) + 1.0]
    y_ext = np.vstack([y, y[-1]])
    cum = np.vstack([np.zeros(y.shape[1]),
                     np.cumsum(0.5 * (y_ext[1:] + y_ext[:-1]) * np.diff(t_ext)[:, None], axis=0)])
    e = np.clip(edges, t[0], None)
    at = np.stack([np.interp(e, t_ext, cum[:, i]) for i in range(y.shape[1])], axis=1)
    # before the first sample, the first value is held
    at += (edges - e)[:, None] * y[0]
    return np.diff(at, axis=0) / np.diff(edges)[:, None]


class _Triplets:
    """A sparse matrix assembled from blocks of (row, column, value) once, whose values can be
    refilled in the same order and handed to OSQP as the CSC data of the same pattern."""

    def __init__(self):
        self.rows, self.cols, self.vals, self.blocks = [], [], [], {}
        self.size = 0

    def add(self, name, r0: int, c0: int, block: np.ndarray) -> None:
        """Dense block at (r0, c0), every entry kept in the pattern (zeros too)."""
        r, c = np.meshgrid(np.arange(block.shape[0]), np.arange(block.shape[1]), indexing="ij")
        self.rows.append(r0 + r.ravel())
        self.cols.append(c0 + c.ravel())
        self.vals.append(block.ravel().astype(float))
        if name is not None:
            self.blocks.setdefault(name, []).append(slice(self.size, self.size + block.size))
        self.size += block.size

    def csc(self, shape) -> sp.csc_matrix:
        rows, cols = np.concatenate(self.rows), np.concatenate(self.cols)
        self.order = np.lexsort((rows, cols))
        self.data = np.concatenate(self.vals)
        A = sp.csc_matrix((self.data[self.order], (rows[self.order], cols[self.order])),
                          shape=shape)
        if A.nnz != self.data.size:
            raise ValueError("overlapping blocks in the QP matrix")
        A.data[:] = self.data[self.order]   # explicit zeros kept: the pattern is fixed
        return A

    def refill(self, name: str, blocks: np.ndarray) -> None:
        """New values of the named blocks, (count, rows, cols), in the order they were added."""
        for sl, b in zip(self.blocks[name], blocks):
            self.data[sl] = b.ravel()

    def csc_data(self) -> np.ndarray:
        return self.data[self.order]


class _Qp:
    """The sparse QP of one horizon. P and the dynamics are built once; the leg rows (stroke,
    force, voltage) are re-linearised on the predicted trajectory every step (their values
    change, not their pattern); q, l, u carry the vehicle motion and the offsets.

    Variables z = (x_0..x_N, u_0..u_{N-1}, s_0..s_{N-1}); s_k >= 0 relaxes the stroke at k+1."""

    def __init__(self, pm: PredictionModel, lim: Capability, tilt_rate: float | None,
                 legs: LegLinearisation, steps: int,
                 weights: np.ndarray, state_weights: np.ndarray, input_weights: np.ndarray,
                 slack_weight: tuple[float, float], margins: dict[str, float],
                 tolerance: float, max_iter: int, terminal_weight: float):
        self.pm, self.lim, self.N, self.margin = pm, lim, steps, margins
        self.tilt_rate = tilt_rate
        self.tolerance, self.max_iter = tolerance, max_iter
        n, N = pm.n, steps
        self.nx, self.nu0, self.ns0 = (N + 1) * n, (N + 1) * n, (N + 1) * n + N * NU
        nz = self.ns0 + N
        self.nz = nz
        xi, ui, si = (lambda k: k * n), (lambda k: self.nu0 + k * NU), (lambda k: self.ns0 + k)
        # Rows in units of their own range (stroke half-range, force and voltage limits), so
        # the slack is a fraction and OSQP sees rows of one size.
        self.span = (lim.leg_max - lim.leg_min) / 2 if None not in (lim.leg_min, lim.leg_max) \
            else 1.0
        W = np.diag(weights)
        Cy, Dy = pm.C, pm.D
        P = _Triplets()
        for k in range(N + 1):
            Qx = Cy.T @ W @ Cy
            Qx[:NP, :NP] += np.diag(state_weights) * (terminal_weight if k == N else 1.0)
            P.add(None, xi(k), xi(k), np.triu(Qx))
            if k < N:
                P.add(None, xi(k), ui(k), Cy.T @ W @ Dy)
                P.add(None, ui(k), ui(k), np.triu(Dy.T @ W @ Dy + np.diag(input_weights)))
                P.add(None, si(k), si(k), np.array([[slack_weight[1]]]))
        self.P = sp.csc_matrix(sp.triu(P.csc((nz, nz))))
        self.grad = np.hstack([Cy, Dy]).T @ W @ pm.G       # d q / d w, (n + 6, 6)
        A, self.sections, r0 = _Triplets(), {}, 0

        def section(name, m):
            nonlocal r0
            self.sections[name] = slice(r0, r0 + m)
            r0 += m
            return self.sections[name].start

        r = section("init", n)
        A.add(None, r, 0, np.eye(n))
        r = section("dynamics", N * n)
        for k in range(N):
            A.add(None, r + k * n, xi(k), pm.A)
            A.add(None, r + k * n, ui(k), pm.B)
            A.add(None, r + k * n, xi(k + 1), -np.eye(n))
        if lim.leg_min is not None or lim.leg_max is not None:
            for name, sign in (("stroke_lo", 1.0), ("stroke_hi", -1.0)):
                r = section(name, 6 * N)
                for k in range(N):
                    A.add("stroke", r + 6 * k, xi(k + 1), legs.length_q[k] / self.span)
                    A.add(None, r + 6 * k, si(k), np.full((6, 1), sign))
        if lim.axis is not None:
            r = section("force", 12 * N)
            for k in range(N):
                for end in (0, 1):
                    A.add("force", r + 12 * k + 6 * end, xi(k + end), np.zeros((6, NP)))
                    A.add("force", r + 12 * k + 6 * end, ui(k), np.zeros((6, NU)))
            r = section("voltage", 6 * N)
            for k in range(N):
                A.add("voltage", r + 6 * k, xi(k + 1), np.zeros((6, NP)))
                A.add("voltage", r + 6 * k, ui(k), np.zeros((6, NU)))
        if tilt_rate is not None:
            r = section("tilt_rate", 2 * N)
            for k in range(N):
                # roll and pitch rates, in units of the limit
                A.add(None, r + 2 * k, xi(k + 1) + 9, np.array([[1.0, 0.0]]) / tilt_rate)
                A.add(None, r + 2 * k + 1, xi(k + 1) + 10, np.array([[1.0]]) / tilt_rate)
        r = section("slack", N)
        A.add(None, r, self.ns0, np.eye(N))
        self.Atrip = A
        self.A = A.csc((r0, nz))
        self.m = r0
        self.l, self.u = np.full(self.m, -np.inf), np.full(self.m, np.inf)
        self.l[self.sections["slack"]] = 0.0
        self.q = np.zeros(nz)
        self.q[self.ns0:] = slack_weight[0]
        self.xi, self.ui = xi, ui
        self.solver = osqp.OSQP()
        self.solver.setup(self.P, self.q, self.A, self.l, self.u, verbose=False,
                          eps_abs=tolerance, eps_rel=tolerance, max_iter=max_iter,
                          warm_starting=True, **OSQP_SETTINGS)

    def solve(self, x0: np.ndarray, w: np.ndarray, xbar: np.ndarray, ubar: np.ndarray,
              start: LegLinearisation, end: LegLinearisation, vehicle_rate: np.ndarray):
        """One horizon: x0 the state now, w (N+1, 6) the known vestibular inputs, the leg rows
        linearised at the predicted (xbar (N+1, 12), ubar (N, 6)): `start` at (x_k, u_k) and
        `end` at (x_k+1, u_k), k = 0..N-1; vehicle_rate (N, 2) the vehicle's roll and pitch
        rates at k = 1..N."""
        pm, N, n, lim = self.pm, self.N, self.pm.n, self.lim
        q, l, u, S = self.q, self.l, self.u, self.sections
        for k in range(N + 1):
            g = self.grad @ w[k]
            q[self.xi(k):self.xi(k) + n] = g[:n]
            if k < N:
                q[self.ui(k):self.ui(k) + NU] = g[n:]
        l[S["init"]] = u[S["init"]] = x0
        l[S["dynamics"]] = u[S["dynamics"]] = -(w[:N] @ pm.E.T).ravel()
        if "stroke_lo" in S:
            # l(x) ~ l(xbar) + L_q (dq - dqbar) within [leg_min + margin, leg_max - margin]
            self.Atrip.refill("stroke", np.concatenate([end.length_q, end.length_q])
                              / self.span)
            base = end.lengths - np.einsum("kij,kj->ki", end.length_q, xbar[1:, :6])
            lo = -np.inf if lim.leg_min is None else lim.leg_min + self.margin["stroke"]
            hi = np.inf if lim.leg_max is None else lim.leg_max - self.margin["stroke"]
            l[S["stroke_lo"]] = (lo - base).ravel() / self.span
            u[S["stroke_hi"]] = (hi - base).ravel() / self.span
        if "force" in S:
            fmax = lim.force - self.margin["force"]
            vmax = lim.voltage - self.margin["voltage"]
            blocks, base = [], np.empty((N, 2, 6))
            for e, (lin, xs) in enumerate(((start, xbar[:-1]), (end, xbar[1:]))):
                base[:, e] = lin.sigma - np.einsum("kij,kj->ki", lin.sigma_x, xs) \
                    - np.einsum("kij,kj->ki", lin.sigma_u, ubar)
            for k in range(N):
                for lin in (start, end):
                    blocks += [lin.sigma_x[k] / lim.force, lin.sigma_u[k] / lim.force]
            self.Atrip.refill("force", blocks)
            l[S["force"]] = (-fmax - base).ravel() / lim.force
            u[S["force"]] = (fmax - base).ravel() / lim.force
            vbase = end.voltage - np.einsum("kij,kj->ki", end.voltage_x, xbar[1:]) \
                - np.einsum("kij,kj->ki", end.voltage_u, ubar)
            self.Atrip.refill("voltage", [b for k in range(N) for b in
                                          (end.voltage_x[k] / lim.voltage,
                                           end.voltage_u[k] / lim.voltage)])
            l[S["voltage"]] = (-vmax - vbase).ravel() / lim.voltage
            u[S["voltage"]] = (vmax - vbase).ravel() / lim.voltage
        if "tilt_rate" in S:
            l[S["tilt_rate"]] = (vehicle_rate / self.tilt_rate - 1.0).ravel()
            u[S["tilt_rate"]] = (vehicle_rate / self.tilt_rate + 1.0).ravel()
        self.solver.update(q=q, l=l, u=u, Ax=self.Atrip.csc_data())
        res = self.solver.solve(raise_error=False)   # warm-started from the previous solution
        if res.info.status == "solved" and res.info.status_polish != 1:
            # polishing (the exact solve on the active set) failed: the hard limits then hold
            # to the tolerance only, so the step is solved on from there, 10x tighter, for at
            # most REFINE_ITERATIONS more (kept if it gets there, else the first solution)
            self.solver.update_settings(eps_abs=self.tolerance / 10, eps_rel=self.tolerance / 10,
                                        max_iter=REFINE_ITERATIONS)
            refined = self.solver.solve(raise_error=False)
            self.solver.update_settings(eps_abs=self.tolerance, eps_rel=self.tolerance,
                                        max_iter=self.max_iter)
            if refined.info.status == "solved":
                return refined
        return res


@dataclass(frozen=True)
class OptimalResult:
    """The optimal cue on the motion's times, the applied plan on the MPC grid, the solver's
    record."""

    cue: Cue
    plan: Plan
    diagnostics: Diagnostics


def optimal_cue(model: Model, config: CueingConfig, motion: VehicleMotion, home, gravity, *,
                controller: ControllerConfig | None,
                options: OptimalOptions = OptimalOptions()) -> Cue:
    """The model-predictive cue (the same Cue as classical_washout gives): see the module doc."""
    return optimal_cueing(model, config, motion, home, gravity, controller=controller,
                          options=options).cue


def optimal_cueing(model: Model, config: CueingConfig, motion: VehicleMotion, home, gravity, *,
                   controller: ControllerConfig | None,
                   options: OptimalOptions = OptimalOptions(),
                   progress: Callable[[int, int], None] | None = None) -> OptimalResult:
    """The receding-horizon cue for a vehicle motion, with the plan and the solver's record:
    OptimalStepper stepped over the motion's MPC grid. `controller`: the scene's [controller]
    table (the drives' force and voltage limits; None: not imposed).

    The platform starts at rest at `home` with the perceived error's states at zero (both the
    vehicle and the platform perceive from rest). Each MPC step applies the first move of the
    horizon's optimum; a step OSQP does not solve applies the previous plan's next move (counted
    in the status). The Cue's `tilt` is the whole roll and pitch from home: the MPC does not
    split them into a tilt and a rotational channel. `progress(steps_done, steps)` is called
    after each MPC step."""
    clock = time.perf_counter()
    stepper = OptimalStepper(model, config, home, gravity, controller=controller, options=options)
    dt, N = stepper.dt, stepper.steps
    t = np.asarray(motion.t, dtype=float)
    M = max(1, int(np.ceil((t[-1] - t[0]) / dt - 1e-9)))
    edges = t[0] + dt * np.arange(M + N + 1)
    # Means of the deviation from rest, then rest added back: a vehicle at rest stays exactly
    # at rest through the sums (zero motion gives the neutral pose exactly).
    sampled = np.hstack([np.asarray(motion.specific_force, float),
                         np.asarray(motion.angular_velocity, float)]) - stepper.rest
    vehicle = interval_means(t, sampled, edges)
    record = {"dq": np.empty((M, 6)), "qd": np.empty((M, 6)), "qdd": np.empty((M, 6)),
              "it": np.zeros(M, int), "time": np.zeros(M), "slack": np.zeros(M),
              "error": np.empty((M, 6)), "polished": np.zeros(M, bool)}
    status = []
    for j in range(M):
        window = vehicle[j:j + N + 1] if options.preview else np.repeat(vehicle[j:j + 1], N + 1, 0)
        solution = stepper.solve(window)
        move = stepper.apply(solution, window[0])
        status.append(solution.status)
        record["it"][j], record["time"][j] = solution.iterations, solution.solve_time
        record["polished"][j], record["slack"][j] = solution.polished, solution.slack
        record["error"][j] = move.error
        if progress is not None:
            progress(j + 1, M)
        record["dq"][j], record["qd"][j], record["qdd"][j] = move.dq, move.qd, move.qdd
    plan = Plan(t[0] + dt * np.arange(M), record["dq"], record["qd"], record["qdd"])
    dq, qd, qdd = plan.sample(t)
    q = stepper.home + dq
    cue = Cue(t=t, q=q, qd=qd, qdd=qdd, tilt=dq[:, 3:5].copy())
    diag = Diagnostics(plan.t, record["it"], record["time"], tuple(status), record["polished"],
                       record["slack"], record["error"], stepper.limit_names,
                       time.perf_counter() - clock, stepper.variables, stepper.constraints)
    return OptimalResult(cue, plan, diag)


@dataclass(frozen=True)
class Solution:
    """One MPC step's QP, solved (OSQP's record) from the stepper's state at the time."""

    status: str              # OSQP's status
    iterations: int
    solve_time: float        # s, OSQP's own (refinement included)
    polished: bool           # solved exactly on its active set
    states: np.ndarray | None   # (N+1, n) the predicted states; None: not usable
    inputs: np.ndarray | None   # (N, 6) the planned accelerations; None: not usable
    slack: float             # stroke slack of the first step, m (0: not usable or kept)
    wall_time: float         # s, the whole step: linearisation, vectors and solve


@dataclass(frozen=True)
class Move:
    """The applied step: state at its start (dq, qd) and the acceleration held over it."""

    dq: np.ndarray      # (6,) pose minus home
    qd: np.ndarray      # (6,)
    qdd: np.ndarray     # (6,)
    error: np.ndarray   # (6,) perceived error predicted by the model over the step


@dataclass
class StepperState:
    """What one MPC step starts from: the state x (dq, qd, vestibular error states) and the
    prediction the leg rows are linearised on (the previous plan shifted by one step)."""

    x: np.ndarray    # (n,)
    X: np.ndarray    # (N+1, n)
    U: np.ndarray    # (N, 6)


class OptimalStepper:
    """The receding-horizon MPC one step at a time: the QP (built once, see the module doc) and
    the state. `step(window)` is one MPC step given the vehicle window; `solve` and `apply` are
    its two halves, apart so that a solve can run elsewhere (another process) and a late one
    be replaced by the previous plan (`apply(None, ...)`).

    A window is (steps + 1, 6): the vehicle's specific force and angular velocity minus rest
    (`rest`), zero-order-hold means over the MPC steps from now on."""

    def __init__(self, model: Model, config: CueingConfig, home, gravity, *,
                 controller: ControllerConfig | None,
                 options: OptimalOptions = OptimalOptions()):
        if not (options.rate > 0 and options.horizon > 0):
            raise StewartError(f"MPC rate and horizon must be > 0, got {options.rate}, "
                               f"{options.horizon}")
        self.model, self.options = model, options
        self.home = np.asarray(home, dtype=float)
        g = np.asarray(gravity, dtype=float)
        self.dt = 1.0 / options.rate
        # the QP's grid: `blocking` MPC steps per prediction step, the horizon in whole blocks
        self.blocking = r = options.blocking
        if not (isinstance(r, int) and r >= 1):
            raise StewartError(f"MPC blocking must be an integer >= 1, got {r!r}")
        blocks = max(1, round(options.horizon * options.rate / r))
        self.steps = N = blocks * r
        tilt_rate = options.tilt_rate_limit if options.tilt_rate_limit is not None \
            else config.tilt_rate_limit
        self.limits = lim = capability(model, controller)
        self.lin = linearise(self.home, g, config.head)
        thresholds = np.r_[OTOLITH_THRESHOLD, CANAL_THRESHOLD]
        self.pm = pm = prediction_model(self.lin, VESTIBULAR_CHANNELS, self.dt)
        grid = pm if r == 1 else prediction_model(self.lin, VESTIBULAR_CHANNELS, r * self.dt)
        weights = np.asarray(options.perception_weight, dtype=float) / thresholds**2
        state_weights = np.r_[options.position_weight, 0.0, 0.0, options.yaw_weight,
                              options.velocity_weight, options.rate_weight]
        input_weights = np.r_[options.acceleration_weight, options.angular_acceleration_weight]
        margins = {"stroke": options.stroke_margin,
                   "force": 0.0 if lim.force is None else options.force_margin * lim.force,
                   "voltage": 0.0 if lim.voltage is None else options.voltage_margin * lim.voltage}
        n = pm.n
        X = np.zeros((N + 1, n))          # the prediction the rows are linearised on
        U = np.zeros((N, NU))
        self._qp = _Qp(grid, lim, tilt_rate, leg_rows(model, lim, self.home, X[::r, :NP], U[::r])[1], blocks,
                       weights,
                       state_weights, input_weights, options.slack_weight, margins,
                       options.tolerance, options.max_iter, options.terminal_weight)
        self.state = StepperState(np.zeros(n), X, U)
        # the vehicle at rest as perception() takes it
        self.rest = np.r_[0.0, 0.0, np.linalg.norm(g), 0.0, 0.0, 0.0]
        self.limit_names = tuple(name for name, on in (
            ("stroke", lim.leg_min is not None or lim.leg_max is not None),
            ("force", lim.force is not None), ("voltage", lim.voltage is not None),
            ("tilt_rate", tilt_rate is not None)) if on)
        self.variables, self.constraints = self._qp.nz, self._qp.m

    def solve(self, window: np.ndarray) -> Solution:
        """The QP of the horizon from the current state, for the vehicle window; the state is
        not advanced (apply does that)."""
        clock = time.perf_counter()
        N, n, qp, lin, home = self.steps, self.pm.n, self._qp, self.lin, self.home
        window = np.asarray(window, dtype=float)
        if window.shape != (N + 1, 6):
            raise StewartError(f"MPC window must have shape ({N + 1}, 6), got {window.shape}")
        s, r = self.state, self.blocking
        s.X[0] = s.x
        # the QP's grid: every r-th point of the prediction, the window's means over each block
        X, U = s.X[::r], s.U[::r]
        if r > 1:
            window = np.vstack([window[:-1].reshape(qp.N, r, 6).mean(axis=1), window[-1:]])
        nonlinear = known_inputs(lin, home, X[:, :NP], U)
        w = np.vstack([nonlinear, nonlinear[-1:]]) - self.rest - window
        start, end = leg_rows(self.model, self.limits, home, X[:, :NP], U)
        res = qp.solve(s.x, w, X[:, :NP], U, start, end,
                       0.5 * (window[:-1, 3:5] + window[1:, 3:5]))
        z = res.x
        usable = res.info.status.startswith("solved") and np.all(np.isfinite(z))
        states = inputs = None
        if usable:
            states = z[:qp.nx].reshape(qp.N + 1, n)
            inputs = z[qp.nu0:qp.ns0].reshape(qp.N, NU)
            if r > 1:
                states, inputs = refine_plan(states, inputs, r, self.dt)
        return Solution(res.info.status, res.info.iter, res.info.solve_time,
                        res.info.status_polish == 1, states, inputs,
                        z[qp.ns0] * qp.span if usable else 0.0, time.perf_counter() - clock)

    def apply(self, solution: Solution | None, vehicle: np.ndarray) -> Move:
        """Apply the first move of `solution` (solved from the current state), or, when it is
        None or not usable, the previous plan's next move; advance the state over the step with
        the vehicle's motion minus rest over it, `vehicle` (6,)."""
        pm, lin, home, s = self.pm, self.lin, self.home, self.state
        x = s.x
        if solution is not None and solution.states is not None:
            Z, Uz = solution.states, solution.inputs
        else:   # keep flying the previous plan
            Z, Uz = s.X, s.U
        u0 = Uz[0]
        # the applied step, with its corrections taken on itself
        x_lin = pm.A @ x + pm.B @ u0
        step = np.vstack([x[:NP], x_lin[:NP]])
        w0 = known_inputs(lin, home, step, u0[None])[0] - self.rest - vehicle
        move = Move(x[:6].copy(), x[6:NP].copy(), u0.copy(), pm.C @ x + pm.D @ u0 + pm.G @ w0)
        # shift: the next step linearises on the rest of this plan
        self.state = StepperState(x_lin + pm.E @ w0, np.vstack([Z[1:], Z[-1:]]),
                                  np.vstack([Uz[1:], np.zeros((1, NU))]))
        return move

    def step(self, window: np.ndarray) -> tuple[Move, Solution]:
        """One MPC step: solve for the window, apply, advance."""
        solution = self.solve(window)
        return self.apply(solution, window[0]), solution


def refine_plan(states: np.ndarray, inputs: np.ndarray, r: int, dt: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """A plan on a grid of r MPC steps (states (B+1, n), inputs (B, 6)) on the MPC steps dt:
    each input held over its r steps, the pose and its rates integrated exactly within the
    block (held_move); the vestibular states, only ever a linearisation point, interpolated."""
    B = inputs.shape[0]
    fine_u = np.repeat(inputs, r, axis=0)
    frac = np.tile(np.arange(r) / r, B)[:, None]
    start = np.repeat(states[:-1], r, axis=0)
    fine = start + frac * (np.repeat(states[1:], r, axis=0) - start)
    fine[:, :6], fine[:, 6:NP], _ = held_move(start[:, :6], start[:, 6:NP], fine_u, frac * r * dt)
    return np.vstack([fine, states[-1:]]), fine_u


def known_inputs(lin: Linearisation, home: np.ndarray, xp: np.ndarray, u: np.ndarray
                 ) -> np.ndarray:
    """The vestibular input beyond its linear part on a platform trajectory xp (K+1, 12) =
    (dq, qd) at the step ends with u (K, 6) on the steps: delivered specific force (its neutral
    value included) and angular velocity minus their linearisation at home, the mean of both
    ends of each step, (K, 6). With the vehicle's motion subtracted this is the w of the
    prediction model: the tilt's sine and the yaw's mixing of the axes enter here."""
    dq, qd = xp[:, :6], xp[:, 6:NP]
    K = u.shape[0]
    w = np.zeros((K, 6))
    for sl in (slice(0, K), slice(1, K + 1)):
        f, om = delivered(home + dq[sl], qd[sl], u, lin.gravity, lin.head)
        w[:, :3] += 0.5 * (f - dq[sl] @ lin.force_q.T - u @ lin.force_qdd.T)
        w[:, 3:] += 0.5 * (om - qd[sl] @ lin.rate_qd.T)
    return w


def leg_rows(model: Model, lim: Capability, home: np.ndarray, xp: np.ndarray, u: np.ndarray
             ) -> tuple[LegLinearisation, LegLinearisation]:
    """The leg quantities linearised at the start (x_k, u_k) and the end (x_k+1, u_k) of each
    step of a predicted trajectory (xp (K+1, 12), u (K, 6))."""
    Q, QD = home + xp[:, :6], xp[:, 6:NP]
    both = leg_linearisation(model, lim.axis, np.vstack([Q[:-1], Q[1:]]),
                             np.vstack([QD[:-1], QD[1:]]), np.vstack([u, u]))
    K = u.shape[0]
    half = [LegLinearisation(*(None if a is None else a[sl] for a in vars(both).values()))
            for sl in (slice(0, K), slice(K, 2 * K))]
    return half[0], half[1]
