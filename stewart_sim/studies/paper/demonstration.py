"""What `stewart-sim demo` writes: the demonstration move, its forces (the `inverse` path),
their plot and 3D view, and the paper rerun."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from controller.config import ControllerConfig
from controller.moves import DEMO_RATE, demo_trajectory
from stewart_fmu import io
from stewart_fmu.dynamics import present_parts
from stewart_fmu.io import writing
from stewart_fmu.model import Model
from stewart_sim.open_loop.inverse_forces import run_inverse
from stewart_sim.shell.plots import forces_figure, save_figure
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.paper.files import run_paper
from stewart_sim.studies.paper.study import PaperResults
from stewart_sim.view.files import VIEW_FILE, write_beside
from stewart_sim.view.sources import trajectory_view


def run_demo(model: Model, controller: ControllerConfig | None, out: Path, duration: float,
             view: bool = True) -> tuple[list[Path], PaperResults | None]:
    """Demonstration trajectory, its forces (the `inverse` path), their plot, the 3D view, the
    paper rerun, into the directory `out`; returns (the files, the paper's results or None).
    `controller`: the scene's parsed [controller] (None: it has none), for the views."""
    t, q, qd, qdd = demo_trajectory(model, duration)
    traj = out / "demo_trajectory.csv"
    with writing(traj):
        io.write_csv(traj, io.trajectory_table(t, q, qd, qdd))
    forces = out / "demo_forces.csv"
    progress = Progress()
    try:
        _, table = run_inverse(model, traj, forces, True, progress, keep=True)
    finally:
        progress.close()
    title = f"{model.name}: demonstration move ({duration:g} s, {DEMO_RATE:g} Hz)"
    png = out / "demo_forces.png"
    with writing(png):
        save_figure(forces_figure(table, present_parts(model), title), png)
    written, results = [traj, forces, png], None
    if view:
        sigma = np.column_stack([table[f"sigma{i}"] for i in range(1, 7)])
        write_beside(out / VIEW_FILE, trajectory_view(
            model, t, q, qd, qdd, controller=controller, forces=sigma, title=title,
            source=forces.name))
        written.append(out / VIEW_FILE)
    if model.legs is None or model.drive is None:
        print("paper rerun skipped: it needs the scene's [legs] and [drive]", file=sys.stderr)
    else:
        report, results = run_paper(model, controller, out / "paper", view)
        written.append(report)
        if view:
            written.append(out / "paper" / VIEW_FILE)
    return written, results
