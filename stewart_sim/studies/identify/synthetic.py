"""Synthetic machines for identification studies: a prior model with every inertial and
friction parameter drawn off by up to +-frac, kept physical (what benchmarks and tests hide
behind the emulated device or behind model-generated runs)."""
from __future__ import annotations

import dataclasses

import numpy as np

from stewart_fmu.model import Model, per_leg

PRIOR_FREE_COULOMB = 0.2   # N: the Coulomb friction drawn (+-frac) when the prior has none


def perturbed_model(model: Model, rng: np.random.Generator, frac: float = 0.3) -> Model:
    """`model` with each mass, centre of mass, moment, rotor inertia and friction multiplied by
    1 + U(-frac, frac), per leg where the scene allows; the platform's principal moments and
    each leg part's (transverse, axial) redrawn until a rigid body has them (the scene's rules:
    triangle inequality, axial <= 2 x transverse). A prior without Coulomb friction gets
    PRIOR_FREE_COULOMB +- frac. Needs [legs], [drive] and [friction]."""
    f = lambda: float(1.0 + rng.uniform(-frac, frac))  # noqa: E731
    while True:
        inertia = model.platform_inertia * np.array([f(), f(), f()])
        if 2.0 * inertia.max() <= inertia.sum():
            break
    lg = model.legs
    while True:
        legs = dataclasses.replace(
            lg, lower_mass=lg.lower_mass * f(), lower_com=lg.lower_com * f(),
            lower_inertia=(lg.lower_inertia[0] * f(), lg.lower_inertia[1] * f()),
            upper_mass=lg.upper_mass * f(), upper_com=lg.upper_com * f(),
            upper_inertia=(lg.upper_inertia[0] * f(), lg.upper_inertia[1] * f()))
        if all(axial <= 2.0 * transverse for transverse, axial in (legs.lower_inertia,
                                                                    legs.upper_inertia)):
            break
    spread = lambda: 1.0 + rng.uniform(-frac, frac, 6)  # noqa: E731
    coulomb = model.friction.coulomb_legs
    drive = dataclasses.replace(model.drive, rotor_inertia=per_leg(model.drive.rotor_inertia)
                                * spread())
    friction = dataclasses.replace(
        model.friction, viscous=model.friction.viscous_legs * spread(),
        coulomb=(coulomb if np.any(coulomb > 0) else PRIOR_FREE_COULOMB) * spread())
    return dataclasses.replace(model, platform_mass=model.platform_mass * f(),
                               platform_inertia=inertia, legs=legs, drive=drive,
                               friction=friction)
