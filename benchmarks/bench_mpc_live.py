"""The live MPC's solve-time histogram (stewart_sim.live.optimal_stream.SolveStats) at 50 and
100 Hz on the shipped motion simulator, with a shipped motion and a held-out one.

    python benchmarks/bench_mpc_live.py [--rates 50 100] [--horizon S] [--motion CSV]
                                        [--blocking R] [--tolerance EPS] [--real-time]

Motions: scenes/motions/braking_car.csv (shipped) and a held-out step (at rest for 1 s, then
2 m/s^2 forward for 10 s), both fed at 1 kHz to LiveOptimal without preview, the scene's
[cueing.optimal] options at each rate and the horizon given (default 1 s: 50 steps at 50 Hz,
100 at 100 Hz; the scene's 2 s is 100 and 200). By default on a simulated clock
(synchronous: each solve inline, its wall time measured; "over" counts the solves longer than
one MPC step, 1 / rate, which in real time would be late). With --real-time the 1 kHz loop
runs on the wall clock with the solves in the worker process: "late" is then the solves not
back in time, "lead" the most steps ahead a solve had to be started, "tick" the loop's own
work at an MPC step; "stopped" the steps flown past a plan's end (no new plan in time).

For the held-out step the delivered specific force (stewart_sim.cueing.vestibular.
delivered_motion of the flown q, qd, qdd) is printed: its largest error while the vehicle is
at rest (0 exactly: no false cue) and its mean forward component over windows after the step.
On the simulated clock the loop's CPU time per MPC step (time.process_time over the pushes
and samples of each step: the solve, its linearisation and the state update; the machine's
load does not inflate it as it does wall time) is printed as p50 / p99 / max, with the cue's
quality: the perceived specific-force and angular-velocity error RMS (vestibular.perception,
per axis, summed in quadrature) and the least distance of a leg from its stroke's ends.
--blocking and --tolerance set [cueing.optimal] blocking and tolerance (default: the scene's).
Wall-clock figures: measured here, never asserted in tests.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.cueing.motion import VehicleMotion, read_motion
from stewart_sim.cueing.vestibular import delivered_motion, perception
from stewart_sim.live.optimal_stream import LiveOptimal, SolveStats
from stewart_sim.scene.cueing_config import cueing_config
from stewart_sim.scene.load import load

ROOT = Path(__file__).resolve().parents[1]

SCENE = ROOT / "scenes" / "motion_simulator.toml"
SHIPPED = ROOT / "scenes" / "motions" / "braking_car.csv"
LOOP = 1e-3          # s: the live loop's period
STEP_AT, STEP_FOR, STEP = 1.0, 10.0, 2.0   # s, s, m/s^2: the held-out motion
AFTER = ((1.0, 1.5), (1.5, 3.0), (3.0, 6.0), (6.0, 11.0))   # s: windows after the step


def held_out(g: float) -> VehicleMotion:
    t = np.arange(round((STEP_AT + STEP_FOR) / LOOP) + 1) * LOOP
    f = np.zeros((t.size, 3))
    f[:, 2] = g
    f[t >= STEP_AT, 0] = STEP
    return VehicleMotion(t, f, np.zeros((t.size, 3)))


def fly(scene, motion: VehicleMotion, rate: float, horizon: float, real_time: bool,
        **options):
    """The motion resampled at 1 kHz through LiveOptimal; (SolveStats, t, f, w, q, qd, qdd,
    CPU time per MPC step)."""
    model = scene.model
    options = dataclasses.replace(scene.optimal, rate=rate, horizon=horizon, preview=False,
                                  **options)
    t = np.arange(0.0, motion.t[-1] - motion.t[0] + LOOP / 2, LOOP)
    f = np.stack([np.interp(t + motion.t[0], motion.t, motion.specific_force[:, i])
                  for i in range(3)], axis=1)
    w = np.stack([np.interp(t + motion.t[0], motion.t, motion.angular_velocity[:, i])
                  for i in range(3)], axis=1)
    out, cpu = [], np.zeros(t.size)
    with LiveOptimal(model, cueing_config(model), model.home, model.gravity, scene.controller,
                     options, synchronous=not real_time) as mpc:
        start = time.perf_counter()
        for k in range(t.size):
            if real_time:
                while time.perf_counter() - start < t[k]:   # bounded: the clock advances
                    time.sleep(min(2e-4, max(0.0, t[k] - (time.perf_counter() - start))))
            clock = time.process_time()
            mpc.push(t[k], f[k], w[k])
            out.append(mpc.sample(t[k]))
            cpu[k] = time.process_time() - clock
        stats = mpc.stats()
    q, qd, qdd = (np.array(a) for a in zip(*out))
    # the pushes of MPC step j: the one at its start (where it solves) to the next one's
    per_step = np.bincount(np.floor(t * rate + 1e-9).astype(int), weights=cpu)
    return stats, t, f, w, q, qd, qdd, per_step


def quality(scene, t, f, w, q, qd, qdd) -> str:
    """Perceived error RMS (specific force, angular velocity) and the stroke's least margin."""
    p = perception(VehicleMotion(t, f, w), t, q, qd, qdd, scene.model.gravity)
    m = scene.model
    lengths = inverse_kinematics(m, q, qd, with_cond=False).lengths
    margin = min(np.min(lengths - m.leg_min), np.min(m.leg_max - lengths))
    return (f"{np.sqrt(np.sum(p.rms_f**2)):.4f} | {np.sqrt(np.sum(p.rms_w**2)):.5f} | "
            f"{margin * 1e3:.1f}")


