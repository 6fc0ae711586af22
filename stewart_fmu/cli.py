"""The stewart-sim command line: the only module that knows about files, plots and progress.

Subcommands: `inverse` (the contract's command), `paper` (Section 3 rerun), `demo` (what
`make demo` runs), `run` (closed loop: the per-axis controllers around the plant or an FMU),
`compare` (constant-load vs Kane control over a drive-inertia sweep), `scene-info` and
`export-fmu`. Exit status: 0 on success; 2 on a usage error or on an
error in the inputs (every StewartError: scene, trajectory, pose); 1 when an output cannot be
written (OutputError); 130 on Ctrl-C. Every output file is written atomically: an error leaves
an existing file as it was.
"""
from __future__ import annotations

import argparse
import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np

from . import io
from .demo import DEMO_DURATION, DEMO_RATE, demo_trajectory
from .dynamics import inverse_dynamics, inverse_dynamics_parts, present_parts
from .errors import KinematicsError, SceneError, StewartError, TrajectoryError
from .fmu import export_fmu
from .kinematics import check_poses, inverse_kinematics
from .model import Model
from .paper import PaperResults, run_paper_experiments
from .paper_report import write_paper_report
from .plots import drive_figure, forces_figure, leg_errors_figure, save_figure, tracking_figure
from .progress import Progress
from .scene import load_scene

PROG = "stewart-sim"
DEFAULT_SCENE = Path("scenes") / "micro_manipulator.toml"
CHUNK_SAMPLES = 50_000       # samples per block of the pose check and of the dynamics
RUN_MOVE = 0.3               # `run`: each quintic move (out, back) takes this share of the run
RUN_HOLD = 0.2               # ... and each hold after a move this share
RUN_MIN_MOVE_SAMPLES = 10    # ... and has at least this many controller samples


class OutputError(Exception):
    """An output file or directory cannot be written (exit status 1)."""


@contextmanager
def writing(path: Path) -> Iterator[None]:
    """Turn an OSError while writing `path` into an OutputError naming it (not a temporary)."""
    try:
        yield
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 I/O failure, 2 bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, usage errors: argparse has printed the message
        return exc.code if isinstance(exc.code, int) else 2
    try:
        args.run(args)
    except StewartError as exc:
        return _fail(str(exc), 2)
    except OutputError as exc:
        return _fail(str(exc), 1)
    except KeyboardInterrupt:
        return _fail("interrupted", 130)
    return 0


