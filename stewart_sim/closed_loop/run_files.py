"""Files of `stewart-sim run`: the closed-loop run (CSV, plots, summary.md) on the in-process
plant or an exported FMU."""
from __future__ import annotations

import tomllib
import zipfile
from pathlib import Path

import numpy as np

from controller.config import ControllerConfig
from controller.cosim import run_closed_loop
from controller.moves import RUN_HOLD, RUN_MOVE, run_reference
from controller.plants import FmuPlant
from stewart_fmu import io
from stewart_fmu.errors import StewartError
from stewart_fmu.frames import table_from_platform
from stewart_fmu.fmu.export import SCENE_RESOURCE
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.io import writing
from stewart_fmu.model import Model
from stewart_fmu.scene import scene_from_dict
from stewart_sim.scene.describe import format_vector
from stewart_sim.scene.load import Scene
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.shell.plots import drive_figure, leg_errors_figure, save_figure, tracking_figure
from stewart_sim.shell.progress import Progress
from stewart_sim.view.files import VIEW_FILE, write_beside
from stewart_sim.view.sources import run_table_view

RUN_FILES = ("run.csv", "run_tracking.png", "run_errors.png", "run_forces.png", "summary.md",
             VIEW_FILE)
FORMATS = ("csv", "parquet")
# Every file a `run` may write (in-process, --fmu, --link: over_link.LINK_FILES): a rerun removes
# them all from an earlier set written without the manifest (outputs.MANIFEST).
ANY_RUN_FILES = (*RUN_FILES, "run.parquet", "run_link.png")


def run_files(fmt: str = "csv", view: bool = True) -> tuple[str, ...]:
    """The files `run` writes with the table in format `fmt` (and the 3D view)."""
    return (f"run.{fmt}", *(n for n in RUN_FILES[1:] if view or n != VIEW_FILE))


def check_format(fmt: str) -> None:
    """The table format must be writable here: parquet needs pyarrow (optional dependency)."""
    if fmt not in FORMATS:
        raise StewartError(f"run: --format must be one of {FORMATS}, got {fmt!r}")
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401  (optional: only --format parquet needs it)
        except ImportError:
            raise StewartError("run: --format parquet needs pyarrow: pip install "
                               "'stewart-sim[parquet]' (or pyarrow)") from None


def write_parquet(path: Path, table: np.ndarray) -> Path:
    """A structured array as a Parquet file (one float64 column per field), atomically."""
    import pyarrow as pa  # optional dependency, checked by check_format
    import pyarrow.parquet as pq

    arrow = pa.table({name: table[name] for name in table.dtype.names})
    return io.atomic_write(path, lambda fh: pq.write_table(arrow, fh), binary=True)


def run_closed_loop_files(model: Model, config: ControllerConfig, duration: float, out: Path,
                          fmu: Path | None = None, fmt: str = "csv", view: bool = True,
                          options: IntegratorOptions | None = None, frame: str = "platform"):
    """Run the closed loop (in-process plant with `options`, the scene's [solver]; or the FMU)
    and write run_files(fmt, view) into `out` (progress covers the writing: a long run's CSV
    takes seconds), the table's poses and its tracking figure in `frame` of the scene's
    [frames]; returns (ClosedLoopResult, reference)."""
    check_format(fmt)
    traj = run_reference(model, config, duration)
    plant = open_fmu(fmu, model) if fmu is not None else None
    progress = Progress()
    try:
        try:
            result = run_closed_loop(model, config, traj, plant=plant, options=options,
                                     progress=lambda k, n: progress.update("closed loop", k, n))
            progress.update("closed loop", len(traj.t), len(traj.t))
        finally:
            if plant is not None:
                plant.close()
        where = f"FMU {fmu}" if fmu is not None else "in-process plant"
        title = (f"{model.name}: closed loop, feedforward {config.feedforward}, {where} "
                 f"({traj.t[-1]:g} s at {config.rate:g} Hz)")
        m = config.motor
        table = out / f"run.{fmt}"
        framed = table_from_platform(model, result.table, frame)
        with writing(out):
            if fmt == "parquet":
                progress.update(f"writing {table.name}", 0, len(result.table), unit="rows")
                write_parquet(table, framed)
                progress.update(f"writing {table.name}", len(result.table), len(result.table),
                                unit="rows")
            else:
                io.write_csv(table, framed, lambda k, n: progress.update(
                    f"writing {table.name}", k, n, unit="rows"))
            figures = (
                ("run_tracking.png", lambda: tracking_figure(framed, f"{title}\npose tracking, {frame} frame")),
                ("run_errors.png", lambda: leg_errors_figure(result.table,
                                                             f"{title}\ntracking errors")),
                ("run_forces.png", lambda: drive_figure(result.table, m.voltage_limit,
                                                        m.current_limit, f"{title}\ndrives")))
            for k, (name, figure) in enumerate(figures):
                progress.update("plotting", k, len(figures), unit="figures")
                save_figure(figure(), out / name)
            progress.update("plotting", len(figures), len(figures), unit="figures")
            io.write_text(out / "summary.md", run_summary(model, result, traj, where, frame))
            if view:
                progress.update("writing the view", 0, 1, unit="files")
                write_beside(out / VIEW_FILE, run_table_view(
                    model, result.table, controller=config, title=title, source=f"run.{fmt}"))
                progress.update("writing the view", 1, 1, unit="files")
    finally:
        progress.close()
    return result, traj


def open_fmu(path: Path, model: Model):
    """controller.plants.FmuPlant for `path`, after checking that the FMU was exported from a
    scene with the same physical parameters as `model` (its resources/scene.toml)."""

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


def run_summary(model: Model, result, traj, where: str, frame: str = "platform") -> str:
    """summary.md of a run: design, tracking per leg and per pose coordinate, effort, timing;
    the frame of run.csv's poses (the summary's own figures are C's pose)."""
    s, a, g, ax, cfg = result.summary, result.analysis, result.gains, result.axis, result.config
    duration = float(traj.t[-1] - traj.t[0])
    units = ("m", "m", "m", "rad", "rad", "rad")
    lines = [
        f"# Closed-loop run: {md_text(model.name)}",
        "",
        f"- scene: {md_code(model.source)}; plant: {md_text(where)}",
        f"- reference: quintic six-axis move out ({RUN_MOVE * duration:.6g} s), hold "
        f"({RUN_HOLD * duration:.6g} s), move back, hold; {duration:.6g} s, "
        f"{len(traj.t)} samples at {cfg.rate:.6g} Hz; goal pose "
        f"{format_vector(traj.q[int(round(RUN_MOVE * duration * cfg.rate))])}",
        f"- run.csv's poses (x..thz, x_ref..thz_ref) and the tracking figure: the {frame} "
        "frame; the goal pose and the pose figures here: C's pose (platform)",
        f"- feedforward: {cfg.feedforward}",
        *([f"- actuation delay: {cfg.delay} controller period (controller.delay: each "
           f"sample's torque drives the period after it)"] if cfg.delay else []),
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
