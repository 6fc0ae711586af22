"""Speed of the C core (stewart_fmu/native) and of the Python API over it, one core, one run.

Prints one table; the ratios within the run matter more than the absolute numbers (the machine
is shared and noisy: every figure is the best of several repeats).

- Plant step: RK4, 1 ms communication step, the full micro-manipulator (default options:
  max_step 1 ms, so 4 right-hand sides + the power-balance check per step), started from the
  hold at home with a small push. C: `stewart_data_run` runs N steps in ONE cffi call, so the
  time per step is the C step itself (the single call overhead, ~0.1 us, is spread over N).
  Also the C step called once per step from Python (core.step with numpy arrays, and
  core.Run.step on a stewart_data held in C: what a Python plant would pay),
  and Plant.do_step (the in-process FMI component: Python per step, the same C step).
- Single calls from Python: core.inverse_dynamics / forward_dynamics on (6,) arrays (with a
  given `out` and allocating), and the public stewart_fmu.inverse_dynamics / forward_dynamics
  (shape checks and typed errors on top).
- Batch inverse dynamics over 100,000 samples of a smooth trajectory, C and the public API.

For comparison, compiled Python kernels of the same arithmetic (the recorded reference's,
tools/plant_reference.py), measured in the same runs: Plant.do_step 7.8 us, single calls
2.5 / 2.8 us, batch 2.38 M samples/s.

Run: .venv/bin/python benchmarks/bench_native.py [--samples N] [--steps N]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from stewart_fmu import forward_dynamics, inverse_dynamics, load_scene
from stewart_fmu.native import core
from stewart_fmu.stability import default_options, hold_state
from stewart_fmu.plant import Plant

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"


def best_time(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def per_call(fn, calls: int, repeats: int = 7) -> float:
    def loop():
        for _ in range(calls):
            fn()
    return best_time(loop, repeats) / calls


def smooth_trajectory(model, n: int, duration: float = 10.0):
    t = np.linspace(0.0, duration, n)[:, None]
    amp = np.array([0.01, 0.01, 0.01, 0.1, 0.1, 0.1])
    w = 2 * np.pi * np.array([0.5, 0.7, 0.9, 0.6, 0.8, 1.0])
    return (model.home + amp * np.sin(w * t), amp * w * np.cos(w * t),
            -amp * w**2 * np.sin(w * t))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--steps", type=int, default=2000)
    args = ap.parse_args()
    model = load_scene(SCENE)
    P = core.native_params(model.params)
    opts = default_options(model)
    assert opts.method == "rk4" and opts.max_step == 1e-3, opts
    _, F_hold = hold_state(model)
    F = F_hold + 0.01 * np.abs(F_hold).max() * np.array([1.0, -1.0, 0.5, 0.2, -0.7, 0.1])
    h, n = 1e-3, args.steps
    rows = []

    # --- plant step ----------------------------------------------------------------------
    o = core.options("rk4", max_step=opts.max_step)
    ffi, lib = core.ffi, core.lib
    d = ffi.new("stewart_data *")
    q0, z, Fb = (ffi.from_buffer("double[]", np.array(a, dtype=float))
                 for a in (model.home, np.zeros(6), F))
    done = ffi.new("long *")

    def c_run():
        lib.stewart_data_init(P.ptr, o, q0, z, Fb, 0.0, d)
        status = lib.stewart_data_run(P.ptr, o, d, Fb, h, n, done)
        assert status == core.OK and done[0] == n, (status, done[0])
    t_c_step = best_time(c_run, 9) / n

    y0 = core.initial_state(P, model.home, np.zeros(6), F)
    e0 = core.energy_terms(P, y0)
    y1, e1 = np.empty_like(y0), np.empty(9)

    def c_py_run():
        ya, yb, ea, eb = y0.copy(), y1, e0.copy(), e1
        for _ in range(n):
            st = core.step(P, o, ya, yb, F, h, ea, eb)[0]
            assert st == core.OK
            ya, yb, ea, eb = yb, ya, eb, ea
    t_c_py_step = best_time(c_py_run, 5) / n

    def c_run_py():
        run = core.Run(P, o, model.home, rack=F)
        for _ in range(n):
            assert run.step(h) == core.OK
    t_c_run_step = best_time(c_run_py, 5) / n

    def plant_run():
        plant = Plant(model, opts)
        plant.set_force(F)
        plant.enter_initialization_mode()
        plant.exit_initialization_mode()
        t = 0.0
        for _ in range(n):
            plant.do_step(t, h)
            t = plant.time
    t_nb_step = best_time(plant_run, 5) / n
    rows += [("plant step rk4 1 ms, C loop (stewart_data_run)", t_c_step * 1e6, "us", "<= 3.75"),
             ("plant step rk4 1 ms, C per call from Python (core.step)", t_c_py_step * 1e6, "us", ""),
             ("plant step rk4 1 ms, C per call from Python (core.Run.step)", t_c_run_step * 1e6, "us", ""),
             ("plant step rk4 1 ms, Plant.do_step (Python per step)", t_nb_step * 1e6, "us", "")]

    # --- single calls --------------------------------------------------------------------
    Q, QD, QDD = smooth_trajectory(model, args.samples)
    q, qd, qdd = Q[123].copy(), QD[123].copy(), QDD[123].copy()
    sigma = inverse_dynamics(model, q, qd, qdd)
    out = np.empty(6)
    calls = 20_000
    t_inv_out = per_call(lambda: core.inverse_dynamics(P, q, qd, qdd, out), calls)
    t_inv = per_call(lambda: core.inverse_dynamics(P, q, qd, qdd), calls)
    t_fwd_out = per_call(lambda: core.forward_dynamics(P, q, qd, sigma, out), calls)
    t_fwd = per_call(lambda: core.forward_dynamics(P, q, qd, sigma), calls)
    t_nb_inv = per_call(lambda: inverse_dynamics(model, q, qd, qdd), calls)
    t_nb_fwd = per_call(lambda: forward_dynamics(model, q, qd, sigma), calls)
    rows += [("inverse_dynamics, one call from Python, C (out given)", t_inv_out * 1e6, "us", "<= 1.5"),
             ("inverse_dynamics, one call from Python, C (allocating)", t_inv * 1e6, "us", "<= 1.5"),
             ("inverse_dynamics, one call, public API", t_nb_inv * 1e6, "us", ""),
             ("forward_dynamics, one call from Python, C (out given)", t_fwd_out * 1e6, "us", "<= 1.5"),
             ("forward_dynamics, one call from Python, C (allocating)", t_fwd * 1e6, "us", "<= 1.5"),
             ("forward_dynamics, one call, public API", t_nb_fwd * 1e6, "us", "")]

    # --- batch ---------------------------------------------------------------------------
    outb = np.empty_like(Q)
    t_cb = best_time(lambda: core.inverse_dynamics_batch(P, Q, QD, QDD, outb), 9)
    _, index, status = core.inverse_dynamics_batch(P, Q, QD, QDD, outb)
    assert (index, status) == (-1, core.OK)
    ref = inverse_dynamics(model, Q, QD, QDD)
    agree = float(np.max(np.abs(outb - ref)) / np.max(np.abs(ref)))
    t_nb = best_time(lambda: inverse_dynamics(model, Q, QD, QDD), 9)
    rows += [(f"batch inverse dynamics {args.samples} samples, C", args.samples / t_cb / 1e6, "M/s",
              ">= 2.4 (stretch 7)"),
             (f"batch inverse dynamics {args.samples} samples, public API", args.samples / t_nb / 1e6, "M/s", "")]

    width = max(len(r[0]) for r in rows)
    print(f"{'what':{width}s}  {'value':>8s}  unit  target")
    for name, value, unit, target in rows:
        print(f"{name:{width}s}  {value:8.3f}  {unit:4s}  {target}")
    print(f"ratios in this run: Plant.do_step / C loop step {t_nb_step / t_c_step:.1f}x, "
          f"public inverse call / C call {t_nb_inv / t_inv:.2f}x; batch C vs public API max "
          f"rel. difference {agree:.1e}")


if __name__ == "__main__":
    main()
