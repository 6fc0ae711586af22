"""Size of the 3D view and the time to write it, for the 4 s demo run and an hour-long run.

1. The 4 s closed-loop run at 1 kHz (what `make demo` writes as results/run/view.html): the
   run itself, then the view from its table (stewart_sim.view.sources.run_table_view + write).
2. An hour-long trajectory at 1 kHz in memory (3.6 M samples, the `demo` move stretched to an
   hour: no hour of simulation needed): the view as `demo` / `inverse` write it (forces by
   inverse dynamics at the frames).
3. `stewart-sim view` end to end on an hour-long trajectory CSV at 100 Hz (360 k rows; an hour
   at 1 kHz is a 1.3 GB CSV): reading the file included.

Prints each figure once (a file writer, not a kernel: no repeats). Run:
.venv/bin/python benchmarks/bench_view.py [--fps FPS] [--keep DIR]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.moves import demo_trajectory, run_reference
from stewart_fmu import io
from stewart_fmu.scene import load_scene
from stewart_sim.view.html import write_view
from stewart_sim.view.sources import run_table_view, trajectory_view

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
HOUR = 3600.0


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--keep", type=Path, help="write the pages and the CSV here")
    args = parser.parse_args()
    out = args.keep or Path(tempfile.mkdtemp(prefix="bench-view-"))
    out.mkdir(parents=True, exist_ok=True)
    model = load_scene(SCENE)
    config = controller_config(model)
    print(f"{'case':44s} {'samples':>9s} {'frames':>7s} {'MB':>6s} {'write (s)':>9s}")

    result = run_closed_loop(model, config, run_reference(model, config, 4.0))
    view, dt_view = timed(lambda: run_table_view(model, result.table, controller=config,
                                                  title="4 s run", fps=args.fps))
    size, dt_write = timed(lambda: write_view(out / "run_4s.html", view))
    print(f"{'4 s closed-loop run at 1 kHz (run)':44s} {view.source_samples:9d} {view.frames:7d} "
          f"{size / 1e6:6.2f} {dt_view + dt_write:9.3f}")

    t, q, qd, qdd = demo_trajectory(model, HOUR)      # 1 kHz (controller.moves.DEMO_RATE)
    view, dt_view = timed(lambda: trajectory_view(model, t, q, qd, qdd, controller=config,
                                                  title="hour", fps=args.fps))
    size, dt_write = timed(lambda: write_view(out / "hour_1khz.html", view))
    print(f"{'hour-long trajectory at 1 kHz (in memory)':44s} {view.source_samples:9d} "
          f"{view.frames:7d} {size / 1e6:6.2f} {dt_view + dt_write:9.3f}")
    del t, q, qd, qdd, view

    csv = out / "hour_100hz.csv"
    subprocess.run([sys.executable, "-m", "stewart_sim", "trajectory", str(SCENE), "--move",
                    "demo", "--duration", str(HOUR), "--rate", "100", "--out", str(csv)],
                   check=True, capture_output=True, cwd=ROOT)
    page = out / "hour_100hz.html"
    done, dt = timed(lambda: subprocess.run(
        [sys.executable, "-m", "stewart_sim", "view", str(csv), "--scene", str(SCENE), "-o",
         str(page), "--fps", str(args.fps)], check=True, capture_output=True, text=True, cwd=ROOT))
    print(f"{'stewart-sim view, hour CSV at 100 Hz':44s} {360001:9d} {'':>7s} "
          f"{page.stat().st_size / 1e6:6.2f} {dt:9.3f}  (process; CSV {csv.stat().st_size / 1e6:.0f} MB)")
    print(f"  its line: {done.stdout.strip()}")
    if args.keep is None:
        for p in out.iterdir():
            p.unlink()
        out.rmdir()


if __name__ == "__main__":
    main()
