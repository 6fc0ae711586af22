"""Inverse and forward dynamics of a scene along a smooth move (docs/guides/plant-and-scenes.md:
Inverse dynamics)."""
from pathlib import Path

import numpy as np

from controller.moves import demo_trajectory
from stewart_fmu import forward_dynamics, inverse_dynamics, inverse_dynamics_parts, load_scene

SCENES = Path(__file__).resolve().parents[1] / "scenes"
model = load_scene(SCENES / "micro_manipulator.toml")  # immutable, built once
t, q, qd, qdd = demo_trajectory(model, duration=1.0)    # (N,), (N, 6) x 3: the demo move
sigma = inverse_dynamics(model, q, qd, qdd)             # (N, 6) -> (N, 6); also (6,) -> (6,)
parts = inverse_dynamics_parts(model, q, qd, qdd)       # {"platform": (N, 6), ...}
qdd_back = forward_dynamics(model, q, qd, sigma)        # the inverse of the above
assert np.allclose(sum(parts.values()), sigma) and np.allclose(qdd_back, qdd)
print(f"{t.size} samples, peak rack force {np.abs(sigma).max():.3f} N, parts {sorted(parts)}")
