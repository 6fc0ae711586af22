"""Views of what the commands write: a trajectory CSV, a forces CSV (with its trajectory), a
`run` directory (run.csv / run.parquet: in-process, --fmu or --link), a `demo` directory and a
`paper` directory; and of the results those commands hold in memory (they write their view
beside their files).

Forces shown: for `run` in-process / --fmu the rack force the motor delivers, torque x zeta / r
(controller.cosim records the mean motor torque of each step); for --link the device's reported
rack force; for trajectories (`inverse`, `demo`, `paper`) the actuator force sigma of
stewart_fmu.dynamics.inverse_dynamics, drive term included when the scene has a [drive].
Every view takes the scene's parsed [controller] (None: the scene has none): its motor and the
[drive] give the colour bar's scale (stewart_sim.view.geometry.drive_peak_force).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu.budget import CSV_BYTES, SCENE_BYTES, InputFileError, open_input, read_input
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.errors import KinematicsError, StewartError
from stewart_fmu.frames import motion_to_platform, table_to_platform
from stewart_fmu.io import (FORCE_COLUMNS, POSE, TRAJECTORY_COLUMNS, csv_header, read_samples,
                            read_trajectory)
from stewart_fmu.kinematics import forward_kinematics
from stewart_fmu.model import Model
from stewart_sim.scene.paper_moves import TRAJECTORIES, make_trajectory
from stewart_sim.view.data import DEFAULT_FPS, ViewData, frame_indices, view_data

SIGMA = "actuator force sigma"
RACK = "rack force"
LEGS = tuple(range(1, 7))
# The paper's moves are 0.1 s long: frames every 1/PAPER_FPS s, played at PAPER_SPEED.
PAPER_FPS = 300.0
PAPER_SPEED = 0.1


# --- in memory ---------------------------------------------------------------------------------

def trajectory_view(model: Model, t, q, qd, qdd, *, controller: ControllerConfig | None,
                    fps: float = DEFAULT_FPS, title: str,
                    source: str = "", forces=None) -> ViewData:
    """A trajectory's view; forces by inverse dynamics at the frames only (unless given for
    every sample), so an hour's trajectory costs what its frames cost."""
    t = np.asarray(t, dtype=float)
    idx = frame_indices(t, fps)
    f = (inverse_dynamics(model, q[idx], qd[idx], qdd[idx]) if forces is None
         else np.asarray(forces, dtype=float)[idx])
    return view_data(model, t[idx], np.asarray(q)[idx], f, controller=controller, fps=fps,
                     force_label=SIGMA, title=title, source=source, source_samples=t.size)


def run_table_view(model: Model, table: np.ndarray, *, controller: ControllerConfig | None,
                   fps: float = DEFAULT_FPS, title: str, source: str = "") -> ViewData:
    """The view of a `run` table (controller.cosim: time, x..thz, x_ref.., torque1..6) or of a
    `run --link` table (hil.client: time, l1..6, l_ref1..6, force1..6)."""
    names = table.dtype.names
    if "x" in names:
        if model.drive is None:
            raise StewartError("view: the run's torques need the scene's [drive] (zeta / r)")
        q = np.column_stack([table[c] for c in POSE])
        q_ref = np.column_stack([table[f"{c}_ref"] for c in POSE])
        forces = np.column_stack([table[f"torque{i}"] for i in LEGS]) * model.drive.force_per_torque
        return view_data(model, table["time"], q, forces, q_ref, controller=controller,
                         fps=fps, force_label=RACK, title=title, source=source)
    t = np.asarray(table["time"], dtype=float)
    idx = frame_indices(t, fps)
    l = np.column_stack([table[f"l{i}"] for i in LEGS])[idx]
    l_ref = np.column_stack([table[f"l_ref{i}"] for i in LEGS])[idx]
    forces = np.column_stack([table[f"force{i}"] for i in LEGS])
    return view_data(model, t[idx], poses_of(model, l, "l"), forces[idx],
                     poses_of(model, l_ref, "l_ref"), controller=controller, fps=fps,
                     force_label=RACK, title=title,
                     source=source, source_samples=t.size,
                     force_peak=float(np.max(np.abs(forces))))


