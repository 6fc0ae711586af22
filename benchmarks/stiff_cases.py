"""The stiff cases with every integrator, and the drift of a simulated hour (the figures of
docs/guides/accuracy-and-stiff.md).

    .venv/bin/python benchmarks/stiff_cases.py [--hour SECONDS]
"""
from __future__ import annotations

import argparse
from pathlib import Path

from stewart_sim.scene.load import load
from stewart_sim.studies.cases.study import hour_drift, integrator_study

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hour", type=float, default=3600.0, help="simulated seconds of the drift run")
    args = parser.parse_args()
    for path in sorted((SCENES / "stiff").glob("*.toml")):
        scene = load(path)
        model = scene.model
        print(f"\n{path.name}: {scene.case.description}")
        print(f"| integrator | outcome | max error vs Radau 1e-10 | run time (s) | rhs evaluations |")
        print("|---|---|---|---|---|")
        for r in integrator_study(model, scene.case, scene.controller):
            where = f" at t = {r.time:.3g} s" if r.time is not None else ""
            print(f"| {r.label} | {r.outcome}{where} | {r.error:.2e} | {r.wall:.3f} | {r.evaluations} |")
    hour = load(SCENES / "extreme" / "hour.toml")
    for step in (1e-3, 1e-2):
        d = hour_drift(hour.model, hour.case, args.hour, step)
        print(f"\nhour run, rk4 at {step:g} s over {d.duration:g} s: energy drift {d.energy_drift:.2e} "
              f"of the peak kinetic energy, orientation drift {d.orientation_drift:.2e} rad, "
              f"{d.wall:.1f} s wall")


if __name__ == "__main__":
    main()
