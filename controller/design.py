"""Per-axis controller design with python-control: a PID on leg position (the derivative acting
on the measured leg rate) tuned to a crossover frequency and phase margin, and its analysis.

C(s) = Kp + Ki / s + Kd s, with the integral zero a fixed fraction of the crossover
(Ki = Kp wc / INTEGRAL_RATIO). Kp and Kd then follow from the two real equations
C(j wc) P(j wc) = exp(j (PM - 180 deg)). Where the plant already has more phase than the margin
needs (the motor's back-EMF damping makes it an integrator below its mechanical pole), that
gives Kd < 0: the design is then a PI (Kd = 0) with Kp and Ki from the same two equations.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import control as ct
import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.model import Model

from .config import ControllerConfig, scene_axis
from .drive import AxisModel

INTEGRAL_RATIO = 10.0


class DesignError(StewartError):
    """The requested bandwidth and phase margin cannot be met by this controller structure."""


@dataclass(frozen=True)
class PidGains:
    """V / m, V / (m s), V s / m."""

    kp: float
    ki: float
    kd: float

    def tf(self) -> ct.TransferFunction:
        return ct.tf([self.kd, self.kp, self.ki], [1, 0])


@dataclass(frozen=True)
class Analysis:
    """Margins and step response of the constant-load loop (continuous time)."""

    gain_margin_db: float      # inf when the phase never crosses -180 deg
    phase_margin_deg: float
    crossover_hz: float
    stable: bool
    rise_time: float           # s, 10-90 %
    overshoot_pct: float
    settling_time: float       # s, 2 %


def tune_pid(axis: AxisModel, bandwidth_hz: float, phase_margin_deg: float) -> PidGains:
    """Gains that put the loop's crossover at bandwidth_hz with phase_margin_deg."""
    if not (bandwidth_hz > 0 and 0 < phase_margin_deg < 90):
        raise DesignError(f"bandwidth {bandwidth_hz} Hz must be > 0 and phase margin "
                          f"{phase_margin_deg} deg in (0, 90)")
    wc = 2 * np.pi * bandwidth_hz
    with np.errstate(all="ignore"), warnings.catch_warnings():   # refused below when not finite
        warnings.simplefilter("ignore", RuntimeWarning)
        P = complex(axis.position_tf()(1j * wc))
        target = np.exp(1j * np.deg2rad(phase_margin_deg - 180.0)) / P
    if not (np.isfinite(wc) and np.isfinite(P) and P != 0 and np.isfinite(target)):
        raise DesignError(f"the drive's response at the crossover (controller.bandwidth "
                          f"{bandwidth_hz:g} Hz) is {P:.3g}, not a finite non-zero number: the "
                          "bandwidth, the [drive] and [controller.motor] keys are beyond what "
                          "the design can compute")
    a = 1 + 1 / (INTEGRAL_RATIO * 1j)   # C = Kp a + Kd b
    b = 1j * wc
    M = np.array([[a.real, b.real], [a.imag, b.imag]])   # det = wc: regular for wc > 0
    kp, kd = np.linalg.solve(M, [target.real, target.imag])
    if kd >= 0 and kp > 0:
        return _finite(PidGains(float(kp), float(kp * wc / INTEGRAL_RATIO), float(kd)),
                       bandwidth_hz, phase_margin_deg)
    kp, ki = target.real, -target.imag * wc   # PI: C(j wc) = Kp - j Ki / wc
    if kp <= 0 or ki < 0:
        raise DesignError(f"no PID with non-negative gains reaches {bandwidth_hz} Hz at "
                          f"{phase_margin_deg} deg phase margin (PI would need Kp = {kp:.3g}, "
                          f"Ki = {ki:.3g})")
    return _finite(PidGains(float(kp), float(ki), 0.0), bandwidth_hz, phase_margin_deg)


