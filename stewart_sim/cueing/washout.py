"""The classical washout: vehicle specific force and angular velocity -> platform pose.

Reid, L. D. and Nahon, M. A., "Flight simulation motion-base drive algorithms", Parts 1-3,
UTIAS Reports, University of Toronto (1985-86); Nahon, M. A. and Reid, L. D., "Simulator
motion-drive algorithms: a designer's perspective", J. Guidance, Control, and Dynamics 13(2),
1990.
Three channels, as there:

- translational: the specific force's deviation from rest is scaled and limited per axis,
  rotated into the inertial frame with the platform's orientation, gravity added back
  (a = R f_s + g, zero at rest), high-passed (second order s^2 / (s^2 + 2 zeta w s + w^2), or
  third order with the extra first-order factor s / (s + w_b) that washes the position back to
  zero under a sustained input) and integrated twice to the platform position;
- tilt coordination: the scaled specific force (x, y) is low-passed (second order) and
  turned into the pitch and roll at which gravity alone gives it in the platform's frame,
  rate-limited (tilt_rate_limit, below the tilt-rate perception threshold) and limited in
  angle;
- rotational: the angular velocity is scaled and limited per axis, high-passed (first or
  second order), turned into Euler-angle rates with the platform's (total) Euler angles and
  integrated; the tilt is added.

Signs, with the contract's R = Rz(thz) Ry(thy) Rx(thx): a platform at rest with orientation R
has the specific force R^T (-g) = g (-sin thy, cos thy sin thx, cos thy cos thx) in its own
frame. A sustained forward acceleration (f_x > 0: the seat pushes the occupant forward) is
therefore given by thy = -asin(f_x / g) (nose UP: thy > 0 tips the x axis down), a leftward
one (f_y > 0) by thx = +asin(f_y / g) (right side down). The classical algorithm takes the two
separately (the delivered lateral specific force is f_y cos(thy), a second-order difference).

Discrete time: every linear filter is propagated exactly for the input interpolated linearly
between samples (filters.py); position, velocity and acceleration, angular velocity and its
derivative are the filters' own states. The angular velocity's derivative takes the input's
slope from the samples up to t_k (a second-order backward difference), so that the whole
washout is causal (washout_step.py says why). The Euler-angle kinematics thetadot = T(theta) w
is nonlinear and integrated with Heun's method (the trapezoidal rule with an Euler predictor,
second order); the stored rates are re-evaluated at the corrected angles, so q is the
trapezoidal integral of qd. The tilt follows its command exactly while the command's rate is
within the limit; otherwise it moves at the limit rate (rate +-limit, acceleration 0). With
[cueing] position_limit the translational position goes through a smooth saturation
(washout_step.soft_limit). The computation is washout_step.WashoutStepper's, one sample at a
time: the offline cue is its loop, so a live loop stepping it gives the same cue.

The vehicle is taken to be at rest before t[0] (all filters start at zero state); the vehicle
frame is aligned with the platform at its neutral pose (home). The cue's angles are added to
home's, as the contract adds pose coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_sim.scene.cueing_config import CueingConfig
from .motion import VehicleMotion
from .washout_step import WashoutStepper


@dataclass(frozen=True)
class Cue:
    """The platform trajectory a washout asks for, in the contract's pose coordinates."""

    t: np.ndarray      # (N,) s
    q: np.ndarray      # (N, 6) absolute platform pose (home + cue), m and rad
    qd: np.ndarray     # (N, 6) its derivative (Euler-angle rates for the angles)
    qdd: np.ndarray    # (N, 6)
    tilt: np.ndarray   # (N, 2) the tilt-coordination part of (roll, pitch), rad


def classical_washout(config: CueingConfig, motion: VehicleMotion, home: np.ndarray,
                      gravity: np.ndarray) -> Cue:
    """The classical washout (Reid & Nahon 1985) of a vehicle motion: the platform pose, rates
    and accelerations at the motion's samples (see the module doc for the algorithm)."""
    t = np.asarray(motion.t, dtype=float)
    h = float((t[-1] - t[0]) / (t.size - 1))
    stepper = WashoutStepper(config, home, gravity, h, start=float(t[0]))
    rows = [stepper.step_row(f, w) for f, w in
            zip(np.asarray(motion.specific_force, dtype=float).tolist(),
                np.asarray(motion.angular_velocity, dtype=float).tolist())]
    q, qd, qdd, tilt = (np.array([row[i] for row in rows]) for i in range(4))
    return Cue(t=t, q=np.asarray(home, dtype=float) + q, qd=qd, qdd=qdd, tilt=tilt)
