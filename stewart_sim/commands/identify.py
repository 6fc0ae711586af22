"""`stewart-sim identify SCENE --runs RUN.csv [RUN2.csv ...] --out DIR [--validate RUN.csv ...]
[--refine]`:
the inertial and friction parameters of a platform from its measured runs (leg lengths and rack
forces or motor currents). The pipeline is stewart_sim/studies/identify/study.py, the files
stewart_sim/studies/identify/report.py, the run format stewart_sim/studies/identify/runs.py, the
output-error refinement stewart_sim/studies/identify/refine.py.
"""
from __future__ import annotations

import argparse

from stewart_sim.shell.argtypes import number


def _positive(v: float) -> bool:
    return v > 0


def _finite(v: float) -> bool:
    return abs(v) < 1.0   # s: a second or more is a mistake, not a sensor (NaN fails too)


def add_parser(sub, help_text: str) -> None:
    """Register `identify` on the command line's subparsers."""
    p = sub.add_parser(
        "identify", help=help_text,
        description="Identify the platform's inertial and friction parameters from runs: "
                    "forward kinematics of the measured leg lengths, zero-phase filtered "
                    "derivatives, the regressor sigma = Y(q, qd, qdd) pi of the C core, base "
                    "parameters (QR with pivoting), weighted least squares with standard "
                    "deviations and a physically consistent set of parameters (semidefinite "
                    "program). Writes DIR/identified.toml (the scene with the identified "
                    "values, every other key and comment kept), base_parameters.csv, "
                    "standard_parameters.csv, residuals.png, report.md and, with --validate, "
                    "validation.png, all or nothing.")
    p.add_argument("scene", metavar="SCENE", help="the prior scene (TOML)")
    p.add_argument("--runs", required=True, nargs="+", metavar="RUN.csv",
                   help="runs: columns t (s), l1..l6 (m) and sigma1..sigma6 (N), or force1..6, "
                        "or current1..6 (A, with [drive] and [controller.motor]); x..thz may "
                        "be added")
    p.add_argument("--validate", nargs="+", default=[], metavar="RUN.csv",
                   help="held-out runs: their forces predicted with the identified and the "
                        "prior parameters")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--cutoff", type=number(float, "a number", _positive, "a number > 0"),
                   metavar="HZ", help="low-pass cut-off of the pose (default: from the data)")
    p.add_argument("--refine", action="store_true",
                   help="then refine by output error: the forward model's leg lengths fitted to "
                        "the measured ones (short segments from the measured state, driven by "
                        "the measured forces), with a force delay and per-leg force biases")
    p.add_argument("--force-delay", type=number(float, "a number", _finite,
                                                "a number of seconds in (-1, 1)"),
                   default=0.0, metavar="S",
                   help="the forces belong to the motion this long before their time stamp "
                        "(the emulated device's recordings: half a controller period, 0.0005 at "
                        "1 kHz: each row's force is the mean over the tick ending at t); "
                        "default 0")
    p.add_argument("--partial", action="store_true",
                   help="identify what the runs determine when they excite less than the "
                        "scene's structure allows; the rest keeps its prior value")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run `identify`; StewartError subclasses for bad input."""
    from stewart_sim.scene.load import load
    from stewart_sim.studies.identify.report import percent, write_identification
    from stewart_sim.studies.identify.runs import read_run
    from stewart_sim.studies.identify.study import identify, predict

    scene = load(args.scene)
    motor = scene.controller.motor if scene.controller is not None else None
    runs = [read_run(path, scene.model, motor) for path in args.runs]
    held = [read_run(path, scene.model, motor) for path in args.validate]
    ident = identify(scene.model, runs, args.cutoff, args.partial, args.force_delay)
    refined = None
    if args.refine:
        from stewart_sim.shell.progress import Progress
        from stewart_sim.studies.identify.refine import refine

        bar = Progress()
        refined = refine(ident, runs, progress=lambda k, n: bar.update(
            "refining (output error)", k, n, unit="evaluations at most"))
        bar.close()
        print(f"refined {len(refined.refined)} base parameters, delay and biases on "
              f"{refined.segments} segments: length RMS {refined.rms_before * 1e6:.4g} -> "
              f"{refined.rms_after * 1e6:.4g} um; delay {refined.delay * 1e3:.4g} +- "
              f"{refined.delay_std * 1e3:.2g} ms")
    validation = [predict(ident, r, refined.pi if refined else None) for r in held]
    for path in write_identification(ident, args.scene, validation, args.out, refined):
        print(f"wrote {path}")
    e = ident.estimate
    rel = e.std / abs(e.beta).clip(1e-300)
    print(f"{ident.base.rank} base parameters from {e.samples} rows; median std "
          f"{float(sorted(rel)[len(rel) // 2]):.2%} of the estimate"
          + ("; consistency constraints active" if e.constrained else ""))
    for v in validation:
        print(f"{v.run.path.name}: force RMS error {percent(v.rms_error('identified'))} of peak "
              f"(prior {percent(v.rms_error('prior'))}), "
              + ("at the noise floor" if v.at_noise_floor() else "above the noise floor"))
