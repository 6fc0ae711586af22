"""`stewart-sim run --link serial|udp`: the device in its own process, the host's closed loop
over the link (hil.client), and the run's files (run.csv, run_link.png, summary.md)."""
from __future__ import annotations

import math
from pathlib import Path

from controller.config import ControllerConfig
from controller.moves import run_reference
from hil.budget import SERIAL_BAUD, realtime_rates
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
from stewart_fmu.model import Model
from stewart_sim.link_figures import run_figure
from stewart_sim.view.files import VIEW_FILE, write_beside
from stewart_sim.view.sources import run_table_view


def link_summary_text(model: Model, run: LinkRun, ref: LinkReference, link: str) -> str:
    """summary.md of a run over the link."""
    s = run.summary
    t = ref.refs.t
    lines = [f"# Closed-loop run over the link: {model.name}", "",
             f"- scene: `{model.source}`; device: `stewart-sim device` (its own process) over "
             f"{link}, mode {s.mode}",
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


def run_link_files(model: Model, config: ControllerConfig, duration: float, out, link: str,
                   mode: str, view: bool = True) -> tuple[LinkRun, LinkReference]:
    """`run --link serial|udp --mode lockstep|realtime`: the device run as its own process
    (`stewart-sim device`, see hil.spawn) over a pseudo-terminal (``serial``) or loopback UDP,
    the `run` reference (controller.moves.run_reference) over the link; run.csv,
    run_link.png, summary.md and (`view`) view.html into `out`."""
    if link not in ("serial", "udp") or mode not in ("lockstep", "realtime"):
        raise LinkError(f"run: --link serial|udp and --mode lockstep|realtime, got {link}, {mode}")
    if model.source is None:
        raise LinkError("run --link: the device process needs the scene as a file")
    out = Path(out)
    ref = link_reference(model, config, run_reference(model, config, duration))
    every, state_rate = realtime_rates(link, config.rate)
    with device_process(model.source, link, lockstep=(mode == "lockstep")) as first:
        transport, where = connect_device(link, first)
        client = Client(transport)
        try:
            if mode == "lockstep":
                run = run_lockstep(client, ref, timeout=1.0)
            else:
                run = run_realtime(client, ref, every=every, state_rate=state_rate)
            client.disarm()
        finally:
            client.close()
    text = link_summary_text(model, run, ref, where)
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
