"""The plots of a design sweep: the sweep's main figure against its axes (tracking error against
gear ratio and payload, peak force against the design), and, for the base scene, the force
envelope and the singularity map (cond(J)) over a slice of the workspace."""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.ticker import FixedLocator, FuncFormatter

from controller.moves import demo_amplitudes
from stewart_fmu.dynamics import inverse_dynamics
from stewart_fmu.fmu.variables import SCENE_KEYS
from stewart_fmu.io import POSE
from stewart_fmu.model import Model
from stewart_sim.studies.sweep.adaptive import REFINEMENT
from stewart_sim.studies.sweep.evaluate import reachable
from stewart_sim.studies.sweep.grid import EnvelopeSettings, GridSpec
from stewart_sim.studies.sweep.joint_layout import LAYOUT_KEYS

SLICE_POINTS = 61            # per side of a workspace slice
DEFAULT_SLICE_SPAN = 6.0     # without [envelope]: +- this many demo amplitudes in x and y
METRIC = {"inverse": ("sigma_max", "peak actuator force max|σ_i| (N)", "peak_force.png"),
          "envelope": ("sigma_max", "peak force over the workspace (N)", "peak_force.png"),
          "closed_loop": ("leg_err_rms", "RMS leg tracking error (m)", "tracking_error.png"),
          "modes": ("lowest_hz", "first mode at home (Hz)", "lowest_hz.png")}
# Units of the keys a sweep may vary: the scene's from stewart_fmu.fmu.variables.SCENE_KEYS,
# the rest (controller/config.py ControllerConfig, controller/drive.py Motor, the sweep's
# trajectory and case tables) here, the one place the plots take them from.
AXIS_UNITS = {
    "controller.rate": "Hz", "controller.bandwidth": "Hz", "controller.phase_margin": "deg",
    "controller.load_mass": "kg",
    "controller.motor.resistance": "ohm", "controller.motor.inductance": "H",
    "controller.motor.torque_constant": "N m/A", "controller.motor.back_emf": "V s/rad",
    "controller.motor.current_limit": "A", "controller.motor.voltage_limit": "V",
    "trajectory.duration": "s", "case.duration": "s", "case.step": "s",
    "case.force_scale": "1", "case.acceleration": "m/s2", **LAYOUT_KEYS,
}


def axis_label(key: str) -> str:
    """'platform.mass (kg)': a swept key with its unit ('-' for dimensionless, '?' unknown)."""
    entry = SCENE_KEYS.get(key)
    unit = entry[2] if entry is not None else AXIS_UNITS.get(key)
    return f"{key} ({'-' if unit == '1' else unit or '?'})"


def colorbar_ticks(cbar, lo: float, hi: float, log: bool, n: int = 5) -> None:
    """n ticks spread evenly (geometrically with a log norm) over [lo, hi], 3 significant
    digits: a LogLocator over less than a decade draws one tick or none."""
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        return
    ticks = np.geomspace(lo, hi, n) if log else np.linspace(lo, hi, n)
    cbar.locator = FixedLocator(ticks)
    cbar.formatter = FuncFormatter(lambda v, _: f"{v:.3g}")
    cbar.minorticks_off()
    cbar.update_ticks()


X_PREFERRED = ("drive.gear_ratio",)
COLOUR_PREFERRED = ("platform.mass",)


def results_figure(table: Mapping[str, np.ndarray], grid: GridSpec, title: str) -> Figure:
    """The evaluation's main figure against the swept values: x the gear ratio (else the first
    numeric axis), colour the payload (else the next numeric axis); failed points are counted."""
    metric, label, _ = METRIC[grid.evaluation]
    numeric = [k for k in grid.keys if table[k].dtype != object]
    x = _pick(numeric, X_PREFERRED, ())
    c = _pick(numeric, COLOUR_PREFERRED, (x,))
    ok = table["status"] == "ok"
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    xs = table[x][ok] if x else np.flatnonzero(ok).astype(float)
    kw = {"c": table[c][ok], "cmap": "viridis"} if c else {}
    sc = ax.scatter(xs, table[metric][ok], s=12, **kw)
    if REFINEMENT in table:     # the points `sweep --adaptive` added: circled
        added = table[REFINEMENT][ok] > 0
        ax.scatter(xs[added], table[metric][ok][added], s=45, facecolors="none",
                   edgecolors="red", linewidths=0.8,
                   label=f"{int(added.sum())} added by refinement")
        ax.legend(fontsize=8, loc="best")
    if c:
        cbar = fig.colorbar(sc, ax=ax, label=axis_label(c))
        values = np.asarray(table[c][ok], float)
        if values.size:
            colorbar_ticks(cbar, float(values.min()), float(values.max()), False)
    ax.set(xlabel=axis_label(x) if x else "point (index)", ylabel=label)
    for name, scale in (("x", x), ("y", metric)):
        values = table[scale][ok] if scale else xs
        if values.size and np.all(values > 0) and values.max() / values.min() > 20:
            getattr(ax, f"set_{name}scale")("log")
    ax.grid(True, alpha=0.3, which="both")
    failed = int((~ok).sum())
    ax.set_title(f"{title}\n{int(ok.sum())} points" + (f", {failed} failed (not shown)" if failed else ""),
                 fontsize=9)
    return fig