def poses_of(model: Model, lengths: np.ndarray, what: str) -> np.ndarray:
    """Forward kinematics of each row of leg lengths, each from the previous pose."""
    q = np.empty((len(lengths), 6))
    guess = model.home
    for k, l in enumerate(lengths):
        try:
            guess = q[k] = forward_kinematics(model, l, guess)
        except KinematicsError as exc:
            raise StewartError(f"view: no pose for the leg lengths {what} of frame {k}: {exc}") from None
    return q


def paper_view(results, *, controller: ControllerConfig | None, title: str | None = None,
               source: str = "") -> ViewData:
    """The paper rerun's six moves one after the other (each 0.1 s from home; the full model's
    sigma), played slowed down (PAPER_SPEED)."""
    from_t, q, f = [], [], []
    span = float(results.t[-1] - results.t[0])
    for k, (name, tr) in enumerate(results.trajectories.items()):
        from_t.append(results.t + k * span * 1.05)
        q.append(tr.q)
        f.append(results.runs[name]["drive"].sigma)
    model = results.model
    return view_data(model, np.concatenate(from_t), np.concatenate(q), np.concatenate(f),
                     controller=controller, fps=PAPER_FPS, force_label=SIGMA, speed=PAPER_SPEED,
                     source=source,
                     title=title or f"{model.name}: the paper's six moves "
                                    f"({', '.join(results.trajectories)}; {span:g} s each)")


# --- files -------------------------------------------------------------------------------------

def recorded_scene(directory: Path) -> Path | None:
    """The scene a `run` recorded in its summary.md ("- scene: `PATH`"), if any."""
    try:   # a regular file within the budget of a text input (not a FIFO: no wait)
        text = read_input(directory / "summary.md", SCENE_BYTES).decode("utf-8")
    except (InputFileError, UnicodeDecodeError):
        return None
    match = re.search(r"^- scene: `([^`]+)`", text, re.MULTILINE)
    return Path(match.group(1)) if match else None


def read_run_table(path: Path) -> np.ndarray:
    """run.csv or run.parquet as a structured array (the columns a view needs)."""
    if path.suffix == ".parquet":
        try:
            import pyarrow.parquet as pq  # optional dependency: only run.parquet needs it
        except ImportError:
            raise StewartError(f"{path}: reading parquet needs pyarrow (pip install "
                               "'stewart-sim[parquet]')") from None
        try:
            with open_input(path, CSV_BYTES) as fh:
                arrow = pq.read_table(fh)
        except InputFileError as exc:
            raise StewartError(f"{path}: cannot read the run table: {exc.reason}") from None
        except (OSError, ValueError) as exc:
            raise StewartError(f"{path}: not a readable parquet table: {exc}") from None
        names = arrow.column_names
        table = {n: arrow.column(n).to_numpy() for n in _run_columns(path, names)}
    else:
        names = _run_columns(path, csv_header(path, "run table"))
        data = read_samples(path, names, "run table", anywhere=True)
        table = {n: data[:, k] for k, n in enumerate(names)}
    out = np.empty(len(table["time"]), dtype=[(n, float) for n in table])
    for n, v in table.items():
        out[n] = v
    return out


def _run_columns(path: Path, header) -> tuple[str, ...]:
    if "x" in header:
        return ("time", *POSE, *(f"{c}_ref" for c in POSE), *(f"torque{i}" for i in LEGS))
    if "l1" in header and "force1" in header:
        return ("time", *(f"l{i}" for i in LEGS), *(f"l_ref{i}" for i in LEGS),
                *(f"force{i}" for i in LEGS))
    raise StewartError(f"{path}: not a run table (columns time, x..thz, x_ref..thz_ref, "
                       "torque1..6, or the --link table's time, l1..6, l_ref1..6, force1..6)")


