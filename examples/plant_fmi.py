"""The plant as an in-process FMI co-simulation component (docs/guides/fmu-and-ssp.md: The
plant as an FMI co-simulation unit): hold the platform at home, push leg 1, roll back."""
from pathlib import Path

import numpy as np

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.plant import Plant, StepRejected

SCENES = Path(__file__).resolve().parents[1] / "scenes"
model = load_scene(SCENES / "micro_manipulator.toml")
plant = Plant(model, IntegratorOptions(method="rk4"))
plant.setup_experiment(start_time=0.0)
plant.enter_initialization_mode()
plant.set_initial(q=model.home, qd=np.zeros(6))  # the default: home, at rest
plant.exit_initialization_mode()                 # checks the initial pose (stroke, singularity)
hold = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))  # static rack forces (N)
plant.set_force(hold + [0.2, 0, 0, 0, 0, 0])     # held over each step; or set_torque(tau)
state = plant.get_state()                        # for a rollback; Plant.serialize_state(state)
for _ in range(100):
    plant.do_step(plant.time, 1e-3)              # raises StepRejected (state unchanged)
o = plant.outputs                                # lengths, rates, q, twist, cond, parts
print(f"t = {plant.time:.3f} s, z = {o.q[2]:.6f} m, l1 = {o.lengths[0]:.6f} m, cond {o.cond:.3f}")
print("rack force by part (N):", {k: round(float(v[0]), 4) for k, v in o.parts.items()})
plant.set_state(state)                           # back to t = 0
plant.set_force(hold + 1e4)                      # far too much: the next step leaves the stroke
try:
    plant.do_step(plant.time, 0.5)
except StepRejected as exc:
    print("rejected:", str(exc).split(";")[0])