def _fail(message: str, status: int) -> int:
    """Print `stewart-sim: error: message` on stderr and return the status."""
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return status


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with its subcommands."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Dynamics of Stewart platforms (Kane's method).",
        epilog="Exit status: 0 ok, 2 usage error or bad scene/trajectory/pose, 1 a file could "
               "not be written.")
    sub = parser.add_subparsers(title="commands", required=True, metavar="COMMAND")

    p = sub.add_parser("inverse", help="actuator forces along a trajectory",
                       description="Actuator (rack) forces for a trajectory CSV, with exactly "
                                   "the effects the scene declares.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--trajectory", required=True, metavar="TRAJ.csv",
                   help="columns t,x,y,z,thx,thy,thz, their rates d*, accelerations dd*")
    p.add_argument("--out", required=True, metavar="FORCES.csv",
                   help="written atomically: t,sigma1..sigma6,cond[,<part>1..<part>6 ...]")
    p.add_argument("--parts", action="store_true",
                   help="add the breakdown of sigma by contribution (the parts the scene has)")
    p.set_defaults(run=cmd_inverse)

    p = sub.add_parser("paper", help="rerun the paper's Section 3 experiments",
                       description="Rerun the paper's Section 3 experiments and write the report.")
    p.add_argument("scene", metavar="SCENE", nargs="?",
                   help=f"scene file (default: {DEFAULT_SCENE}, from the current directory or "
                        "the source checkout)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.set_defaults(run=cmd_paper)

    p = sub.add_parser("demo", help="demonstration run (what `make demo` does)",
                       description="A smooth six-axis demonstration move, its forces and plot, "
                                   "and the paper rerun into DIR/paper/.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", type=_positive_seconds, default=DEMO_DURATION, metavar="SECONDS",
                   help=f"length of the demonstration move (default {DEMO_DURATION:g} s, "
                        f"sampled at {DEMO_RATE:g} Hz)")
    p.set_defaults(run=cmd_demo)

    p = sub.add_parser("run", help="closed-loop run: per-axis controllers around the plant",
                       description="Track a demonstration reference (a quintic six-axis move "
                                   "out and back, with holds) with the scene's per-axis "
                                   "controllers ([controller] table) around the in-process plant "
                                   "or an exported FMU; writes run.csv, three plots and "
                                   "summary.md into DIR and prints the summary.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [controller] table")
    p.add_argument("--fmu", metavar="PLANT.fmu",
                   help="drive this FMU (export-fmu of the same scene) through fmpy instead of "
                        "the in-process plant")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", type=_positive_seconds, default=DEMO_DURATION, metavar="SECONDS",
                   help=f"length of the run (default {DEMO_DURATION:g} s): the move out and "
                        f"back take {100 * RUN_MOVE:g} %% of it each, the holds after them "
                        f"{100 * RUN_HOLD:g} %% each")
    p.add_argument("--feedforward", choices=("none", "constant_load", "kane"),
                   help="override the scene's controller.feedforward")
    p.set_defaults(run=cmd_run)

    p = sub.add_parser("compare", help="constant-load vs Kane control over a gear-ratio sweep",
                       description="Sweep each scene's gear ratio (m_d / m_load over "
                                   "0.1-100), re-tune the per-axis PID at every point and track "
                                   "one reference with feedforward none, constant_load and "
                                   "kane; writes comparison.csv, comparison.png and report.md.")
    p.add_argument("scenes", metavar="SCENE", nargs="+", help="scene files (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--points", type=_sweep_points, default=8, metavar="N",
                   help="log-spaced sweep points per scene (default 8; the scene's own gear "
                        "ratio is added)")
    p.set_defaults(run=cmd_compare)

    p = sub.add_parser("scene-info", help="print the model a scene builds",
                       description="Print the model a scene file builds.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.set_defaults(run=cmd_scene_info)

    p = sub.add_parser("export-fmu", help="export the plant as an FMI 2.0 co-simulation FMU",
                       description="Build an FMI 2.0 co-simulation FMU of the scene's plant "
                                   "(pythonfmu). It runs in the importer's Python, which needs "
                                   "stewart-sim installed.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    p.add_argument("-o", "--out", required=True, metavar="PLANT.fmu", help="the FMU to write")
    p.set_defaults(run=cmd_export_fmu)
    return parser


def _positive_seconds(text: str) -> float:
    """argparse type: a finite duration > 0 s."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text!r}")
    return value


def _sweep_points(text: str) -> int:
    """argparse type: a sweep size of 1 to 100 points."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 1 <= value <= 100:
        raise argparse.ArgumentTypeError(f"must be 1 to 100, got {value}")
    return value


# --- inverse ---------------------------------------------------------------------------------

def cmd_inverse(args: argparse.Namespace) -> None:
    """`stewart-sim inverse SCENE --trajectory TRAJ.csv --out FORCES.csv [--parts]`."""
    model = load_scene(args.scene)
    progress = Progress()
    try:
        n, _ = run_inverse(model, Path(args.trajectory), Path(args.out), args.parts, progress)
    finally:
        progress.close()
    print(f"wrote {args.out}: {n} samples" + (" with the breakdown by part" if args.parts else ""))


def run_inverse(model: Model, trajectory: Path, out: Path, parts: bool, progress: Progress,
                keep: bool = False) -> tuple[int, np.ndarray | None]:
    """Read, check every pose, compute and write the forces; the table too if `keep`."""
    t, q, qd, qdd = io.read_trajectory(
        trajectory, progress=lambda rows: progress.update(f"reading {trajectory}", rows))
    cond = check_trajectory(model, t, q, trajectory, progress)
    kept: list[np.ndarray] = []
    chunks = force_chunks(model, (t, q, qd, qdd), cond, parts, trajectory, progress)
    with writing(out):
        io.write_csv_chunks(out, _keep(chunks, kept) if keep else chunks)
    return t.size, (np.concatenate(kept) if keep else None)


def _chunks(n: int) -> Iterator[slice]:
    """Consecutive slices of at most CHUNK_SAMPLES samples covering range(n)."""
    for start in range(0, n, CHUNK_SAMPLES):
        yield slice(start, min(start + CHUNK_SAMPLES, n))


def check_trajectory(model: Model, t: np.ndarray, q: np.ndarray, source: Path,
                     progress: Progress) -> np.ndarray:
    """check_poses on every sample (stroke, singularity), block by block; returns cond(J)."""
    cond = np.empty(t.size)
    for s in _chunks(t.size):
        try:
            cond[s] = check_poses(model, q[s], t[s]).cond
        except KinematicsError as exc:
            raise _relocated(exc, s.start, t, source) from None
        progress.update("checking poses", s.stop, t.size)
    return cond


def force_chunks(model: Model, traj: tuple[np.ndarray, ...], cond: np.ndarray, parts: bool,
                 source: Path, progress: Progress) -> Iterator[np.ndarray]:
    """The force table block by block: inverse_dynamics (and its parts) per block of samples."""
    t, q, qd, qdd = traj
    names = present_parts(model) if parts else ()
    for s in _chunks(t.size):
        try:
            sigma = inverse_dynamics(model, q[s], qd[s], qdd[s])
            breakdown = inverse_dynamics_parts(model, q[s], qd[s], qdd[s]) if parts else {}
        except KinematicsError as exc:
            raise _relocated(exc, s.start, t, source) from None
        yield force_table(t[s], sigma, cond[s], {k: breakdown[k] for k in names})
        progress.update("computing and writing forces", s.stop, t.size)


def force_table(t: np.ndarray, sigma: np.ndarray, cond: np.ndarray,
                parts: Mapping[str, np.ndarray]) -> np.ndarray:
    """Columns t, sigma1..6, cond, then <part>1..6 for each part given."""
    cols = {"t": t, **{f"sigma{i + 1}": sigma[:, i] for i in range(6)}, "cond": cond}
    for name, values in parts.items():
        cols.update({f"{name}{i + 1}": values[:, i] for i in range(6)})
    return io.named_array(cols)


def _keep(chunks: Iterator[np.ndarray], store: list[np.ndarray]) -> Iterator[np.ndarray]:
    """Pass the chunks through, keeping a reference to each."""
    for chunk in chunks:
        store.append(chunk)
        yield chunk


def _relocated(exc: KinematicsError, offset: int, t: np.ndarray, source: Path) -> KinematicsError:
    """The same error for the whole trajectory: its sample index, time and file line."""
    if exc.index is None:
        return exc
    message = str(exc)
    suffix = str(KinematicsError("", exc.index, exc.time))  # the location the error appended
    if message.endswith(suffix):
        message = message[:-len(suffix)]
    index = exc.index + offset
    return type(exc)(f"{source}, line {index + 2}: {message}", index=index, time=float(t[index]))


# --- paper -----------------------------------------------------------------------------------

def cmd_paper(args: argparse.Namespace) -> None:
    """`stewart-sim paper [SCENE] --out DIR`."""
    model = load_scene(resolve_scene(args.scene))
    report = run_paper(model, Path(args.out))
    print(f"wrote {report}")


def resolve_scene(scene: str | None) -> Path:
    """The scene given, else DEFAULT_SCENE here, else the one in the source checkout."""
    if scene is not None:
        return Path(scene)
    if DEFAULT_SCENE.is_file():
        return DEFAULT_SCENE
    checkout = Path(__file__).resolve().parents[1] / DEFAULT_SCENE
    if checkout.is_file():
        return checkout
    raise SceneError("<file>", f"no scene given, and no {DEFAULT_SCENE} in the current directory "
                               f"({Path.cwd()}) or at {checkout}")


def run_paper(model: Model, out: Path) -> Path:
    """Rerun the paper's experiments into `out`, print the verdicts; returns report.md."""
    results = run_paper_experiments(model)
    with writing(out):
        paths = write_paper_report(results, out)
    print_verdicts(results)
    return next(p for p in paths if p.name == "report.md")


def print_verdicts(results: PaperResults) -> None:
    """One line per claim of the paper: agrees / does not agree."""
    print(f"paper rerun on '{results.scene}':")
    for v in results.verdicts:
        print(f"  {'agrees' if v.agrees else 'does not agree'}: {v.claim}")


# --- demo ------------------------------------------------------------------------------------

def cmd_demo(args: argparse.Namespace) -> None:
    """`stewart-sim demo SCENE --out DIR [--duration S]`."""
    model = load_scene(args.scene)
    out = Path(args.out)
    for path in run_demo(model, out, args.duration):
        print(f"wrote {path}")


def run_demo(model: Model, out: Path, duration: float) -> list[Path]:
    """Demonstration trajectory, its forces (the `inverse` path), their plot, the paper rerun."""
    t, q, qd, qdd = demo_trajectory(model, duration)
    traj = out / "demo_trajectory.csv"
    with writing(traj):
        io.write_csv(traj, io.trajectory_table(t, q, qd, qdd))
    forces = out / "demo_forces.csv"
    progress = Progress()
    try:
        _, table = run_inverse(model, traj, forces, True, progress, keep=True)
    finally:
        progress.close()
    title = f"{model.name}: demonstration move ({duration:g} s, {DEMO_RATE:g} Hz)"
    png = out / "demo_forces.png"
    with writing(png):
        save_figure(forces_figure(table, present_parts(model), title), png)
    written = [traj, forces, png]
    if model.legs is None or model.drive is None:
        print("paper rerun skipped: it needs the scene's [legs] and [drive]", file=sys.stderr)
    else:
        written.append(run_paper(model, out / "paper"))
    return written


# --- run -------------------------------------------------------------------------------------

def cmd_run(args: argparse.Namespace) -> None:
    """`stewart-sim run SCENE [--fmu PLANT.fmu] --out DIR [--duration S] [--feedforward F]`."""
    from dataclasses import replace

    from controller.config import controller_config

    model = load_scene(args.scene)
    config = controller_config(model)
    if args.feedforward is not None:
        config = replace(config, feedforward=args.feedforward)
    out = Path(args.out)
    result, traj = run_closed_loop_files(model, config, args.duration, out,
                                         Path(args.fmu) if args.fmu else None)
    print((out / "summary.md").read_text(encoding="utf-8"), end="")
    for name in RUN_FILES:
        print(f"wrote {out / name}")


RUN_FILES = ("run.csv", "run_tracking.png", "run_errors.png", "run_forces.png", "summary.md")


def run_reference(model: Model, config, duration: float):
    """The demonstration reference of `run`: from rest at home a quintic six-axis move out
    (RUN_MOVE of the duration), a hold (RUN_HOLD), the move back and a second hold, sampled
    at the controller rate (controller.comparison.move_and_hold)."""
    from controller.comparison import move_and_hold

    shortest = RUN_MIN_MOVE_SAMPLES / (RUN_MOVE * config.rate)
    if duration < shortest:
        raise TrajectoryError(f"--duration {duration:g} s is too short: each move needs "
                              f"{RUN_MIN_MOVE_SAMPLES} controller samples ({shortest:.3g} s "
                              f"or more at {config.rate:g} Hz)")
    return move_and_hold(model, config.rate, RUN_MOVE * duration, RUN_HOLD * duration, back=True)


def run_closed_loop_files(model: Model, config, duration: float, out: Path,
                          fmu: Path | None = None):
    """Run the closed loop (in-process plant, or the FMU) and write RUN_FILES into `out`;
    returns (ClosedLoopResult, reference)."""
    from controller.cosim import run_closed_loop

    traj = run_reference(model, config, duration)
    plant = open_fmu(fmu, model) if fmu is not None else None
    progress = Progress()
    try:
        result = run_closed_loop(model, config, traj, plant=plant,
                                 progress=lambda k, n: progress.update("closed loop", k, n))
        progress.update("closed loop", len(traj.t), len(traj.t))
    finally:
        progress.close()
        if plant is not None:
            plant.close()
    where = f"FMU {fmu}" if fmu is not None else "in-process plant"
    title = (f"{model.name}: closed loop, feedforward {config.feedforward}, {where} "
             f"({traj.t[-1]:g} s at {config.rate:g} Hz)")
    m = config.motor
    with writing(out):
        io.write_csv(out / "run.csv", result.table)
        save_figure(tracking_figure(result.table, f"{title}\npose tracking"),
                    out / "run_tracking.png")
        save_figure(leg_errors_figure(result.table, f"{title}\ntracking errors"),
                    out / "run_errors.png")
        save_figure(drive_figure(result.table, m.voltage_limit, m.current_limit,
                                 f"{title}\ndrives"), out / "run_forces.png")
        io.write_text(out / "summary.md", run_summary(model, result, traj, where))
    return result, traj


def open_fmu(path: Path, model: Model):
    """controller.cosim.FmuPlant for `path`, after checking that the FMU was exported from a
    scene with the same physical parameters as `model` (its resources/scene.toml)."""
    import tomllib
    import zipfile

    from controller.cosim import FmuPlant
    from .fmu import SCENE_RESOURCE
    from .scene import scene_from_dict

    if not path.is_file():
        raise StewartError(f"no such FMU: {path}")
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            embedded = (tomllib.loads(zf.read(f"resources/{SCENE_RESOURCE}").decode("utf-8"))
                        if f"resources/{SCENE_RESOURCE}" in names else None)
    except (zipfile.BadZipFile, OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise StewartError(f"{path}: not a readable FMU: {exc}") from None
    if embedded is not None:
        other = scene_from_dict(embedded, source=f"{path}:resources/{SCENE_RESOURCE}")
        if not np.array_equal(other.params, model.params):
            raise StewartError(f"{path} was exported from a scene with other physical "
                               f"parameters than {model.source}: the controller would be "
                               "designed for another plant (export-fmu the same scene)")
    try:
        return FmuPlant(path)
    except Exception as exc:  # fmpy raises plain exceptions for foreign or broken FMUs
        raise StewartError(f"{path}: cannot load the FMU: {type(exc).__name__}: {exc}") from None


def run_summary(model: Model, result, traj, where: str) -> str:
    """summary.md of a run: design, tracking per leg and per pose coordinate, effort, timing."""
    s, a, g, ax, cfg = result.summary, result.analysis, result.gains, result.axis, result.config
    duration = float(traj.t[-1] - traj.t[0])
    units = ("m", "m", "m", "rad", "rad", "rad")
    lines = [
        f"# Closed-loop run: {model.name}",
        "",
        f"- scene: `{model.source}`; plant: {where}",
        f"- reference: quintic six-axis move out ({RUN_MOVE * duration:.6g} s), hold "
        f"({RUN_HOLD * duration:.6g} s), move back, hold; {duration:.6g} s, "
        f"{len(traj.t)} samples at {cfg.rate:.6g} Hz; goal pose "
        f"{_vec(traj.q[int(round(RUN_MOVE * duration * cfg.rate))])}",
        f"- feedforward: {cfg.feedforward}",
        "",
        "## Design (each axis, constant load)",
        "",
        "| quantity | value |",
        "|---|---:|",
        f"| constant load m_load (kg) | {ax.load_mass:.6g} |",
        f"| reflected drive inertia m_d (kg) | {ax.reflected_mass:.6g} |",
        f"| force constant Kt zeta / r (N/A) | {ax.force_constant:.6g} |",
        f"| Kp (V/m) | {g.kp:.6g} |",
        f"| Ki (V/(m s)) | {g.ki:.6g} |",
        f"| Kd (V s/m) | {g.kd:.6g} |",
        f"| target crossover (Hz) | {cfg.bandwidth:.6g} |",
        f"| crossover (Hz) | {a.crossover_hz:.6g} |",
        f"| target phase margin (deg) | {cfg.phase_margin:.6g} |",
        f"| phase margin (deg) | {a.phase_margin_deg:.6g} |",
        f"| gain margin (dB) | {a.gain_margin_db:.6g} |",
        f"| step rise time 10-90 % (s) | {a.rise_time:.6g} |",
        f"| step overshoot (%) | {a.overshoot_pct:.6g} |",
        f"| step settling time 2 % (s) | {a.settling_time:.6g} |",
        "",
        "## Tracking",
        "",
        "| leg | RMS error (m) | max error (m) | RMS voltage (V) | peak current (A) |",
        "|---|---:|---:|---:|---:|",
    ]
    for i in range(6):
        lines.append(f"| {i + 1} | {s.leg_rms[i]:.6g} | {s.leg_max[i]:.6g} | "
                     f"{s.voltage_rms[i]:.6g} | {s.current_max[i]:.6g} |")
    lines += ["", "| coordinate | unit | RMS error | max error |", "|---|---|---:|---:|"]
    for k, name in enumerate(io.POSE):
        lines.append(f"| {name} | {units[k]} | {s.pose_rms[k]:.6g} | {s.pose_max[k]:.6g} |")
    lines += [
        "",
        "## Effort and timing",
        "",
        f"- peak current: {np.max(s.current_max):.6g} A (limit {cfg.motor.current_limit:.6g} A); "
        f"largest RMS voltage: {np.max(s.voltage_rms):.6g} V (limit "
        f"{cfg.motor.voltage_limit:.6g} V)",
        f"- saturated time: {s.saturated_time:.6g} s of {duration:.6g} s (any axis at its "
        "voltage or current limit)",
        f"- wall time: {s.wall_time:.6g} s; real-time factor: {s.realtime_factor:.6g}",
        "",
    ]
    return "\n".join(lines)


# --- compare ---------------------------------------------------------------------------------

def cmd_compare(args: argparse.Namespace) -> None:
    """`stewart-sim compare SCENE... --out DIR [--points N]`."""
    out = Path(args.out)
    for path in run_compare([Path(s) for s in args.scenes], out, args.points):
        print(f"wrote {path}")


def run_compare(scenes: Sequence[Path], out: Path, points: int = 8) -> list[Path]:
    """The drive-inertia comparison of each scene (controller.comparison), its files in `out`."""
    from controller.comparison import compare_drive_inertia, regime
    from controller.comparison_report import write_comparison_report
    from controller.config import controller_config

    models = [load_scene(s) for s in scenes]        # every scene checked before any work
    configs = [controller_config(m) for m in models]
    results = []
    progress = Progress()
    try:
        for model, config in zip(models, configs):
            results.append(compare_drive_inertia(
                model, config, n_points=points,
                progress=lambda k, n, name=model.name: progress.update(
                    f"comparison of {name}, closed-loop", k, n)))
    finally:
        progress.close()
    for c in results:
        nom = c.nominal()
        if nom is not None:
            print(f"{c.scene}: m_d / m_load = {nom.mass_ratio:.3g}, coupling {nom.coupling:.3g}: "
                  f"{regime(nom)}")
    with writing(out):
        return write_comparison_report(results, out)


# --- export-fmu ------------------------------------------------------------------------------

def cmd_export_fmu(args: argparse.Namespace) -> None:
    """`stewart-sim export-fmu SCENE -o PLANT.fmu`."""
    out = Path(args.out)
    with writing(out):
        export_fmu(args.scene, out)
    print(f"wrote {out}")


# --- scene-info ------------------------------------------------------------------------------

def cmd_scene_info(args: argparse.Namespace) -> None:
    """`stewart-sim scene-info SCENE`."""
    print(describe_model(load_scene(args.scene)))


def describe_model(model: Model) -> str:
    """The model as text: name, effects, masses, m_d, home leg lengths, cond(J) at home."""
    kin = inverse_kinematics(model, model.home)
    lines = [
        f"scene: {model.name}" + (f" ({model.source})" if model.source else ""),
        f"effects: {', '.join(model.effects) or 'none'} (platform and gravity always)",
        f"gravity: {_vec(model.gravity)} m/s^2",
        f"platform: mass {model.platform_mass:g} kg, principal inertia "
        f"{_vec(model.platform_inertia)} kg m^2",
        _describe_legs(model), _describe_drive(model), _describe_friction(model),
        f"stroke: [{_opt(model.leg_min)}, {_opt(model.leg_max)}] m",
        f"home pose: {_vec(model.home)} (m, rad)",
        f"home leg lengths: {_vec(kin.lengths)} m",
        f"cond(J) at home: {kin.cond:.6g} (rotational columns scaled by "
        f"{model.characteristic_length:.6g} m)",
    ]
    return "\n".join(lines)


def _describe_legs(model: Model) -> str:
    """Leg part masses, or that the legs are massless."""
    lg = model.legs
    if lg is None:
        return "legs: none (massless)"
    moving = model.platform_mass + 6 * (lg.lower_mass + lg.upper_mass)
    return (f"legs: lower part {lg.lower_mass:g} kg (CoM {lg.lower_com:g} m from the base joint, "
            f"inertia {_vec(lg.lower_inertia)} kg m^2), upper part {lg.upper_mass:g} kg (CoM "
            f"{lg.upper_com:g} m from the platform joint, inertia {_vec(lg.upper_inertia)} "
            "kg m^2); "
            f"platform + 12 leg parts {moving:g} kg")


def _describe_drive(model: Model) -> str:
    """Drive parameters and m_d, or that there is none."""
    dr = model.drive
    if dr is None:
        return "drive: none (m_d = 0, not modelled)"
    return (f"drive: gear ratio {dr.gear_ratio:g}, rotor inertia {dr.rotor_inertia:g} kg m^2, "
            f"pinion radius {dr.pinion_radius:g} m; m_d = zeta^2 I / r^2 = "
            f"{dr.reflected_mass:.6g} kg")


def _describe_friction(model: Model) -> str:
    """Friction coefficients, or that there is none."""
    fr = model.friction
    if fr is None:
        return "friction: none"
    return f"friction: viscous {fr.viscous:g} N s/m, Coulomb {fr.coulomb:g} N"


def _vec(a) -> str:
    """A vector as [a, b, c] with 6 significant digits."""
    return "[" + ", ".join(f"{v:.6g}" for v in np.ravel(a)) + "]"


def _opt(x: float | None) -> str:
    """A number, or 'none'."""
    return "none" if x is None else f"{x:g}"
