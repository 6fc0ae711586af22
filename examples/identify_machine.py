"""The model meets the machine (docs/guides/identification-and-calibration.md): two
excitation trajectories, the emulated device with a hidden true scene recording a run of each
over the serial link, identification on one, validation on the other, and the identified values
beside the truth the device hid."""
import tempfile
from pathlib import Path

import numpy as np

from stewart_fmu import load_scene
from stewart_sim.cli import main

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
TRUTH = ROOT / "scenes" / "machines" / "micro_manipulator_truth.toml"


def stewart_sim(*args) -> None:
    status = main([str(a) for a in args])
    if status != 0:
        raise SystemExit(f"stewart-sim {args[0]} exited {status}")


def waypoints(path: Path, seed: int, duration: float, every: float = 0.4) -> Path:
    """Seeded random poses around home every `every` seconds, home at both ends: the same file
    on every machine (excite's optimiser reaches another optimum under each BLAS kernel)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + every / 2, every)
    spread = np.array([0.012, 0.012, 0.015, 0.12, 0.12, 0.10])          # m, rad
    q = np.clip(rng.standard_normal((t.size, 6)), -2.5, 2.5) * spread
    q[[0, -1]] = 0.0
    q[:, 2] += 0.12                                                      # home height (m)
    np.savetxt(path, np.column_stack([t, q]), delimiter=",", comments="",
               header="t,x,y,z,thx,thy,thz")
    return path


with tempfile.TemporaryDirectory() as tmp:
    d = Path(tmp)
    for name, seed, duration in (("T", 1, 10.0), ("V", 2, 8.0)):    # identify on T, hold out V
        stewart_sim("trajectory", SCENE, "--waypoints", waypoints(d / f"{name}_w.csv", seed,
                                                                  duration),
                    "--out", d / f"{name}.csv")
    for trajectory, run in (("T.csv", "run1"), ("V.csv", "run2")):
        stewart_sim("run", SCENE, "--link", "serial", "--truth", TRUTH,
                    "--trajectory", d / trajectory, "--record", d / f"{run}.csv", "--out", d / run)
    # the device's force in each row is the mean over the tick ending at t: half a period late
    stewart_sim("identify", SCENE, "--runs", d / "run1.csv", "--validate", d / "run2.csv",
                "--force-delay", 0.0005, "--out", d / "ident")
    found, truth, prior = (load_scene(p) for p in (d / "ident" / "identified.toml", TRUTH, SCENE))
    for name, unit, get in (("viscous friction", "N s/m", lambda m: m.friction.viscous_legs),
                            ("Coulomb friction", "N", lambda m: m.friction.coulomb_legs),
                            ("reflected drive mass", "kg", lambda m: m.drive.reflected_masses)):
        print(f"{name} ({unit}):\n  prior      {np.round(get(prior), 3)}\n  identified "
              f"{np.round(get(found), 3)}\n  truth      {np.round(get(truth), 3)}")
        print(f"{name} within {np.max(np.abs(get(found) - get(truth))):.2g} {unit} of the "
              f"truth (the prior: {np.max(np.abs(get(prior) - get(truth))):.2g})")