def view_of(path: Path, model: Model, *, controller: ControllerConfig | None,
            fps: float = DEFAULT_FPS, trajectory: Path | None = None,
            frame: str = "platform") -> ViewData:
    """The view of a file or result directory (see the module doc); the poses of a trajectory
    or run table (file or directory) given in `frame` of the scene's [frames] (a `demo` or
    `paper` directory holds C's)."""
    if path.is_dir():
        return _directory_view(path, model, controller, fps, frame)
    if not path.exists():
        raise StewartError(f"{path}: no such file or directory")
    header = csv_header(path, "table") if path.suffix != ".parquet" else ()
    if path.suffix == ".parquet" or "time" in header:
        return run_table_view(model, _run_table(model, path, frame), controller=controller,
                              fps=fps, source=str(path), title=f"{model.name}: closed-loop run")
    if tuple(header[:len(FORCE_COLUMNS)]) == FORCE_COLUMNS:
        if trajectory is None:
            raise StewartError(f"{path} holds forces but no poses: give --trajectory TRAJ.csv, "
                               "the trajectory they were computed from")
        return _forces_view(model, controller, path, trajectory, fps, frame)
    if header == TRAJECTORY_COLUMNS:
        return trajectory_view(model, *_trajectory(model, path, frame), controller=controller,
                               fps=fps, source=str(path), title=f"{model.name}: {path.name}")
    raise StewartError(f"{path}: not a trajectory (t,x..ddthz), forces (t,sigma1..6) or run "
                       "table (time, ...) CSV")


def _trajectory(model: Model, path: Path, frame: str) -> tuple[np.ndarray, ...]:
    """t, q, qd, qdd of C of a trajectory file given in `frame`."""
    t, q, qd, qdd = read_trajectory(path)
    return (t, *motion_to_platform(model, q, qd, qdd, frame))


def _run_table(model: Model, path: Path, frame: str) -> np.ndarray:
    """A run table whose poses (x..thz, x_ref..thz_ref) are given in `frame`, with C's."""
    return table_to_platform(model, read_run_table(path), frame)


def _forces_view(model: Model, controller: ControllerConfig | None, forces: Path,
                 trajectory: Path, fps: float, frame: str = "platform") -> ViewData:
    f = read_samples(forces, FORCE_COLUMNS, "forces", prefix=True)
    t, q, qd, qdd = _trajectory(model, trajectory, frame)
    if f.shape[0] != t.size or not np.allclose(f[:, 0], t, rtol=0, atol=1e-9):
        raise StewartError(f"{forces} and {trajectory}: not the same sample times")
    return trajectory_view(model, t, q, qd, qdd, controller=controller, fps=fps,
                           forces=f[:, 1:7], source=str(forces),
                           title=f"{model.name}: {forces.name}")


def _directory_view(directory: Path, model: Model, controller: ControllerConfig | None,
                    fps: float, frame: str = "platform") -> ViewData:
    for name in ("run.csv", "run.parquet"):
        if (directory / name).is_file():
            return run_table_view(model, _run_table(model, directory / name, frame),
                                  controller=controller, fps=fps, source=str(directory / name),
                                  title=f"{model.name}: closed-loop run")
    if (directory / "demo_trajectory.csv").is_file() and (directory / "demo_forces.csv").is_file():
        return _forces_view(model, controller, directory / "demo_forces.csv",
                            directory / "demo_trajectory.csv", fps)
    if (directory / "report.md").is_file() and (directory / "x_level3.csv").is_file():
        return _paper_directory_view(directory, model, controller)
    raise StewartError(f"{directory}: no run.csv, run.parquet, demo_trajectory.csv with "
                       "demo_forces.csv, or paper report (report.md, x_level3.csv) in it")


def _paper_directory_view(directory: Path, model: Model,
                          controller: ControllerConfig | None) -> ViewData:
    """The paper directory's six moves: poses from the study's own definition of each move
    (stewart_sim.scene.paper_moves.make_trajectory) at the CSV's times, forces from the CSVs."""
    t_all, q_all, f_all = [], [], []
    offset = 0.0
    for name in TRAJECTORIES:
        data = read_samples(directory / f"{name}_level3.csv", FORCE_COLUMNS, "forces",
                            prefix=True)
        t = data[:, 0]
        q_all.append(make_trajectory(model, name, t).q)
        t_all.append(t + offset)
        f_all.append(data[:, 1:7])
        offset += 1.05 * float(t[-1] - t[0])
    return view_data(model, np.concatenate(t_all), np.concatenate(q_all), np.concatenate(f_all),
                     controller=controller, fps=PAPER_FPS, force_label=SIGMA, speed=PAPER_SPEED,
                     source=str(directory),
                     title=f"{model.name}: the paper's six moves")
