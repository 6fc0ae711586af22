"""The six axis controllers at run time and the drive electronics they command.

`AxisControllers` is the discrete form of the design (design.py) for all six legs at once:
V = Kp e + Ki int(e) + Kd (ldot_ref - ldot) + V_ff, clipped to the voltage limit, with
conditional integration as anti-windup (the integral stops while the output is saturated and
the error would drive it further). The derivative acts on the measured leg rate, so no
derivative filter is needed and the discrete controller differs from the continuous one only by
the sampling of the integral and the zero-order hold.

`MotorCurrents` integrates each motor's current exactly over a step with the voltage and the
leg rate held (first-order ODE), clamps it at the current limit, and returns the step's mean
torque, which the plant receives as its motor-torque input.
"""
from __future__ import annotations

import numpy as np

from .design import PidGains
from .drive import AxisModel


class AxisControllers:
    """Six PID position loops with saturation and anti-windup."""

    def __init__(self, gains: PidGains, axis: AxisModel, dt: float):
        self.gains, self.axis, self.dt = gains, axis, dt
        self.integral = np.zeros(6)

    def reset(self) -> None:
        self.integral[:] = 0.0

    def step(self, l_ref: np.ndarray, ldot_ref: np.ndarray, l: np.ndarray, ldot: np.ndarray,
             v_ff: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Voltages for this sample and which axes are saturated."""
        g, vmax = self.gains, self.axis.motor.voltage_limit
        e = l_ref - l
        v = g.kp * e + g.ki * self.integral + g.kd * (ldot_ref - ldot) + v_ff
        out = np.clip(v, -vmax, vmax)
        saturated = out != v
        winding = saturated & (np.sign(e) == np.sign(v))
        self.integral += np.where(winding, 0.0, e * self.dt)
        return out, saturated


class MotorCurrents:
    """Motor current of each leg: L i' = V - R i - Ke' ldot, exact over a held step."""

    def __init__(self, axis: AxisModel, dt: float):
        m = axis.motor
        self.axis, self.dt = axis, dt
        self.decay = np.exp(-m.resistance * dt / m.inductance)
        # mean of exp(-t R / L) over the step
        self.mean_decay = (1.0 - self.decay) * m.inductance / (m.resistance * dt)
        self.current = np.zeros(6)

    def reset(self) -> None:
        self.current[:] = 0.0

    def step(self, voltage: np.ndarray, ldot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance the currents; returns (mean motor torque over the step, current-limited axes)."""
        m = self.axis.motor
        steady = (voltage - self.axis.emf_constant * ldot) / m.resistance
        gap = self.current - steady
        mean = steady + gap * self.mean_decay
        end = steady + gap * self.decay
        limited = np.abs(mean) > m.current_limit
        self.current = np.clip(end, -m.current_limit, m.current_limit)
        return m.torque_constant * np.clip(mean, -m.current_limit, m.current_limit), limited

    def voltage_for(self, current: np.ndarray, current_rate: np.ndarray,
                    ldot: np.ndarray) -> np.ndarray:
        """The voltage that makes the current follow a given path (for feedforward)."""
        m = self.axis.motor
        return m.resistance * current + m.inductance * current_rate + self.axis.emf_constant * ldot
