"""The `inverse` command's pipeline over files: read a trajectory, check every pose, compute
the forces block by block and write them as they come (atomically), with progress."""
from __future__ import annotations

from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

from controller.config import ControllerConfig
from stewart_fmu import io
from stewart_fmu.dynamics import inverse_dynamics, inverse_dynamics_parts, present_parts
from stewart_fmu.errors import KinematicsError
from stewart_fmu.frames import motion_to_platform
from stewart_fmu.io import writing
from stewart_fmu.kinematics import check_poses
from stewart_fmu.model import Model
from stewart_sim.shell.progress import Progress
from stewart_sim.view.files import write_beside
from stewart_sim.view.sources import trajectory_view

CHUNK_SAMPLES = 50_000       # samples per block of the pose check and of the dynamics


def run_inverse(model: Model, trajectory: Path, out: Path, parts: bool, progress: Progress,
                keep: bool = False, view: Path | None = None,
                controller: ControllerConfig | None = None,
                frame: str = "platform") -> tuple[int, np.ndarray | None]:
    """Read (a motion in `frame` of the scene's [frames], converted to C's first), check every
    pose, compute and write the forces; the table too if `keep`; then the 3D view into `view`
    (its forces by inverse dynamics at its frames: the file's numbers at those samples; its
    force scale from the scene's parsed [controller], `controller`). `out` and `view` are the
    caller's temporaries (cmd_inverse: an outputs.file_set, so the two files appear together or
    not at all; demo: its result set)."""
    t, q, qd, qdd = io.read_trajectory(
        trajectory, progress=lambda rows: progress.update(f"reading {trajectory}", rows))
    if frame != "platform":
        q, qd, qdd = motion_to_platform(model, q, qd, qdd, frame)
    cond = check_trajectory(model, t, q, trajectory, progress)
    kept: list[np.ndarray] = []
    chunks = force_chunks(model, (t, q, qd, qdd), cond, parts, trajectory, progress)
    with writing(out):
        io.write_csv_chunks(out, _keep(chunks, kept) if keep else chunks)
    if view is not None:
        write_beside(view, trajectory_view(model, t, q, qd, qdd, controller=controller,
                                           source=out.name, title=f"{model.name}: {out.name}"))
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
