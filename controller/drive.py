"""One leg's drive as the paper's controller sees it: a DC servomotor, gearbox and rack and
pinion moving a constant load mass (the constant-load assumption of Section 4).

Leg coordinate x (m, the leg length), rack speed v = x', motor current i:

    L i' = V - R i - (Ke zeta / r) v
    (m_load + m_d) v' = (Kt zeta / r) i - c v         m_d = zeta^2 I / r^2

The constant load is derived from the Kane model: the largest diagonal entry of the leg-space
mass matrix [m] at home (what one actuator accelerates when the other five hold still), so the
design sees the platform and leg inertia but none of the coupling. A scene can give it instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from stewart_fmu.errors import SceneError
from stewart_fmu.kane_terms import mass_matrix
from stewart_fmu.model import Model, per_leg, rack_ratio

MOTOR_KEYS = ("resistance", "inductance", "torque_constant", "back_emf", "current_limit",
               "voltage_limit")


@dataclass(frozen=True)
class Motor:
    """DC servomotor: ohm, H, N m / A, V s / rad, A, V."""

    resistance: float
    inductance: float
    torque_constant: float
    back_emf: float
    current_limit: float
    voltage_limit: float


@dataclass(frozen=True)
class AxisModel:
    """Drive of one leg with its constant load."""

    motor: Motor
    gear_ratio: float
    pinion_radius: float
    rotor_inertia: float
    load_mass: float        # kg, the constant load (see the module doc)
    viscous: float          # N s / m, joint friction (0 without [friction])

    @property
    def force_constant(self) -> float:
        """Rack force per ampere, N / A: Kt zeta / r."""
        return self.motor.torque_constant * rack_ratio(self.gear_ratio, self.pinion_radius)

    @property
    def emf_constant(self) -> float:
        """Back-EMF per rack speed, V s / m: Ke zeta / r."""
        return self.motor.back_emf * rack_ratio(self.gear_ratio, self.pinion_radius)

    @property
    def reflected_mass(self) -> float:
        """m_d = zeta^2 I / r^2, kg."""
        return self.gear_ratio**2 * self.rotor_inertia / self.pinion_radius**2

    @property
    def moving_mass(self) -> float:
        return self.load_mass + self.reflected_mass

    @property
    def peak_force(self) -> float:
        """The most rack force the drive gives, N: Kf x the motor's current_limit."""
        return self.force_constant * self.motor.current_limit

    @property
    def no_load_speed(self) -> float:
        """The fastest the rack moves, m/s: the motor's voltage_limit / Ke' (no current, all
        the voltage against the back-EMF)."""
        return self.motor.voltage_limit / self.emf_constant

    @property
    def peak_acceleration(self) -> float:
        """The most the drive accelerates its constant load, m/s^2: peak_force / moving_mass."""
        return self.peak_force / self.moving_mass

    def voltage(self, current, current_rate, ldot):
        """The motor voltage that drives `current` changing at `current_rate` at rack speed
        `ldot`: R i + L di/dt + (Ke zeta / r) ldot (arrays or numbers)."""
        m = self.motor
        return m.resistance * current + m.inductance * current_rate + self.emf_constant * ldot

    def drive_for(self, t, force, ldot) -> tuple[np.ndarray, np.ndarray]:
        """(voltage, current) that deliver the rack forces `force` (N, 6) at rack speeds `ldot`
        sampled at times t: i = F / Kf and V = R i + L di/dt + Ke' ldot, di/dt by central
        differences over the samples."""
        current = force / self.force_constant
        di = np.gradient(force, t, axis=0) / self.force_constant
        return self.voltage(current, di, ldot), current

    def state_space(self) -> ct.StateSpace:
        """States (x, v, i), input voltage V, outputs (x, v)."""
        L, R = self.motor.inductance, self.motor.resistance
        m = self.moving_mass
        A = [[0, 1, 0], [0, -self.viscous / m, self.force_constant / m],
             [0, -self.emf_constant / L, -R / L]]
        return ct.ss(A, [[0], [0], [1 / L]], [[1, 0, 0], [0, 1, 0]], [[0], [0]],
                     inputs=["V"], outputs=["x", "v"], states=["x", "v", "i"], name="axis")

    def position_tf(self) -> ct.TransferFunction:
        """x(s) / V(s) = Kf / (s ((L s + R)(m s + c) + Kf Ke))."""
        L, R, m, c = self.motor.inductance, self.motor.resistance, self.moving_mass, self.viscous
        den = np.polymul([L, R], [m, c]) + np.r_[0, 0, self.force_constant * self.emf_constant]
        return ct.tf([self.force_constant], np.polymul(den, [1, 0]), inputs="V", outputs="x")


def constant_load(model: Model) -> float:
    """The largest diagonal entry of the Kane mass matrix [m] at home (kg), drives excluded."""
    return float(np.max(np.diag(mass_matrix(model, model.home))))


def axis_model(model: Model, motor: Motor, load_mass: float | None = None) -> AxisModel:
    """The drive of the scene's legs with its constant load (derived when not given). One
    model for all six axes: with per-leg values it is the conservative axis, the largest rotor
    inertia (the slowest leg) and the smallest viscous friction (the least damped)."""
    if model.drive is None:
        raise SceneError("drive", "the per-axis controller needs the scene's [drive] table")
    d = model.drive
    return AxisModel(motor, d.gear_ratio, d.pinion_radius, float(np.max(per_leg(d.rotor_inertia))),
                     constant_load(model) if load_mass is None else load_mass,
                     float(np.min(model.friction.viscous_legs)) if model.friction is not None else 0.0)
