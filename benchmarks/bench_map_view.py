"""What `workspace --map`'s view.html costs: the surface (studies.workspace.map_surface) and the
page (studies.workspace.map_view), on the shipped micro-manipulator at home's angles.

    python benchmarks/bench_map_view.py [--resolutions MM,...]

For each x-y grid step (default: the map's default, the characteristic length / 30, and 1 mm):
the map's columns and seconds, the drawing grid (1 column in k, map_surface.drawing_step), the
triangles, the surface's seconds, the page's seconds (built and written: the view's whole extra
time) and its size in MB.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from controller.capability import engine
from stewart_sim.scene.load import load
from stewart_sim.studies.workspace.map_surface import drawing_step, surface
from stewart_sim.studies.workspace.map_view import write_map_view
from stewart_sim.studies.workspace.maps import constant_orientation

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolutions", default="", help="x-y steps in mm (default: the map's "
                    "default and 1)")
    args = ap.parse_args()
    scene = load(SCENE)
    model = scene.model
    steps = [float(v) / 1e3 for v in args.resolutions.split(",") if v] or \
        [model.characteristic_length / 30, 0.001]
    eng = engine(model, scene.controller)
    home = np.asarray(model.home, dtype=float)
    print(f"{'grid mm':>8} {'columns':>8} {'map s':>7} {'k':>3} {'triangles':>10} "
          f"{'surface s':>10} {'view s':>7} {'page MB':>8}")
    for h in steps:
        m = constant_orientation(eng, home, "platform", h)
        k = drawing_step(m)
        t0 = time.perf_counter()
        s = surface(m, k)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            write_map_view(Path(tmp), scene, m, home, SCENE.name)
            t2 = time.perf_counter()
            size = (Path(tmp) / "view.html").stat().st_size
        columns = len(np.unique(m.runs[:, :2], axis=0))
        print(f"{h * 1e3:8.4g} {columns:8d} {m.seconds:7.2f} {k:3d} {len(s.triangles):10d} "
              f"{t1 - t0:10.2f} {t2 - t1:7.2f} {size / 1e6:8.2f}")


if __name__ == "__main__":
    main()
