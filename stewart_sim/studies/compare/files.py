"""Files of `stewart-sim compare`: the drive-inertia comparison of each scene
(stewart_sim.studies.compare.study) and its report (stewart_sim.studies.compare.report)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from stewart_fmu.io import writing
from stewart_sim.scene.load import Scene
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.compare.report import write_comparison_report
from stewart_sim.studies.compare.study import N_POINTS, compare_drive_inertia, regime


def run_compare(scenes: Sequence[Scene], out: Path, points: int = N_POINTS) -> list[Path]:
    """The drive-inertia comparison of each scene (stewart_sim.studies.compare.study), its files in
    `out`."""
    pairs = [(s.model, s.require_controller()) for s in scenes]  # every scene checked first
    results = []
    progress = Progress()
    try:
        for model, config in pairs:
            results.append(compare_drive_inertia(
                model, config, n_points=points,
                progress=lambda k, n, name=model.name: progress.update(
                    f"comparison of {name}, closed-loop", k, n)))
    finally:
        progress.close()
    for c in results:
        nom = c.nominal()
        if nom is not None:
            print(f"{c.scene}: m_d / m_load = {nom.mass_ratio:.3g}, coupling {nom.coupling:.3g}: "
                  f"{regime(nom)}")
    with writing(out):
        return write_comparison_report(results, out)
