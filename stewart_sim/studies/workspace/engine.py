"""The feasibility engine of a scene: the model's limits with the drives' bounds of its
[drive] and [controller.motor] tables (controller.drive.AxisModel: the no-load speed, the
peak acceleration of its constant load and the peak force Kf I_max, what excite and the live
envelope bound too)."""
from __future__ import annotations

from stewart_fmu.reach import DriveBounds, Engine


def drive_bounds(scene) -> DriveBounds | None:
    """The drives' bounds of a loaded scene (stewart_sim.scene.load.Scene); None without a
    [drive] or a [controller] table (the legs' speed, acceleration and force are then not
    limited)."""
    model, controller = scene.model, scene.controller
    if controller is None or model.drive is None:
        return None
    from controller.drive import axis_model

    axis = axis_model(model, controller.motor, controller.load_mass)
    return DriveBounds(axis.no_load_speed, axis.peak_acceleration, axis.peak_force)


def engine(scene) -> Engine:
    """The scene's engine (its drives' bounds when it has them, the default cond(J) limit)."""
    return Engine(scene.model, drive_bounds(scene))