def _finite(gains: PidGains, bandwidth_hz: float, phase_margin_deg: float) -> PidGains:
    """The gains, once computed: finite (DesignError naming the keys they come from)."""
    if not all(np.isfinite(g) for g in (gains.kp, gains.ki, gains.kd)):
        raise DesignError(f"the PID gains {gains} from controller.bandwidth {bandwidth_hz:g} Hz, "
                          f"controller.phase_margin {phase_margin_deg:g} deg and the drive "
                          "([drive], [controller.motor]) are not finite")
    return gains


def sampled_spectral_radius(axis: AxisModel, gains: PidGains, dt: float, delay: int = 0) -> float:
    """Largest |eigenvalue| of the loop as it runs: the axis sampled with a zero-order hold at
    dt, the integral summed per sample and the derivative on the measured rate (axis.py), the
    voltage applied `delay` periods after its sample (0 or 1: ControllerConfig.delay).
    Below 1 the sampled loop is stable; the continuous margins alone do not show that."""
    if delay not in (0, 1):
        raise ValueError(f"delay must be 0 or 1 controller periods, got {delay!r}")
    sys = ct.c2d(axis.state_space(), dt, method="zoh")
    Ad, Bd = np.asarray(sys.A), np.asarray(sys.B)[:, 0]
    # states (x, v, i, integral[, the latched voltage]); reference 0: e = -x,
    # V = -kp x - kd v + ki integral, driving the axis now or (delay 1) over the next period
    K = np.array([-gains.kp, -gains.kd, 0.0, gains.ki])
    M = np.zeros((4 + delay, 4 + delay))
    M[:3, :3] = Ad
    if delay:
        M[:3, 4] = Bd
        M[4, :4] = K
    else:
        M[:3, :] += np.outer(Bd, K)
    M[3, 0], M[3, 3] = -dt, 1.0
    if not np.all(np.isfinite(M)):   # the loop's numbers overflow: no stable loop either
        return math.inf
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def loop(axis: AxisModel, gains: PidGains) -> ct.TransferFunction:
    """The open loop C(s) P(s) on leg position."""
    return gains.tf() * axis.position_tf()


def analyse(axis: AxisModel, gains: PidGains) -> Analysis:
    """Gain and phase margin, crossover, and the closed loop's step figures."""
    L = loop(axis, gains)
    gm, pm, _, wc = ct.margin(L)
    T = ct.feedback(L, 1)
    stable = bool(np.all(np.real(ct.poles(T)) < 0))
    info = ct.step_info(T) if stable else {}
    return Analysis(float(20 * np.log10(gm)) if np.isfinite(gm) else float("inf"), float(pm),
                    float(wc / (2 * np.pi)), stable, float(info.get("RiseTime", np.nan)),
                    float(info.get("Overshoot", np.nan)), float(info.get("SettlingTime", np.nan)))


class UnstableLoopError(DesignError):
    """The closed loop is unstable (by analysis before the run, or diverging during it)."""


def design_axis(model: Model, config: ControllerConfig) -> tuple[AxisModel, PidGains, Analysis]:
    """The constant-load drive, its tuned gains and the loop's analysis; refuses unstable loops."""
    axis = scene_axis(model, config)
    gains = tune_pid(axis, config.bandwidth, config.phase_margin)
    return axis, gains, check_stable(axis, gains, config.dt, config.delay)


def check_stable(axis: AxisModel, gains: PidGains, dt: float, delay: int = 0) -> Analysis:
    """analyse(), raising UnstableLoopError (with the margins) when the continuous loop or the
    loop sampled at dt (with `delay` periods of actuation delay) is unstable."""
    a = analyse(axis, gains)
    rho = sampled_spectral_radius(axis, gains, dt, delay)
    if not a.stable or not rho < 1.0:
        late = f" with {delay} period of actuation delay" if delay else ""
        where = ("closed loop" if not a.stable else
                 f"loop sampled at {1 / dt:g} Hz{late} (spectral radius {rho:.4g})")
        raise UnstableLoopError(
            f"{where} unstable with gains {gains}: gain margin {a.gain_margin_db:.3g} dB, "
            f"phase margin {a.phase_margin_deg:.3g} deg at {a.crossover_hz:.3g} Hz")
    return a
