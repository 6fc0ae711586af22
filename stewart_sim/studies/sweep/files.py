"""The `sweep` pipeline: GRID.toml -> the sweep on Dask (dask_run.run_sweep) -> DIR/sweep.csv
and the designer's plots."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from stewart_fmu.io import writing
from stewart_fmu.scene import load_scene
from stewart_sim.shell.plots import save_figure
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.sweep.adaptive_plots import REFINEMENT_PLOT, refinement_figure
from stewart_sim.studies.sweep.dask_run import SweepSummary, run_sweep
from stewart_sim.studies.sweep.grid import load_grid
from stewart_sim.studies.sweep.plots import METRIC, results_figure, workspace_figures
from stewart_sim.studies.sweep.result_table import read_table

MAPS = ("force_envelope.png", "singularity_map.png")


def run_sweep_files(scene: Path, grid_path: Path, out: Path, scheduler: str | None = None,
                    workers: int | None = None, plots: bool = True,
                    notice: Callable[[str], None] | None = None, adaptive: int = 0,
                    dashboard: Callable[[str], None] | None = None
                    ) -> tuple[SweepSummary, list[Path]]:
    """Run or resume the sweep into `out`, then plot it; returns the summary and the files.
    `notice` gets a line for each chunk file refused on resume, `dashboard` the Dask
    dashboard's address (run_sweep); `adaptive` N points added where the outcome changes, and
    their map (refinement_figure)."""
    grid = load_grid(grid_path)
    model = load_scene(scene)
    progress = Progress()
    try:
        with writing(out):
            summary = run_sweep(scene, grid, out, scheduler, workers, progress, notice=notice,
                                adaptive=adaptive, dashboard=dashboard)
    finally:
        progress.close()
    written = [summary.table]
    if plots:
        title = f"{model.name}: {grid.evaluation} sweep over {', '.join(grid.keys)}"
        table = read_table(summary.table)
        figures = [(results_figure(table, grid, title), METRIC[grid.evaluation][2])]
        if adaptive:
            figures.append((refinement_figure(table, grid, title), REFINEMENT_PLOT))
        envelope = grid.envelope if grid.evaluation == "envelope" else None
        figures += zip(workspace_figures(model, envelope), MAPS)
        for fig, name in figures:
            with writing(out / name):
                written.append(save_figure(fig, out / name))
    return summary, written