def row(name: str, s: SolveStats, cpu: np.ndarray, quality: str) -> str:
    ms = 1e3
    statuses = ", ".join(f"{k} {v}" for k, v in sorted(s.status_counts.items()))
    return (f"| {name} | {s.rate:g} | {s.steps} | {s.solves} | {s.wall_p50 * ms:.1f} / "
            f"{s.wall_p99 * ms:.1f} / {s.wall_p999 * ms:.1f} / {s.wall_max * ms:.1f} | "
            f"{s.osqp_p50 * ms:.1f} / {s.osqp_p99 * ms:.1f} / {s.osqp_p999 * ms:.1f} / "
            f"{s.osqp_max * ms:.1f} | {s.iterations_p50:.0f} / {s.iterations_max} | "
            f"{s.over_deadline} | {s.late} | {s.lead_max} | {s.tick_p99 * ms:.2f} / "
            f"{s.tick_max * ms:.2f} | {s.stopped} | {statuses} | "
            f"{np.percentile(cpu, 50) * ms:.1f} / {np.percentile(cpu, 99) * ms:.1f} / "
            f"{cpu.max() * ms:.1f} | {quality} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[50.0, 100.0])
    ap.add_argument("--horizon", type=float, default=1.0)
    ap.add_argument("--motion", type=Path, default=SHIPPED)
    ap.add_argument("--blocking", type=int, default=None)
    ap.add_argument("--tolerance", type=float, default=None)
    ap.add_argument("--real-time", action="store_true")
    args = ap.parse_args(argv)
    chosen = {k: v for k, v in (("blocking", args.blocking), ("tolerance", args.tolerance))
              if v is not None}
    scene = load(SCENE)
    g = float(np.linalg.norm(scene.model.gravity))
    motions = {args.motion.stem: read_motion(args.motion), "held-out step": held_out(g)}
    clock = "real time (worker process)" if args.real_time else "simulated clock (inline)"
    print(f"{SCENE.name}, horizon {args.horizon:g} s, no preview, 1 kHz loop, {clock}, "
          f"blocking {chosen.get('blocking', scene.optimal.blocking)}, tolerance "
          f"{chosen.get('tolerance', scene.optimal.tolerance):g}")
    print("| motion | Hz | steps | solves | solve wall p50 / p99 / p99.9 / max, ms | "
          "OSQP p50 / p99 / p99.9 / max, ms | iterations p50 / max | over 1/rate | late | "
          "lead | tick p99 / max, ms | stopped | statuses | CPU per step p50 / p99 / max, ms | "
          "perceived f error RMS, m/s^2 | perceived w error RMS, rad/s | least stroke "
          "margin, mm |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    notes = []
    for name, motion in motions.items():
        for rate in args.rates:
            stats, t, f, w, q, qd, qdd, cpu = fly(scene, motion, rate, args.horizon,
                                                  args.real_time, **chosen)
            print(row(name, stats, cpu, quality(scene, t, f, w, q, qd, qdd)), flush=True)
            if name == "held-out step":
                delivered, _ = delivered_motion(t, q, qd, qdd, scene.model.gravity)
                rest = t < STEP_AT
                means = ", ".join(
                    f"[{a:g}, {b:g}) s {np.mean(delivered[(t >= a) & (t < b), 0]):+.3f}"
                    for a, b in AFTER)
                notes.append(f"held-out step at {rate:g} Hz: delivered specific force error "
                             f"at rest, max {np.max(np.abs(delivered[rest] - f[rest])):.3g} "
                             f"m/s^2; mean delivered f_x (vehicle {STEP:g}): {means}; "
                             f"at t = 11 s f_x {delivered[-1, 0]:+.3f}, pitch "
                             f"{np.rad2deg(q[-1, 4] - scene.model.home[4]):+.2f} deg, surge "
                             f"{q[-1, 0] - scene.model.home[0]:+.3f} m")
    print()
    for line in notes:
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
