"""The emulated device's six drive loops around its plant: the references and one servo tick.

The plant is `stewart_fmu.plant.Plant` (behind `controller.plants.InProcessPlant`), the drive
controllers are `controller.axis.AxisControllers` and `MotorCurrents` with the gains that
`controller.design.design_axis` gives for the scene's [controller] table (it also refuses an
unstable sampled loop). One tick: measure the leg lengths and rates, one
`controller.axis.servo_step` (the co-simulation master's step: PID voltages + feed-forward, the
motor currents over the sample), step the plant by the controller period with the mean motor
torques.

The references are what the device's mode (hil.operating_mode) asks: `hold` (the lengths measured now, at
rest), `follow` (a setpoint's lengths, rates and optional force feed-forward: the voltage
R i + L di/dt + Ke' ldot_ref with i = F / Kf) or the homing quintic (`start_homing`,
`homing_reference`). When a feed-forward stream begins or ends the integral takes its static part
over (bumpless transfer). `start_holding` restarts the plant at rest at a pose with the drives
holding it: `controller.feedforward.start_at_equilibrium`, the master's bumpless start.

With a hidden true scene (`plant_model`, hil.truth) the plant is built from it, and so is the
holding force of a (re)start: a machine at rest has its integrators settled on its true load.
The drive design, the motor model and the feed-forward stay the believed `model`'s.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from controller.axis import AxisControllers, MotorCurrents, servo_step
from controller.config import ControllerConfig
from controller.design import design_axis
from controller.feedforward import start_at_equilibrium
from controller.plants import InProcessPlant
from controller.trajectory import QUINTIC_PEAK_RATE, Trajectory, leg_references, minimum_jerk
from stewart_fmu.errors import SceneError, StewartError
from stewart_fmu.model import Model

HOMING_SPEED = 0.25        # peak homing leg rate, stroke fractions per second
HOMING_MIN_TIME = 0.2      # s


class Servo:
    """The drives and the plant of the device (see the module doc)."""

    def __init__(self, model: Model, config: ControllerConfig,
                 plant_model: Model | None = None) -> None:
        if config.delay:   # the ticks below apply each sample's torque within its own tick
            raise SceneError("controller.delay", f"the device's drive loops have no actuation "
                                                 f"delay: must be 0, got {config.delay}",
                             model.source)
        self.model = model
        self.plant_model = model if plant_model is None else plant_model
        self.dt = config.dt
        axis, gains, _ = design_axis(model, config)
        self.ctrl = AxisControllers(gains, axis, self.dt)
        self.motors = MotorCurrents(axis, self.dt)
        self.port = InProcessPlant(self.plant_model)
        self.plant = self.port.plant
        self.design_gains, self.design_motor = gains, axis.motor
        self.voltage = np.zeros(6)                   # of the last tick
        self.saturated = np.zeros(6, dtype=bool)     # voltage-saturated or current-limited
        self._ff_static: np.ndarray | None = None   # R i + Ke ldot_ref of the feed-forward in use
        # the pose of the setpoint being followed (observers' ghost); None while holding or homing
        self.reference_pose: np.ndarray | None = None
        self._path: tuple[np.ndarray, np.ndarray, int, int] | None = None  # homing: l0, l1, k0, n
        self.start_holding(np.asarray(model.home, dtype=float), 0.0)

    def start_holding(self, q: np.ndarray, t0: float) -> None:
        """(Re)start the plant at rest at pose q, drives holding it (the master's bumpless start)."""
        traj = Trajectory(np.array([t0, t0 + self.dt]), np.tile(q, (2, 1)), np.zeros((2, 6)),
                          np.zeros((2, 6)))
        self.plant.reset()
        start_at_equilibrium(self.plant_model, traj, leg_references(self.model, traj),
                             self.ctrl.gains, self.ctrl, self.motors, np.zeros(6), self.port)
        self._ff_static = None
        self.hold()

    def hold(self) -> None:
        """References: the leg lengths measured now, at rest, no feed-forward."""
        self.l_ref = self.plant.outputs.lengths.copy()
        self.reference_pose = None
        self.ldot_ref = np.zeros(6)
        self._set_feedforward(None, None)

    def follow(self, lengths: np.ndarray, rates: np.ndarray | None, pose: np.ndarray,
               force: np.ndarray | None, force_rate: np.ndarray | None) -> None:
        """References of a valid setpoint (rates, force and force rate: None when not valid)."""
        self.reference_pose = pose
        self.l_ref = lengths
        self.ldot_ref = np.zeros(6) if rates is None else rates
        if force is None:
            self._set_feedforward(None, None)
            return
        ax = self.ctrl.axis
        i = force / ax.force_constant
        di = 0.0 if force_rate is None else force_rate / ax.force_constant
        self._set_feedforward(ax.voltage(i, di, self.ldot_ref), ax.voltage(i, 0.0, self.ldot_ref))

    def _set_feedforward(self, v_ff: np.ndarray | None, static: np.ndarray | None) -> None:
        """Bumpless transfer: when a feed-forward stream begins (or ends: hold, watchdog, homing,
        a setpoint without force) the integral hands its static part R i + Ke ldot_ref over (or
        takes it back), as controller.feedforward.start_at_equilibrium does at the start of a run."""
        ki = self.ctrl.gains.ki
        if ki > 0 and (static is None) != (self._ff_static is None):
            old = 0.0 if self._ff_static is None else self._ff_static
            self.ctrl.integral += (old - (0.0 if static is None else static)) / ki
        self.v_ff = np.zeros(6) if v_ff is None else v_ff
        self._ff_static = static

    def start_homing(self, home_lengths: np.ndarray, k: int, rate: float, stroke: float) -> None:
        """From tick k, a quintic in leg space from the lengths now to `home_lengths` at a quarter
        `stroke` per second peak (at least HOMING_MIN_TIME)."""
        l0 = self.plant.outputs.lengths.copy()
        d = float(np.max(np.abs(home_lengths - l0)))
        duration = max(HOMING_MIN_TIME, QUINTIC_PEAK_RATE * d / (HOMING_SPEED * stroke))
        self._path = (l0, home_lengths.copy(), k, max(1, round(duration * rate)))
        self.reference_pose = None   # the reference moves in leg space, not along a pose
        self._set_feedforward(None, None)

    def homing_reference(self, k: int, rate: float) -> bool:
        """The homing references of tick k; True when the quintic has ended (then holding its
        end, at rest)."""
        l0, l1, k0, n = self._path
        u = min(1.0, (k - k0) / n)
        s, sd, _ = minimum_jerk(u, n / rate)
        self.l_ref = l0 + (l1 - l0) * s
        self.ldot_ref = (l1 - l0) * sd
        if u < 1.0:
            return False
        self.ldot_ref = np.zeros(6)
        return True

    def tick(self) -> None:
        """One servo step and one plant step of dt; raises PlantStepError (an end stop), or a
        numerical failure (FloatingPointError for a non-finite voltage or torque, or what the
        plant raises)."""
        outputs = self.plant.outputs
        v, torque, saturated = servo_step(self.ctrl, self.motors, self.l_ref, self.ldot_ref,
                                          outputs.lengths, outputs.rates, self.v_ff)
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(torque))):
            raise FloatingPointError("non-finite motor voltage or torque")
        self.voltage, self.saturated = v, saturated
        self.port.step(self.plant.time, self.dt, torque)

    def idle(self) -> None:
        """No voltage and no saturation to report (after a numerical failure)."""
        self.voltage, self.saturated = np.zeros(6), np.zeros(6, dtype=bool)

    def set_gain(self, name: str, x: float) -> None:
        """Set kp, ki or kd; a new ki keeps ki * integral (bumpless)."""
        old = self.ctrl.gains
        if name == "ki" and old.ki > 0 and x > 0:
            self.ctrl.integral *= old.ki / x
        self.ctrl.gains = replace(old, **{name: x})

    def set_motor(self, field: str, x: float) -> None:
        """Set a motor rating (voltage_limit, current_limit) of the controllers and the currents."""
        axis = self.ctrl.axis
        axis = replace(axis, motor=replace(axis.motor, **{field: x}))
        self.ctrl.axis = self.motors.axis = axis

    def restore_design(self) -> None:
        """The designed gains and the motor's rated limits (after a numerical failure)."""
        self.ctrl.gains = self.design_gains
        self.set_motor("voltage_limit", self.design_motor.voltage_limit)
        self.set_motor("current_limit", self.design_motor.current_limit)

    def restart_after_failure(self, good_q: np.ndarray, last_pose: np.ndarray, t: float) -> None:
        """Restart at rest at the last good pose (else at `last_pose`, else home), at the plant's
        time (else at t)."""
        t = self.plant.time if math.isfinite(self.plant.time) else t
        q = good_q if np.all(np.isfinite(good_q)) else last_pose
        try:
            self.start_holding(q, t)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, StewartError):
            self.start_holding(np.asarray(self.model.home, dtype=float), t)
