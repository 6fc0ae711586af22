"""The paper rerun into a directory: the study (study.py), its report (report.py) and the view
of its six moves; the verdicts as terminal lines."""
from __future__ import annotations

from pathlib import Path

from controller.config import ControllerConfig
from stewart_fmu.io import writing
from stewart_fmu.model import Model
from stewart_sim.studies.paper.report import write_paper_report
from stewart_sim.studies.paper.study import PaperResults, run_paper_experiments
from stewart_sim.view.files import VIEW_FILE, write_beside
from stewart_sim.view.sources import paper_view


def run_paper(model: Model, controller: ControllerConfig | None, out: Path,
              view: bool = True) -> tuple[Path, PaperResults]:
    """Rerun the paper's experiments into the directory `out` (with the view of its six moves,
    its force scale from the scene's parsed [controller], `controller`); returns (report.md,
    results)."""
    results = run_paper_experiments(model)
    with writing(out):
        paths = write_paper_report(results, out)
    if view:
        write_beside(out / VIEW_FILE, paper_view(results, controller=controller,
                                                        source="the paper rerun"))
    return next(p for p in paths if p.name == "report.md"), results


def print_verdicts(results: PaperResults) -> None:
    """One line per claim of the paper: agrees / does not agree."""
    print(f"paper rerun on '{results.scene}':")
    for v in results.verdicts:
        print(f"  {'agrees' if v.agrees else 'does not agree'}: {v.claim}")
