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

`servo_step` is one servo sample of the six drives (the PID voltages, then the currents over
the sample): the master's Python loop (controller.cosim, e.g. around an FMU) and the emulated
device (hil.servo) both take their sample from it. The arithmetic lives in two C functions
(controller/native/axis.c: `pid_voltages`, `advance_currents`) shared by these classes and by the
master's C loop (`closed_loop_run`), so every loop computes the same numbers.
"""
from __future__ import annotations

import numpy as np

from .design import PidGains
from .drive import AxisModel
from .native._axis import ffi, lib

_buf = ffi.from_buffer


def _f64(a: np.ndarray) -> np.ndarray:
    """a itself when it is C-contiguous float64 (the C side updates it in place), else a copy."""
    return np.ascontiguousarray(a, dtype=np.float64)


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
        g = self.gains
        v, sat = np.empty(6), np.empty(6, dtype=np.bool_)
        self.integral = _f64(self.integral)
        lib.pid_voltages(g.kp, g.ki, g.kd, self.axis.motor.voltage_limit, self.dt,
                         _buf(self.integral), _buf(_f64(l_ref)), _buf(_f64(ldot_ref)),
                         _buf(_f64(l)), _buf(_f64(ldot)), _buf(_f64(v_ff)), _buf(v), _buf(sat))
        return v, sat


class MotorCurrents:
    """Motor current of each leg: L i' = V - R i - Ke' ldot, exact over a held step."""

    def __init__(self, axis: AxisModel, dt: float):
        m = axis.motor
        self.axis, self.dt = axis, dt
        self.decay = float(np.exp(-m.resistance * dt / m.inductance))
        # mean of exp(-t R / L) over the step
        self.mean_decay = (1.0 - self.decay) * m.inductance / (m.resistance * dt)
        self.current = np.zeros(6)

    def reset(self) -> None:
        self.current[:] = 0.0

    def step(self, voltage: np.ndarray, ldot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance the currents; returns (mean motor torque over the step, current-limited axes)."""
        m = self.axis.motor
        torque, limited = np.empty(6), np.empty(6, dtype=np.bool_)
        self.current = _f64(self.current)
        lib.advance_currents(m.resistance, m.torque_constant, self.axis.emf_constant,
                             m.current_limit, self.decay, self.mean_decay, _buf(self.current),
                             _buf(_f64(voltage)), _buf(_f64(ldot)), _buf(torque), _buf(limited))
        return torque, limited


def servo_step(ctrl: AxisControllers, motors: MotorCurrents, l_ref: np.ndarray,
               ldot_ref: np.ndarray, l: np.ndarray, ldot: np.ndarray,
               v_ff: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One servo sample from the measured leg lengths and rates: (the voltages, the mean motor
    torques over the sample, the axes saturated in voltage or limited in current)."""
    v, sat = ctrl.step(l_ref, ldot_ref, l, ldot, v_ff)
    torque, limited = motors.step(v, ldot)
    return v, torque, sat | limited
