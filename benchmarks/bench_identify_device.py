"""The issue's device figures of `identify`, over seeds: the emulated device (hil.device.Device
in process, lockstep, as `run --link` drives it) with a hidden true scene whose every inertial
and friction parameter is drawn up to +-30 % off the prior's (platform moments redrawn until
they obey the triangle inequality), 1 um encoders and force noise 1 % of the excitation's
peak force, follows an `excite` trajectory; its recording is identified (force delay half a
period: the device's force is the mean over the tick ending at t) and a second recording on
another excitation is predicted.

    python benchmarks/bench_identify_device.py [--seeds N] [--duration S]

Prints per seed: the share of base parameters whose truth lies inside the reported 3-sigma
interval, the held-out force RMS error (% of peak) of the identified and the prior model and
the ratio of the identified one to the noise floor (worst leg); then the totals.
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from controller.config import controller_config
from hil.client import run_lockstep_direct
from hil.device import Device
from hil.sensors import SensorConfig
from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.io import write_csv
from stewart_fmu.standard import standard_parameters
from stewart_sim.closed_loop.over_link import link_reference, record_table
from stewart_sim.studies.excite.design import design, excitation
from stewart_sim.studies.identify.runs import read_run
from stewart_sim.studies.identify.study import identify, predict
from stewart_sim.studies.identify.synthetic import perturbed_model

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"


def record(model, config, truth, traj, noise, seed, path):
    sensors = SensorConfig(encoder_resolution=1e-6, force_noise=noise, seed=seed)
    run = run_lockstep_direct(Device(model, config, lockstep=True, truth=truth,
                                     sensors=sensors), link_reference(model, config, traj))
    write_csv(path, record_table(run))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=60.0)
    args = ap.parse_args()
    prior = load_scene(SCENE)
    config = controller_config(prior)
    ident_traj = excitation(prior, config, design(prior, config), int(args.duration / 5.0),
                            config.rate).trajectory
    held_traj = excitation(prior, config, design(prior, config, period=4.0), 5,
                           config.rate).trajectory
    peak = float(np.max(np.abs(inverse_dynamics(prior, ident_traj.q, ident_traj.qd,
                                                ident_traj.qdd))))
    noise = 0.01 * peak
    print(f"excitation {args.duration:g} s, force peak (prior) {peak:.3g} N, force noise "
          f"{noise:.3g} N, encoders 1 um", flush=True)
    inside = total = 0
    worst_rms = worst_ratio = 0.0
    with tempfile.TemporaryDirectory() as d:
        for seed in range(args.seeds):
            rng = np.random.default_rng(seed)
            truth = perturbed_model(prior, rng)
            a = record(prior, config, truth, ident_traj, noise, 2 * seed, Path(d) / "a.csv")
            b = record(prior, config, truth, held_traj, noise, 2 * seed + 1, Path(d) / "b.csv")
            ident = identify(prior, [read_run(a, prior)], force_delay=0.5 / config.rate)
            bt = ident.base.beta(standard_parameters(truth))
            z = np.abs(ident.estimate.beta - bt) / ident.estimate.std
            inside += int(np.sum(z <= 3))
            total += z.size
            v = predict(ident, read_run(b, prior))
            rms = float(np.sqrt(np.mean(v.rms("identified") ** 2)) / v.force_peak)
            rms_p = float(np.sqrt(np.mean(v.rms("prior") ** 2)) / v.force_peak)
            ratio = float(np.max(v.rms("identified") / v.noise_floor))
            worst_rms, worst_ratio = max(worst_rms, rms), max(worst_ratio, ratio)
            print(f"seed {seed}: inside 3 sigma {np.mean(z <= 3):.1%}; held-out RMS {rms:.3%} of "
                  f"peak (prior {rms_p:.3%}); RMS / noise floor {ratio:.3f}", flush=True)
    print(f"\n{args.seeds} seeds: truth inside 3 sigma for {inside / total:.1%} of base "
          f"parameters; worst held-out RMS {worst_rms:.3%} of peak; worst RMS / noise floor "
          f"{worst_ratio:.3f}")


if __name__ == "__main__":
    main()
