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
  (never on roll and pitch: a sustained tilt is the cue of a sustained specific force), the
  input effort, and an exact penalty on the constraint slacks.
* Constraints, linearised at the neutral pose: the six leg lengths within the stroke minus a
  margin (l ~ l_home + L_q dq), the rack forces within Kf I_max (sigma ~ sigma_hold + S_q dq +
  S_v qd + S_a qdd, from stewart_fmu.dynamics.inverse_dynamics: every effect the scene declares),
  the drive voltage R sigma / Kf + Ke' ldot within V_max (controller.drive's motor; the inductive
  L di/dt is left out: with L/R = 10 ms on the shipped simulator it acts within one MPC step),
  forces and voltages at both ends of every step, and the tilt rate: the platform's roll and
  pitch rates may differ from the vehicle's by at most the tilt-rate limit (the rotation the
  occupant feels that the vehicle does not make stays below the canals' threshold).
* Non-linearity: each step evaluates the exact leg lengths, rack forces, voltages and delivered
  motion on the previous solution's prediction (shifted by one step) and adds the difference to
  the linear model as known offsets: one fixed-Jacobian SQP iteration per step. The QP's matrices
  are built once; per step only its vectors change (OSQP update + warm start). At a steady
  state the prediction is the state, so the steady state is exact: a sustained specific force f
  ends as the tilt asin(f / g), not its small-angle f / g.
* Stroke, force and voltage are soft (slack with a linear and a quadratic penalty, exact when
  the hard problem is feasible), so a step whose linear model cannot be met still has a
  solution; the slack used is reported. The tilt-rate limit is hard.
