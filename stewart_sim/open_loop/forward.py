"""Open-loop forward dynamics from rack forces: what `stewart-sim simulate SCENE --forces F.csv
--out DIR [--integrator M]` runs (stewart_sim.commands.simulate).

The forces file has the columns t, sigma1..sigma6 (N; further columns, such as the cond and
parts that `inverse` writes, are ignored); each row's forces are held from its time to the
next row's (zero-order hold, as an FMU's inputs). The platform starts at rest at the scene's
home pose at the first time. The run goes through stewart_fmu.plant.Plant, so the plant's
checks apply: a step that leaves the stroke, meets a singularity or goes unstable ends the run
with its typed error (StepRejected, IntegrationError), and nothing is written. On success DIR
gets motion.csv (t, the pose x..thz, its rates dx..dthz, leg lengths l1..l6) and motion.png,
all or nothing; with `--frame F` the pose and its rates are F's (stewart_fmu.frames).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stewart_fmu import io
from stewart_fmu.errors import StewartError
from stewart_fmu.integrators import INTEGRATORS, IntegratorOptions
from stewart_fmu.io import POSE
from stewart_fmu.model import Model
from stewart_fmu.plant import Plant
from stewart_fmu.stability import default_options
from stewart_sim.shell.outputs import result_set

FORCE_COLUMNS = io.FORCE_COLUMNS                      # t, sigma1..sigma6
MOTION_COLUMNS = ("t", *POSE, *(f"d{c}" for c in POSE), *(f"l{i}" for i in range(1, 7)))
FILES = ("motion.csv", "motion.png")


def read_forces(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """t (N,) and sigma (N, 6) from a forces CSV (columns t,sigma1..sigma6, further columns
    ignored: `inverse` output works); errors name the line and column."""
    data = io.read_samples(path, FORCE_COLUMNS, "forces", prefix=True, min_rows=2)
    return data[:, 0].copy(), data[:, 1:].copy()


def simulate(model: Model, t: np.ndarray, sigma: np.ndarray, integrator: str | None = None,
             q0=None, qd0=None, options: IntegratorOptions | None = None) -> np.ndarray:
    """The plant from rest at home (or q0, qd0) at t[0], sigma[k] held over [t[k], t[k+1]);
    the MOTION_COLUMNS table at every t. `options`: the plant's integrator (default
    stability.default_options; the scene's [solver]), `integrator` its method instead. A refused
    step raises its typed error (StepRejected, IntegrationError), its message naming the time."""
    options = options or default_options(model)
    if integrator is not None:
        if integrator not in INTEGRATORS:
            raise StewartError(f"integrator '{integrator}' unknown: one of {', '.join(INTEGRATORS)}")
        options = replace(options, method=integrator)
    plant = Plant(model, options)
    plant.setup_experiment(float(t[0]))
    plant.enter_initialization_mode()
    plant.set_initial(model.home if q0 is None else q0, np.zeros(6) if qd0 is None else qd0)
    plant.set_force(sigma[0])
    plant.exit_initialization_mode()
    rows = np.empty((t.size, len(MOTION_COLUMNS)))
    rows[0] = _row(plant, t[0])
    for k in range(t.size - 1):
        plant.set_force(sigma[k])
        try:
            plant.do_step(plant.time, float(t[k + 1] - plant.time))
        except StewartError as exc:   # typed as the plant raised it, the sample named first
            exc.args = (f"forces sample {k} (t = {float(t[k])!r} s): {exc}",)
            raise
        rows[k + 1] = _row(plant, t[k + 1])
    return io.named_array({name: rows[:, k] for k, name in enumerate(MOTION_COLUMNS)})


def _row(plant: Plant, t: float) -> np.ndarray:
    o = plant.outputs
    return np.r_[t, o.q, o.qd, o.lengths]


def write_motion(model: Model, table: np.ndarray, out: Path, title: str) -> list[Path]:
    """motion.csv and motion.png into `out`, all or nothing."""
    with result_set(out) as tmp:
        io.write_csv(tmp / "motion.csv", table)
        from stewart_sim.shell.plots import save_figure   # matplotlib: only when plotting
        save_figure(motion_figure(table, title), tmp / "motion.png")
    return [out / name for name in FILES]


def motion_figure(table: np.ndarray, title: str):
    """Translations (m), rotations (rad) and leg lengths (m) against time (s)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    t = table["t"]
    from stewart_sim.shell.plots import plot_line   # each line decimated for drawing (MAX_POINTS)
    for c in ("x", "y", "z"):
        plot_line(axes[0], t, table[c], label=c)
    for c in ("thx", "thy", "thz"):
        plot_line(axes[1], t, table[c], label=f"θ{c[2]}")
    for i in range(1, 7):
        plot_line(axes[2], t, table[f"l{i}"], label=f"l{i}")
    for ax, (what, unit) in zip(axes, (("position", "m"), ("orientation", "rad"), ("leg length", "m"))):
        ax.set(ylabel=f"{what} ({unit})", xlabel="time t (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=6, fontsize="small", loc="best")
    fig.suptitle(title)
    return fig
