"""Feedforward of the axis controllers: the force the drives should supply (Kane inverse
dynamics or the constant load), its voltage, and the bumpless start at the first pose."""
from __future__ import annotations

import numpy as np

from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.model import Model

from .config import ControllerConfig
from .design import PidGains
from .drive import AxisModel
from .trajectory import LegReferences, Trajectory


def feedforward_force(model: Model, config: ControllerConfig, axis: AxisModel,
                      traj: Trajectory, refs: LegReferences) -> np.ndarray | None:
    """Leg forces the feedforward of config.feedforward supplies (None: no feedforward)."""
    if config.feedforward == "kane":
        return inverse_dynamics(model, traj.q, traj.qd, traj.qdd)
    if config.feedforward == "constant_load":
        return axis.moving_mass * refs.lddot + axis.viscous * refs.ldot
    return None


def feedforward_voltage(model: Model, config: ControllerConfig, axis: AxisModel,
                        traj: Trajectory, refs: LegReferences) -> tuple[np.ndarray, np.ndarray]:
    """(voltage, current) feedforward per sample: R i + L di/dt + Ke' ldot_ref for the
    feedforward force's current i = F / Kf (the device computes the same from F and dF/dt)."""
    force = feedforward_force(model, config, axis, traj, refs)
    if force is None:
        return np.zeros_like(refs.l), np.zeros_like(refs.l)
    return axis.drive_for(traj.t, force, refs.ldot)


def equilibrium(model: Model, q0: np.ndarray, qd0: np.ndarray, ldot_ref0: np.ndarray,
                i_ff0: np.ndarray, gains: PidGains, axis: AxisModel) -> tuple[np.ndarray, np.ndarray]:
    """(motor currents, PID integrals) of the drives holding the platform at q0 before the move
    (bumpless start): the integral supplies what the feedforward's resistive and back-EMF parts
    (of i_ff0 at ldot_ref0) do not, so the feedforward's inductive part (L di/dt) still reaches
    the motor from the first sample."""
    hold = inverse_dynamics(model, q0, qd0, np.zeros(6))
    current = hold / axis.force_constant
    v_hold = axis.voltage(current, 0.0, 0.0)
    v_static = axis.voltage(i_ff0, 0.0, ldot_ref0)
    integral = (v_hold - v_static) / gains.ki if gains.ki > 0 else np.zeros(6)
    return current, integral


def start_at_equilibrium(model, traj, refs, gains, ctrl, motors, i_ff0, plant) -> None:
    """The controllers and drives at their equilibrium at the first pose (equilibrium), and
    the plant, when given, started there holding the same torques."""
    motors.current, ctrl.integral = equilibrium(model, traj.q[0], traj.qd[0], refs.ldot[0], i_ff0,
                                                gains, motors.axis)
    if plant is not None:
        plant.start(traj.q[0], traj.qd[0], float(traj.t[0]),
                    motors.current * motors.axis.motor.torque_constant)