* Preview: with `preview=True` (default) the future vehicle motion over the horizon is known
  (a recorded motion, as in Garrett and Best's offline case); with False the current vehicle
  motion is held over the horizon (the real-time case of Dagdelen et al.).

The applied accelerations are integrated exactly (piecewise constant), so the returned q, qd,
qdd are consistent at any sample rate; the cue is resampled at the motion's own times.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp

from controller.config import controller_config
from controller.drive import AxisModel, axis_model
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import StewartError, StrokeLimitError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model

from .config import CueingConfig
from .motion import VehicleMotion
from .vestibular import ANGULAR_VELOCITY_THRESHOLD, CANAL, OTOLITH, SPECIFIC_FORCE_THRESHOLD
from .washout import Cue
from .mpc_model import NP, NU, Linearisation, PredictionModel, delivered, linearise, \
    prediction_model

VEHICLE_REST = np.array([0.0, 0.0, 9.81])  # the motion format's specific force at rest
VESTIBULAR_CHANNELS = (OTOLITH,) * 3 + (CANAL,) * 3
SOLVED = ("solved",)  # OSQP statuses whose solution is applied as is


@dataclass(frozen=True)
class OptimalOptions:
    """The MPC's rate, horizon, margins and weights (defaults: the shipped motion simulator).

    Weights are per unit of: position m, velocity m/s, yaw rad, angular rate rad/s,
    acceleration m/s^2, angular acceleration rad/s^2; the perceived error is counted in
    perception thresholds (its weight is `perception_weight` / threshold^2)."""

    rate: float = 20.0                 # Hz, MPC steps
    horizon: float = 2.0               # s
    preview: bool = True               # future vehicle motion known over the horizon
    stroke_margin: float = 0.02        # m, kept from each end of the stroke
    force_margin: float = 0.05         # fraction of Kf I_max kept free
    voltage_margin: float = 0.05       # fraction of V_max kept free
    tilt_rate_limit: float | None = None   # rad/s; None: the [cueing] table's
    perception_weight: tuple[float, float] = (1.0, 1.0)      # specific force, angular velocity
    position_weight: tuple[float, float, float] = (1.0, 1.0, 1.0)
    velocity_weight: tuple[float, float, float] = (1.0, 1.0, 1.0)
    yaw_weight: float = 1.0
    rate_weight: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acceleration_weight: tuple[float, float, float] = (0.01, 0.01, 0.01)
    angular_acceleration_weight: tuple[float, float, float] = (0.01, 0.01, 0.01)
    slack_weight: tuple[float, float] = (1e3, 1e3)   # linear, quadratic, per fraction of range
    tolerance: float = 1e-6            # OSQP eps_abs = eps_rel
    max_iter: int = 20000


@dataclass(frozen=True)
class Diagnostics:
    """How the receding-horizon solves went: per MPC step, and totals."""

    t: np.ndarray                    # (M,) MPC step times, s
    iterations: np.ndarray           # (M,) OSQP iterations
    solve_time: np.ndarray           # (M,) s, OSQP's own solve time
    status: tuple[str, ...]          # (M,) OSQP status of each step
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
        tau = (t - self.t[k])[:, None]
        a = self.qdd[k]
        return self.dq[k] + self.qd[k] * tau + 0.5 * a * tau**2, self.qd[k] + a * tau, a


@dataclass(frozen=True)
class Limits:
    """The mechanism's limits the MPC keeps (None: the scene does not declare it)."""

    leg_min: float | None
    leg_max: float | None
    force: float | None       # N, Kf I_max (rack force)
    voltage: float | None     # V
    axis: AxisModel | None
    tilt_rate: float | None   # rad/s


def mechanism_limits(model: Model, tilt_rate: float | None) -> Limits:
    """Stroke from [geometry]; force and voltage from [controller.motor] and [drive] when the
    scene has both (otherwise those limits are not imposed)."""
    axis = None
    if model.drive is not None and "controller" in model.extra:
        axis = axis_model(model, controller_config(model).motor)
    return Limits(model.leg_min, model.leg_max,
                  None if axis is None else axis.force_constant * axis.motor.current_limit,
                  None if axis is None else axis.motor.voltage_limit, axis, tilt_rate)


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


class _Qp:
    """The sparse QP of one horizon, built once; `solve` updates its vectors only.

    Variables z = (x_0..x_N, u_0..u_{N-1}, s_0..s_{N-1}); s_k = (stroke, force, voltage) slacks
    of step k (both ends of the step share them)."""

    def __init__(self, pm: PredictionModel, lin: Linearisation, lim: Limits, steps: int,
                 weights: np.ndarray, state_weights: np.ndarray, input_weights: np.ndarray,
                 slack_weight: tuple[float, float], margins: dict[str, float],
                 tolerance: float, max_iter: int):
        self.pm, self.lin, self.lim, self.N, self._margin = pm, lin, lim, steps, margins
        # Rows in units of their own range (stroke half-range, force and voltage limits), so
        # the slacks are fractions and OSQP sees rows of one size.
        span = (lim.leg_max - lim.leg_min) / 2 if None not in (lim.leg_min, lim.leg_max) else 1.0
        self.scale = np.array([span, lim.force or 1.0, lim.voltage or 1.0])
        n, N = pm.n, steps
        self.nx, self.nu0, self.ns0 = (N + 1) * n, (N + 1) * n, (N + 1) * n + N * NU
        nz = self.ns0 + N
        self.nz = nz
        xi = (lambda k: k * n)
        ui = (lambda k: self.nu0 + k * NU)
        si = (lambda k: self.ns0 + k)
        W = np.diag(weights)
        Cy, Dy = pm.C, pm.D
        P = sp.lil_matrix((nz, nz))
        for k in range(N + 1):
            Qx = Cy.T @ W @ Cy
            Qx[:NP, :NP] += np.diag(state_weights)
            P[xi(k):xi(k) + n, xi(k):xi(k) + n] = Qx
            if k < N:
                P[ui(k):ui(k) + NU, ui(k):ui(k) + NU] = Dy.T @ W @ Dy + np.diag(input_weights)
                P[xi(k):xi(k) + n, ui(k):ui(k) + NU] = Cy.T @ W @ Dy
                P[ui(k):ui(k) + NU, xi(k):xi(k) + n] = Dy.T @ W @ Cy
                P[si(k), si(k)] = slack_weight[1]
        self.P = sp.triu(P.tocsc(), format="csc")
        self._grad = np.hstack([Cy, Dy]).T @ W @ pm.G       # (n + 6, 6): d q / d w
        self._slack_lin = slack_weight[0]
        A_blocks, self.sections = [], {}
        r0 = 0

        def add(name, mat):
            nonlocal r0
            A_blocks.append(mat)
            self.sections[name] = slice(r0, r0 + mat.shape[0])
            r0 += mat.shape[0]

        def block(m):
            return sp.lil_matrix((m, nz))

        B0 = block(n)
        B0[:, 0:n] = np.eye(n)
        add("init", B0)
        Bd = block(N * n)
        for k in range(N):
            Bd[k * n:(k + 1) * n, xi(k):xi(k) + n] = pm.A
            Bd[k * n:(k + 1) * n, ui(k):ui(k) + NU] = pm.B
            Bd[k * n:(k + 1) * n, xi(k + 1):xi(k + 1) + n] = -np.eye(n)
        add("dynamics", Bd)
        Lq = lin.length_q
        if lim.leg_min is not None or lim.leg_max is not None:
            lo, hi = block(6 * N), block(6 * N)
            for k in range(N):
                for M in (lo, hi):
                    M[6 * k:6 * k + 6, xi(k + 1):xi(k + 1) + 6] = Lq / self.scale[0]
                lo[6 * k:6 * k + 6, si(k)] = 1.0
                hi[6 * k:6 * k + 6, si(k)] = -1.0
            add("stroke_lo", lo)
            add("stroke_hi", hi)
        if lim.axis is not None:
            ax = lim.axis
            # rack force and voltage as linear maps of (dq, qd) and u
            Fx = np.hstack([lin.sigma_q, lin.sigma_qd])
            Fu = lin.sigma_qdd
            Vx = ax.motor.resistance / ax.force_constant * Fx
            Vx[:, 6:] += ax.emf_constant * Lq
            Vu = ax.motor.resistance / ax.force_constant * Fu
            Bf, Bv = block(12 * N), block(6 * N)
            for k in range(N):
                for end in (0, 1):
                    r = 12 * k + 6 * end
                    Bf[r:r + 6, xi(k + end):xi(k + end) + NP] = Fx / self.scale[1]
                    Bf[r:r + 6, ui(k):ui(k) + NU] = Fu / self.scale[1]
                Bv[6 * k:6 * k + 6, xi(k + 1):xi(k + 1) + NP] = Vx / self.scale[2]
                Bv[6 * k:6 * k + 6, ui(k):ui(k) + NU] = Vu / self.scale[2]
            add("force", Bf)
            add("voltage", Bv)
        if lim.tilt_rate is not None:
            Bt = block(2 * N)
            for k in range(N):
                Bt[2 * k, xi(k + 1) + 9] = 1.0     # roll rate  thx'
                Bt[2 * k + 1, xi(k + 1) + 10] = 1.0  # pitch rate thy'
            add("tilt_rate", Bt)
        Bs = block(N)
        Bs[:, self.ns0:] = np.eye(N)
        add("slack", Bs)
        self.A = sp.vstack([b.tocsr() for b in A_blocks]).tocsc()
        self.m = self.A.shape[0]
        self.l = np.full(self.m, -np.inf)
        self.u = np.full(self.m, np.inf)
        self.l[self.sections["slack"]] = 0.0
        self.q = np.zeros(nz)
        self.q[self.ns0:] = self._slack_lin
        self.solver = osqp.OSQP()
        self.solver.setup(self.P, self.q, self.A, self.l, self.u, verbose=False, polishing=True,
                          eps_abs=tolerance, eps_rel=tolerance, max_iter=max_iter,
                          warm_starting=True)
        self.xi, self.ui, self.si = xi, ui, si

    def shift(self, z: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The solution (z, y) moved one step on: the warm start of the next horizon, the last
        step repeated (its input set to zero)."""
        n, N = self.pm.n, self.N
        X = z[:self.nx].reshape(N + 1, n)
        U = z[self.nu0:self.ns0].reshape(N, NU)
        S = z[self.ns0:]
        zs = np.r_[X[1:].ravel(), X[-1], U[1:].ravel(), np.zeros(NU), S[1:], 0.0]
        ys = y.copy()
        for name, sl in self.sections.items():
            if name == "init":
                continue
            per = (sl.stop - sl.start) // N
            part = y[sl]
            ys[sl] = np.r_[part[per:], part[-per:]]
        return zs, ys

    def solve(self, x0: np.ndarray, w: np.ndarray, offsets: dict[str, np.ndarray],
              vehicle_rate: np.ndarray, guess: tuple[np.ndarray, np.ndarray] | None):
        """One horizon: x0 the state now, w (N+1, 6) the known inputs, offsets the non-linear
        corrections ('length' (N, 6) at k=1..N, 'force', 'voltage' (N, 2, 6) at both ends),
        vehicle_rate (N, 2) the vehicle's roll and pitch rates at k=1..N."""
        pm, N, n, lim, lin = self.pm, self.N, self.pm.n, self.lim, self.lin
        q, l, u = self.q, self.l, self.u
        for k in range(N + 1):
            g = self._grad @ w[k]
            q[self.xi(k):self.xi(k) + n] = g[:n]
            if k < N:
                q[self.ui(k):self.ui(k) + NU] = g[n:]
        S = self.sections
        l[S["init"]] = u[S["init"]] = x0
        rhs = -(w[:N] @ pm.E.T).ravel()
        l[S["dynamics"]] = u[S["dynamics"]] = rhs
        if "stroke_lo" in S:
            base = lin.lengths + offsets["length"]
            lo = -np.inf if lim.leg_min is None else lim.leg_min + self._margin["stroke"]
            hi = np.inf if lim.leg_max is None else lim.leg_max - self._margin["stroke"]
            l[S["stroke_lo"]] = (lo - base).ravel() / self.scale[0]
            u[S["stroke_hi"]] = (hi - base).ravel() / self.scale[0]
        if "force" in S:
            hold = lin.sigma_hold
            fmax = lim.force - self._margin["force"]
            l[S["force"]] = (-fmax - hold - offsets["force"]).ravel() / self.scale[1]
            u[S["force"]] = (fmax - hold - offsets["force"]).ravel() / self.scale[1]
            ax = lim.axis
            vhold = ax.motor.resistance / ax.force_constant * hold
            vmax = lim.voltage - self._margin["voltage"]
            l[S["voltage"]] = (-vmax - vhold - offsets["voltage"][:, 1]).ravel() / self.scale[2]
            u[S["voltage"]] = (vmax - vhold - offsets["voltage"][:, 1]).ravel() / self.scale[2]
        if "tilt_rate" in S:
            l[S["tilt_rate"]] = (vehicle_rate - lim.tilt_rate).ravel()
            u[S["tilt_rate"]] = (vehicle_rate + lim.tilt_rate).ravel()
        self.solver.update(q=q, l=l, u=u)
        if guess is not None:
            self.solver.warm_start(x=guess[0], y=guess[1])
        return self.solver.solve()


@dataclass(frozen=True)
class OptimalResult:
    """The optimal cue on the motion's times, the applied plan on the MPC grid, the solver's
    record."""

    cue: Cue
    plan: Plan
    diagnostics: Diagnostics


def optimal_cue(model: Model, config: CueingConfig, motion: VehicleMotion, home, gravity, *,
                options: OptimalOptions = OptimalOptions()) -> Cue:
    """The model-predictive cue (the same Cue as classical_washout gives): see the module doc."""
    return optimal_cueing(model, config, motion, home, gravity, options=options).cue


def optimal_cueing(model: Model, config: CueingConfig, motion: VehicleMotion, home, gravity, *,
                   options: OptimalOptions = OptimalOptions()) -> OptimalResult:
    """The receding-horizon cue for a vehicle motion, with the plan and the solver's record.

    The platform starts at rest at `home` with the perceived error's states at zero (both the
    vehicle and the platform perceive from rest). Each MPC step applies the first move of the
    horizon's optimum; a step OSQP does not solve applies the previous plan's next move (counted
    in the status)."""
    start = time.perf_counter()
    if not (options.rate > 0 and options.horizon > 0):
        raise StewartError(f"MPC rate and horizon must be > 0, got {options.rate}, {options.horizon}")
    home, g = np.asarray(home, dtype=float), np.asarray(gravity, dtype=float)
    dt = 1.0 / options.rate
    N = max(1, int(round(options.horizon * options.rate)))
    t = np.asarray(motion.t, dtype=float)
    M = max(1, int(np.ceil((t[-1] - t[0]) / dt - 1e-9)))
    tilt_rate = options.tilt_rate_limit if options.tilt_rate_limit is not None \
        else config.tilt_rate_limit
    lim = mechanism_limits(model, tilt_rate)
    lin = linearise(model, home, g)
    thresholds = np.r_[SPECIFIC_FORCE_THRESHOLD, ANGULAR_VELOCITY_THRESHOLD]
    pm = prediction_model(lin, VESTIBULAR_CHANNELS, dt)
    pw = options.perception_weight
    weights = np.r_[np.full(3, pw[0]), np.full(3, pw[1])] / thresholds**2
    state_weights = np.r_[options.position_weight, 0.0, 0.0, options.yaw_weight,
                          options.velocity_weight, options.rate_weight]
    input_weights = np.r_[options.acceleration_weight, options.angular_acceleration_weight]
    margins = {"stroke": options.stroke_margin,
               "force": 0.0 if lim.force is None else options.force_margin * lim.force,
               "voltage": 0.0 if lim.voltage is None else options.voltage_margin * lim.voltage}
    qp = _Qp(pm, lin, lim, N, weights, state_weights, input_weights, options.slack_weight,
             margins, options.tolerance, options.max_iter)
    edges = t[0] + dt * np.arange(M + N + 1)
    # Means of the deviation from rest, then rest added back: a vehicle at rest stays exactly
    # at rest through the sums (zero motion gives the neutral pose exactly).
    rest = np.r_[VEHICLE_REST, 0.0, 0.0, 0.0]
    sampled = np.hstack([np.asarray(motion.specific_force, float),
                         np.asarray(motion.angular_velocity, float)]) - rest
    vehicle = interval_means(t, sampled, edges)
    n = pm.n
    x = np.zeros(n)
    X = np.zeros((N + 1, n))          # the prediction the corrections are taken on
    U = np.zeros((N, NU))
    guess = None
    record = {"dq": np.empty((M, 6)), "qd": np.empty((M, 6)), "qdd": np.empty((M, 6)),
              "it": np.zeros(M, int), "time": np.zeros(M), "slack": np.zeros(M),
              "error": np.empty((M, 6))}
    status = []
    for j in range(M):
        window = vehicle[j:j + N + 1] if options.preview else np.repeat(vehicle[j:j + 1], N + 1, 0)
        X[0] = x
        offsets, nonlinear = corrections(model, lin, lim, home, X[:, :NP], U)
        w = np.vstack([nonlinear, nonlinear[-1:]]) - rest - window
        res = qp.solve(x, w, offsets, 0.5 * (window[:-1, 3:5] + window[1:, 3:5]), guess)
        status.append(res.info.status)
        record["it"][j], record["time"][j] = res.info.iter, res.info.solve_time
        z = res.x
        usable = res.info.status.startswith("solved") and np.all(np.isfinite(z))
        if usable:
            Z = z[:qp.nx].reshape(N + 1, n)
            Uz = z[qp.nu0:qp.ns0].reshape(N, NU)
            record["slack"][j] = z[qp.ns0] * qp.scale[0]
            guess = qp.shift(z, res.y)
        else:   # keep flying the previous plan
            Z, Uz = X, U
            guess = None
        u0 = Uz[0]
        # the applied step, with its corrections taken on itself
        x_lin = pm.A @ x + pm.B @ u0
        step = np.vstack([x[:NP], x_lin[:NP]])
        _, w0 = corrections(model, lin, lim, home, step, u0[None])
        w0 = w0[0] - rest - vehicle[j]
        record["error"][j] = pm.C @ x + pm.D @ u0 + pm.G @ w0
        record["dq"][j], record["qd"][j], record["qdd"][j] = x[:6], x[6:NP], u0
        x = x_lin + pm.E @ w0
        # shift: the next step's prediction and warm start
        X = np.vstack([Z[1:], Z[-1:]])
        U = np.vstack([Uz[1:], np.zeros((1, NU))])
    plan = Plan(t[0] + dt * np.arange(M), record["dq"], record["qd"], record["qdd"])
    dq, qd, qdd = plan.sample(t)
    q = home + dq
    cue = Cue(t=t, q=q, qd=qd, qdd=qdd, tilt=q[:, 3:5].copy())
    limits = tuple(name for name, on in (
        ("stroke", lim.leg_min is not None or lim.leg_max is not None),
        ("force", lim.force is not None), ("voltage", lim.voltage is not None),
        ("tilt_rate", lim.tilt_rate is not None)) if on)
    diag = Diagnostics(plan.t, record["it"], record["time"], tuple(status), record["slack"],
                       record["error"], limits, time.perf_counter() - start, qp.nz, qp.m)
    return OptimalResult(cue, plan, diag)


def corrections(model: Model, lin: Linearisation, lim: Limits, home: np.ndarray,
                xp: np.ndarray, u: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The non-linear remainders on a predicted platform trajectory xp (K+1, 12) = (dq, qd) at
    the step ends and u (K, 6) on the steps: exact minus linearised leg lengths (K, 6) at
    k = 1..K, rack forces and voltages (K, 2, 6) at both ends of each step, and the known
    vestibular input (K, 6): delivered specific force (its neutral value included) and angular
    velocity beyond their linear part, the mean of both ends of the step.

    Poses outside the stroke (a prediction that used slack) keep the linear force model there:
    the inverse dynamics refuses them."""
    dq, qd = xp[:, :6], xp[:, 6:NP]
    K = u.shape[0]
    Q = home + dq
    kin = inverse_kinematics(model, Q, qd, with_cond=False)
    offsets = {"length": kin.lengths[1:] - (lin.lengths + dq[1:] @ lin.length_q.T)}
    ends = (slice(0, K), slice(1, K + 1))
    if lim.axis is not None:
        ax = lim.axis
        force, volt = np.zeros((K, 2, 6)), np.zeros((K, 2, 6))
        lo = -np.inf if lim.leg_min is None else lim.leg_min
        hi = np.inf if lim.leg_max is None else lim.leg_max
        inside = np.all((kin.lengths >= lo) & (kin.lengths <= hi), axis=1)
        for e, sl in enumerate(ends):
            ok = np.flatnonzero(inside[sl])
            if ok.size == 0:
                continue
            qs, qds = Q[sl][ok], qd[sl][ok]
            try:
                sigma = inverse_dynamics(model, qs, qds, u[ok])
            except StrokeLimitError:   # a pose on the stroke's edge: linear model there
                continue
            lin_sigma = (lin.sigma_hold + dq[sl][ok] @ lin.sigma_q.T + qds @ lin.sigma_qd.T
                         + u[ok] @ lin.sigma_qdd.T)
            force[ok, e] = sigma - lin_sigma
            rates = kin.rates[sl][ok]
            exact_v = ax.voltage(sigma / ax.force_constant, 0.0, rates)
            lin_v = (ax.motor.resistance / ax.force_constant * lin_sigma
                     + ax.emf_constant * (qds @ lin.length_q.T))
            volt[ok, e] = exact_v - lin_v
        offsets["force"], offsets["voltage"] = force, volt
    w = np.zeros((K, 6))
    for sl in ends:
        f, om = delivered(Q[sl], qd[sl], u, lin.gravity)
        w[:, :3] += 0.5 * (f - dq[sl] @ lin.force_q.T - u @ lin.force_qdd.T)
        w[:, 3:] += 0.5 * (om - qd[sl] @ lin.rate_qd.T)
    return offsets, w