def _pick(keys: Sequence[str], preferred: Sequence[str], taken: Sequence[str | None]) -> str | None:
    """The first preferred key present, else the first key not taken."""
    free = [k for k in keys if k not in taken]
    return next((k for k in preferred if k in free), free[0] if free else None)


def workspace_slice(model: Model, envelope: EnvelopeSettings | None
                    ) -> tuple[tuple[str, np.ndarray], tuple[str, np.ndarray], np.ndarray]:
    """Two pose coordinates and the (n, n, 6) poses of their slice through home: the first two
    ranges of [envelope], else x and y over +- DEFAULT_SLICE_SPAN demo amplitudes."""
    ranges = list(envelope.ranges) if envelope is not None else []
    span = DEFAULT_SLICE_SPAN * np.abs(demo_amplitudes(model))
    for name in POSE:
        if len(ranges) >= 2:
            break
        if name not in [r[0] for r in ranges]:
            k = POSE.index(name)
            ranges.append((name, -span[k], span[k]))
    (a, alo, ahi), (b, blo, bhi) = ranges[:2]
    av, bv = np.linspace(alo, ahi, SLICE_POINTS), np.linspace(blo, bhi, SLICE_POINTS)
    poses = np.tile(model.home, (SLICE_POINTS, SLICE_POINTS, 1))
    poses[..., POSE.index(a)] += av[None, :]
    poses[..., POSE.index(b)] += bv[:, None]
    return (a, av), (b, bv), poses


def workspace_figures(model: Model, envelope: EnvelopeSettings | None) -> tuple[Figure, Figure]:
    """Force envelope (max |σ| over legs and load cases) and cond(J) over a workspace slice;
    poses past the stroke or near a singularity are left blank."""
    (a, av), (b, bv), poses = workspace_slice(model, envelope)
    flat = poses.reshape(-1, 6)
    ok, cond = reachable(model, flat)
    acc = np.array((envelope or EnvelopeSettings()).accelerations)
    force = np.full(len(flat), np.nan)
    if ok.any():
        q = np.repeat(flat[ok], len(acc), axis=0)
        sigma = inverse_dynamics(model, q, np.zeros_like(q), np.tile(acc, (int(ok.sum()), 1)))
        force[ok] = np.abs(sigma).reshape(int(ok.sum()), len(acc), 6).max(axis=(1, 2))
    cond = np.where(np.isfinite(cond), cond, np.nan)
    shape = poses.shape[:2]
    where = f"{model.name}: slice {a}-{b} through home {model.home.tolist()}"
    cases = f"{len(acc)} load case{'s' if len(acc) > 1 else ''} (qdd)"
    env = _map(av, bv, force.reshape(shape), a, b, "max |σ_i| (N)",
               f"{where}\nforce envelope: static + {cases}; blank: outside the stroke", False)
    sing = _map(av, bv, np.where(ok, cond, np.nan).reshape(shape), a, b, "cond(J) (-)",
                f"{where}\nsingularity map: condition number of the leg Jacobian", True)
    return env, sing


def _map(av, bv, values, a: str, b: str, label: str, title: str, log: bool) -> Figure:
    fig = Figure(figsize=(7, 5.6), layout="constrained")
    ax = fig.add_subplot()
    finite = values[np.isfinite(values)]
    norm = LogNorm(finite.min(), finite.max()) if log and finite.size and finite.min() > 0 else None
    mesh = ax.pcolormesh(av, bv, np.ma.masked_invalid(values), shading="auto", norm=norm,
                         cmap="magma_r" if log else "viridis")
    cbar = fig.colorbar(mesh, ax=ax, label=label)
    if finite.size:
        colorbar_ticks(cbar, float(finite.min()), float(finite.max()), norm is not None)
    unit = lambda n: "rad" if n.startswith("th") else "m"  # noqa: E731
    ax.set(xlabel=f"{a} offset from home ({unit(a)})", ylabel=f"{b} offset from home ({unit(b)})")
    ax.set_title(title, fontsize=9)
    return fig
