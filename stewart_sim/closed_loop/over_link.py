"""`stewart-sim run --link serial|udp`: the device in its own process, the host's closed loop
over the link (hil.client), and the run's files (run.csv, run_link.png, summary.md).

The reference is `run`'s demonstration move, or a trajectory file (`link_trajectory`: the
contract's columns, as `inverse` reads them) starting at rest at the scene's home pose, where the
device starts; a file not sampled at the controller rate is resampled onto it by piecewise
quintic Hermite interpolation of its poses, rates and accelerations (exact for quintics, C2).
`record_table` is the recording of a lockstep run (`run --record RUN.csv`): device time, the
leg lengths, rack forces and motor currents as the device reports them (its [sensors]), the
input of `identify`.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.interpolate import BPoly

from controller.config import ControllerConfig
from controller.moves import run_reference
from controller.trajectory import Trajectory
from hil.bandwidth import SERIAL_BAUD, realtime_rates
from hil.client import (
    Client,
    LinkReference,
    LinkRun,
    connect_device,
    link_reference,
    run_lockstep,
    run_realtime,
)
from hil.errors import LinkError
from hil.spawn import device_process
from stewart_fmu import io as sio
from stewart_fmu.budget import check_count
from stewart_fmu.errors import TrajectoryError
from stewart_fmu.frames import motion_to_platform
from stewart_fmu.model import Model
from stewart_sim.closed_loop.link_figures import run_figure
from stewart_sim.shell.markdown import md_code, md_text
from stewart_sim.view.files import VIEW_FILE, write_beside
from stewart_sim.view.sources import run_table_view


def link_summary_text(model: Model, run: LinkRun, ref: LinkReference, link: str,
                      truth: str | Path | None = None) -> str:
    """summary.md of a run over the link (`truth`: the device's hidden true scene)."""
    s = run.summary
    t = ref.refs.t
    lines = [f"# Closed-loop run over the link: {md_text(model.name)}", "",
             f"- scene: {md_code(model.source)}; device: `stewart-sim device` (its own process) over "
             f"{md_text(link)}, mode {s.mode}"
             + (f"; its plant and sensors from the truth scene {md_code(truth)}" if truth else ""),
             f"- reference: {t[-1] - t[0]:.6g} s, {len(t)} samples at "
             f"{1 / (t[1] - t[0]):.6g} Hz; feedforward {ref.feedforward}",
             "", "## Tracking (measured leg length vs reference at the state's time)", "",
             "| leg | RMS error (m) | max error (m) |", "|---|---:|---:|"]
    for i in range(6):
        lines.append(f"| {i + 1} | {s.leg_rms[i]:.6g} | {s.leg_max[i]:.6g} |")
    ms_ = (lambda x: "n/a" if not math.isfinite(x) else f"{1e3 * x:.4g} ms")
    lines += ["", "## Link", "",
              f"- states recorded: {s.samples}",
              f"- messages sent: {s.sent}; received: {s.received}; lost: {s.lost} "
              f"({'resends after a timeout' if s.mode == 'lockstep' else 'LEG_STATEs missing'})",
              f"- round trip (setpoint + LOCKSTEP -> LEG_STATE): median {ms_(s.rtt_median)}, "
              f"p99 {ms_(s.rtt_p99)}, max {ms_(s.rtt_max)}",
              f"- wall time: {s.wall_time:.4g} s",
              f"- device messages: {len(s.statustexts)} STATUSTEXT"
              + (f" (last: {s.statustexts[-1]!r})" if s.statustexts else ""), ""]
    return "\n".join(lines)


LINK_FILES = ("run.csv", "run_link.png", "summary.md", VIEW_FILE)
RECORD_COLUMNS = ("t", *(f"l{i}" for i in range(1, 7)), *(f"sigma{i}" for i in range(1, 7)))
CURRENT_COLUMNS = tuple(f"current{i}" for i in range(1, 7))
START_TOLERANCE = 1e-9   # m, rad, m/s, rad/s: a trajectory's first sample at rest at home
RATE_TOLERANCE = 1e-9    # relative: a file's time step taken as the controller period


def link_trajectory(model: Model, config: ControllerConfig, path: str | Path,
                    frame: str = "platform") -> Trajectory:
    """A trajectory file (a motion in `frame` of the scene's [frames], converted to C's first)
    as the link's reference: from t = 0 at the controller rate (resampled when its step is not
    the controller period, see the module doc); TrajectoryError when it does not start at rest
    at the scene's home pose."""
    t, q, qd, qdd = sio.read_trajectory(path)
    q, qd, qdd = motion_to_platform(model, q, qd, qdd, frame)
    if t.size < 2:
        raise TrajectoryError(f"{path}: need two or more samples, got {t.size}")
    gap = float(np.max(np.abs(q[0] - model.home)))
    speed = float(np.max(np.abs(qd[0])))
    if gap > START_TOLERANCE or speed > START_TOLERANCE:
        raise TrajectoryError(f"{path}: the device starts at rest at the home pose "
                              f"{model.home.tolist()}; the trajectory's first sample is "
                              f"{gap:.3g} from it at speed {speed:.3g}: begin there, at rest")
    t = t - t[0]
    period = 1.0 / config.rate
    if np.all(np.abs(np.diff(t) - period) <= RATE_TOLERANCE * period):
        return Trajectory(np.arange(t.size) / config.rate, q, qd, qdd)
    steps = t[-1] * config.rate * (1 + RATE_TOLERANCE)
    check_count(f"{path}: {t[-1]:g} s at the controller's {config.rate:g} Hz: samples",
                steps + 1, 2 * 19 * 8, "a shorter trajectory")
    tk = np.arange(int(math.floor(steps)) + 1) / config.rate
    if tk.size < 2:
        raise TrajectoryError(f"{path}: lasts {t[-1]:g} s, less than one controller period "
                              f"({period:g} s)")
    spline = BPoly.from_derivatives(t, np.stack([q, qd, qdd], axis=1))
    return Trajectory(tk, spline(tk), spline.derivative(1)(tk), spline.derivative(2)(tk))


def record_table(run: LinkRun) -> np.ndarray:
    """The recording of a lockstep run: RECORD_COLUMNS (t: device time, s; l1..l6, m;
    sigma1..sigma6, N; as the device reported them), then CURRENT_COLUMNS (A) when recorded."""
    tab = run.table
    sources = ("time", *(f"l{i}" for i in range(1, 7)), *(f"force{i}" for i in range(1, 7)))
    cols = {name: tab[src] for name, src in zip(RECORD_COLUMNS, sources)}
    if run.currents is not None:
        cols.update({name: run.currents[:, i] for i, name in enumerate(CURRENT_COLUMNS)})
    return sio.named_array(cols)


def run_link_files(model: Model, config: ControllerConfig, duration: float, out, link: str,
                   mode: str, view: bool = True, *, traj: Trajectory | None = None,
                   truth: str | Path | None = None, currents: bool = False
                   ) -> tuple[LinkRun, LinkReference]:
    """`run --link serial|udp --mode lockstep|realtime`: the device run as its own process
    (`stewart-sim device`, see hil.spawn; its plant from `truth` when given) over a
    pseudo-terminal (``serial``) or loopback UDP, the `run` reference
    (controller.moves.run_reference; `traj` instead when given) over the link; run.csv,
    run_link.png, summary.md and (`view`) view.html into `out`. `currents`: the motor currents
    of every state too (lockstep; LinkRun.currents)."""
    if link not in ("serial", "udp") or mode not in ("lockstep", "realtime"):
        raise LinkError(f"run: --link serial|udp and --mode lockstep|realtime, got {link}, {mode}")
    if model.source is None:
        raise LinkError("run --link: the device process needs the scene as a file")
    out = Path(out)
    ref = link_reference(model, config,
                         traj if traj is not None else run_reference(model, config, duration))
    every, state_rate = realtime_rates(link, config.rate)
    with device_process(model.source, link, lockstep=(mode == "lockstep"),
                        truth=truth) as first:
        transport, where = connect_device(link, first)
        client = Client(transport)
        try:
            if mode == "lockstep":
                run = run_lockstep(client, ref, timeout=1.0, currents=currents)
            else:
                run = run_realtime(client, ref, every=every, state_rate=state_rate)
            client.disarm()
        finally:
            client.close()
    text = link_summary_text(model, run, ref, where, truth)
    if mode == "realtime":
        text += (f"- setpoints every {every} controller samples ({config.rate / every:g} Hz), "
                 f"LEG_STATE at {state_rate:g} Hz"
                 + (f" (what fits a {SERIAL_BAUD} baud UART)" if link == "serial" else "") + "\n")
    with sio.writing(out):
        sio.write_csv(out / "run.csv", run.table)
        run_figure(run.table, f"{model.name}: closed loop over {where}, {mode}",
                   out / "run_link.png")
        sio.write_text(out / "summary.md", text)
        if view:
            title = f"{model.name}: closed loop over {where}, {mode}"
            write_beside(out / VIEW_FILE, run_table_view(model, run.table, controller=config,
                                                         title=title, source="run.csv"))
    return run, ref
