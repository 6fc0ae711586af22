"""Record the plant's results on every shipped scene into tests/data/plant_reference.npz.

The file holds the results of a second implementation of the C core's arithmetic (compiled
Python kernels, operation for operation the same); tests/stewart_fmu/test_plant_reference.py holds
the C core (stewart_fmu/native) to it (1e-12 relative). What is recorded, per scene (the
shipped, stiff and extreme scenes), from seeded states near home: inverse_dynamics,
inverse_dynamics_parts, forward_dynamics, leg_state, cond(J), energy terms, and 20 Plant steps
of 1 ms (with the inputs held from a seeded hold + 2 % wiggle) with rk4, euler and dopri5.

    python tools/plant_reference.py   # rewrites the file: only when the physics changes on purpose
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from stewart_fmu import load_scene
from stewart_fmu.dynamics import (forward_dynamics, inverse_dynamics, inverse_dynamics_parts,
                                  leg_state, present_parts)
from stewart_fmu.energy import energy_terms
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.kinematics import condition_number
from stewart_fmu.errors import IntegrationError
from stewart_fmu.plant import Plant, StepRejected
from stewart_fmu.stability import hold_state

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "tests" / "data" / "plant_reference.npz"
SCENES = sorted(ROOT.glob("scenes/*.toml")) + sorted(ROOT.glob("scenes/stiff/*.toml")) + \
    sorted(ROOT.glob("scenes/extreme/*.toml"))
N_STATES, N_STEPS, H = 8, 20, 1e-3
METHODS = ("rk4", "euler", "dopri5")


def states(model, seed: int):
    """q near home (a tenth of a demo-sized move), qd and qdd of moderate size."""
    rng = np.random.default_rng(seed)
    scale = np.r_[np.full(3, 1e-3 * np.max(np.abs(model.base_joints))), np.full(3, 0.01)]
    q = model.home + rng.uniform(-1, 1, (N_STATES, 6)) * scale
    qd = rng.uniform(-1, 1, (N_STATES, 6)) * scale * 10
    qdd = rng.uniform(-1, 1, (N_STATES, 6)) * scale * 100
    return q, qd, qdd


def record(path: Path, seed: int) -> dict[str, np.ndarray]:
    model = load_scene(path)
    q, qd, qdd = states(model, seed)
    sigma = inverse_dynamics(model, q, qd, qdd)
    parts = inverse_dynamics_parts(model, q, qd, qdd)
    out = {"q": q, "qd": qd, "qdd": qdd, "sigma": sigma,
           "parts": np.stack([parts[k] for k in present_parts(model)]),
           "forward": forward_dynamics(model, q, qd, sigma),
           "legs": np.stack([np.concatenate(leg_state(model, a, b)) for a, b in zip(q, qd)]),
           "cond": np.array([condition_number(model, a) for a in q])}
    y, F = hold_state(model)
    out["energy"] = energy_terms(model, y)
    rng = np.random.default_rng(seed + 1)
    wiggle = F * (1 + 0.02 * rng.standard_normal((N_STEPS, 6)))
    out["inputs"] = wiggle
    for method in METHODS:
        plant = Plant(model, IntegratorOptions(method=method, max_step=min(H, 1e-4) if
                                               model.transmission is not None else H))
        plant.setup_experiment(0.0)
        plant.enter_initialization_mode()
        plant.set_force(wiggle[0])
        plant.exit_initialization_mode()
        rows, outcome = [], [N_STEPS, 0]   # (first refused step, its status) or (N_STEPS, 0)
        for k in range(N_STEPS):
            plant.set_force(wiggle[k])
            try:
                plant.do_step(k * H, H)
            except StepRejected as exc:
                outcome = [k, exc.status]
                break
            except IntegrationError:
                outcome = [k, -1]
                break
            rows.append(np.r_[plant.outputs.q, plant.outputs.qd, plant.outputs.lengths])
        out[f"steps_{method}"] = np.array(rows).reshape(-1, 18)
        out[f"outcome_{method}"] = np.array(outcome)
    return out


def main() -> int:
    data = {}
    for seed, path in enumerate(SCENES):
        name = str(path.relative_to(ROOT / "scenes")).removesuffix(".toml")
        for key, value in record(path, seed).items():
            data[f"{name}/{key}"] = value
    OUT.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT, **data)
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes, {len(SCENES)} scenes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
