"""The emulated device's hidden true scene: what it must share with the scene the host believes.

`stewart-sim device SCENE --truth TRUE.toml` (and `run --link --truth`) builds the device's
plant from TRUE.toml while its drive loops, feed-forward, setpoint checks and everything the
host computes come from SCENE: the machine's masses, inertias, frictions and rotor inertias
differ from the drawing's, as a real machine's do. What the two scenes must share
(`check_truth`, SceneError naming the key): the gravity; the geometry (base and platform joints,
home, stroke: identification assumes the joints known, kinematic calibration is a separate step);
the drive's gear ratio and pinion radius (the device's motor model converts currents to rack
forces and rack speeds to back-EMF with SCENE's ratio); and whether there is a [drive] at all
(the drives apply motor torques). The plant-side tables [legs], [friction], [transmission] may
differ freely, also be present in one scene only.
"""
from __future__ import annotations

import numpy as np

from stewart_fmu.errors import SceneError
from stewart_fmu.model import Model

# |truth - scene| <= RTOL |scene| + ATOL for every shared number: far below a 1 um encoder step
# and above the last digit of a decimal TOML value
RTOL, ATOL = 1e-9, 1e-12


def check_truth(model: Model, truth: Model) -> None:
    """SceneError (naming the truth scene's key) when `truth` cannot be the machine behind
    `model` (see the module doc)."""
    shared = [("gravity", model.gravity, truth.gravity),
              ("geometry.base_joints", model.base_joints, truth.base_joints),
              ("geometry.platform_joints", model.platform_joints, truth.platform_joints),
              ("geometry.home", model.home, truth.home),
              ("geometry.leg_min", model.leg_min, truth.leg_min),
              ("geometry.leg_max", model.leg_max, truth.leg_max)]
    if (model.drive is None) != (truth.drive is None):
        raise SceneError("drive", "the truth scene must have a [drive] exactly when the scene "
                         f"({model.source}) has one", truth.source)
    if model.drive is not None:
        shared += [("drive.gear_ratio", model.drive.gear_ratio, truth.drive.gear_ratio),
                   ("drive.pinion_radius", model.drive.pinion_radius, truth.drive.pinion_radius)]
    for key, mine, theirs in shared:
        if (mine is None) != (theirs is None):
            raise SceneError(key, f"given in one of the scene ({model.source}) and the truth "
                             "scene only: the geometry must be the scene's", truth.source)
        if mine is None:
            continue
        a, b = np.asarray(mine, dtype=float), np.asarray(theirs, dtype=float)
        gap = np.abs(a - b)
        if np.any(gap > RTOL * np.abs(a) + ATOL):
            raise SceneError(key, f"differs from the scene's ({model.source}) by "
                             f"{float(np.max(gap)):.3g}: the truth scene may differ in masses, "
                             "inertias, frictions and rotor inertia only", truth.source)
