"""Cost of the classical washout stepped one sample at a time (stewart_sim/cueing/washout_step.py)
and of the offline cue that is its loop.

    python benchmarks/bench_washout_step.py [--runs N]

Scene scenes/motion_simulator.toml's [cueing], the shipped motions scenes/motions/*.csv (100 Hz).
Prints, per motion: the best and the median over N runs of the time per `WashoutStepper.step`
(us/step: the live loop's cost per telemetry sample, CueSample built), of the stepper's
construction (the filters' matrix exponentials) and of `classical_washout` on the whole motion.
Times are the process's CPU time (time.process_time): on a machine shared with other work the
wall time also counts the waits for a core, which are not the washout's cost; on an idle
machine the two agree. A live loop at 1 kHz has 1000 us per sample for everything; the
washout's share is this.
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from stewart_fmu import load_scene
from stewart_sim.cueing.motion import read_motion
from stewart_sim.cueing.washout import classical_washout
from stewart_sim.cueing.washout_step import WashoutStepper
from stewart_sim.scene.cueing_config import cueing_config

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "motion_simulator.toml"
MOTIONS = ("braking_car", "lane_change", "takeoff")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    runs = max(1, min(parser.parse_args().runs, 100))
    model = load_scene(SCENE)
    config = cueing_config(model)
    print(f"{'motion':<12} {'samples':>7} {'step us (best/median)':>22} "
          f"{'construct ms':>13} {'offline ms (best/median)':>25}")
    for name in MOTIONS:
        motion = read_motion(ROOT / "scenes" / "motions" / f"{name}.csv")
        t = motion.t
        h = float((t[-1] - t[0]) / (t.size - 1))
        rows = list(zip(motion.specific_force, motion.angular_velocity))
        steps, builds, offline = [], [], []
        for _ in range(runs):
            t0 = time.process_time()
            stepper = WashoutStepper(config, model.home, model.gravity, h)
            t1 = time.process_time()
            for f, w in rows:
                stepper.step(f, w)
            t2 = time.process_time()
            classical_washout(config, motion, model.home, model.gravity)
            t3 = time.process_time()
            builds.append((t1 - t0) * 1e3)
            steps.append((t2 - t1) / len(rows) * 1e6)
            offline.append((t3 - t2) * 1e3)
        print(f"{name:<12} {len(rows):>7} {min(steps):>10.1f} / {statistics.median(steps):<9.1f} "
              f"{min(builds):>13.2f} {min(offline):>12.1f} / {statistics.median(offline):<10.1f}")


if __name__ == "__main__":
    main()
