"""The figures the commands write, inspected as matplotlib Figures before saving (no pixels):
every visible axis labelled with a unit, every colour bar with >= 3 ticks, limits in titles
with their unit, and long runs decimated for drawing (plots.MAX_POINTS points a line)."""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.moves import demo_trajectory, run_reference
from stewart_fmu import io
from stewart_fmu.dynamics import present_parts
from stewart_fmu.scene import load_scene
from stewart_sim.closed_loop.link_figures import run_link_figure, tracking_vs_link_figure
from stewart_sim.open_loop.forward import motion_figure
from stewart_sim.open_loop.inverse_forces import run_inverse
from stewart_sim.shell.plots import (
    MAX_POINTS,
    decimate,
    drive_figure,
    forces_figure,
    leg_errors_figure,
    tracking_figure,
)
from stewart_sim.shell.progress import Progress
from stewart_sim.studies.sweep.grid import grid_from_dict
from stewart_sim.studies.sweep.plots import axis_label, results_figure, workspace_figures

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
LONG = 120.0                       # s: `demo --duration 120`, `run --duration 120`
UNIT = re.compile(r"\([^()]+\)\s*(,|$)|\[[^\[\]]+\]")   # "... (unit)" or "... [unit]"


def check_figure(fig: Figure) -> None:
    """Every visible x and y axis has a label with a unit; every colour bar has >= 3 ticks and
    a label with a unit; every line has at most MAX_POINTS points."""
    assert fig.axes
    for ax in fig.axes:
        cbar = getattr(ax, "_colorbar", None)
        if cbar is not None:
            label = (ax.get_ylabel() if cbar.orientation == "vertical" else ax.get_xlabel())
            assert UNIT.search(label), f"colour bar label without a unit: {label!r}"
            assert len(cbar.get_ticks()) >= 3, f"colour bar {label!r}: {cbar.get_ticks()}"
            continue
        for axis, label in ((ax.xaxis, ax.get_xlabel()), (ax.yaxis, ax.get_ylabel())):
            if axis.get_visible():
                assert label.strip(), f"unlabelled axis in {ax.get_title()!r}"
                assert UNIT.search(label), f"axis label without a unit: {label!r}"
        for line in ax.get_lines():
            assert len(line.get_xdata()) <= MAX_POINTS, (ax.get_title(), len(line.get_xdata()))


def titles(fig: Figure) -> list[str]:
    return [ax.get_title() for ax in fig.axes]


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def long_run(model):
    """A 120 s closed-loop run (`run --duration 120`): 120,000 samples at 1 kHz."""
    config = controller_config(model)
    result = run_closed_loop(model, config, run_reference(model, config, LONG))
    assert len(result.table) > 20 * MAX_POINTS
    return config, result.table


def test_decimation_keeps_the_envelope_within_the_budget():
    t = np.linspace(0.0, LONG, 120_001)
    y = np.sin(2 * np.pi * 3 * t) + (t > 60.0005) * (t < 60.0015) * 5.0   # a 1 ms spike
    td, yd = decimate(t, y)
    assert len(td) <= MAX_POINTS and np.all(np.diff(td) > 0)
    assert yd.max() == y.max() and yd.min() == y.min()      # peaks kept
    assert decimate(t[:100], y[:100])[0].size == 100        # short lines untouched


def test_run_figures_have_units_and_draw_a_long_run_decimated(long_run):
    config, table = long_run
    m = config.motor
    figs = [tracking_figure(table, "t"), leg_errors_figure(table, "e"),
            drive_figure(table, m.voltage_limit, m.current_limit, "d")]
    for fig in figs:
        check_figure(fig)
    limits = [s for s in titles(figs[2]) if "limit" in s]
    assert limits and all(re.search(r"limit ±[\d.e+-]+ (V|A)\b", s) for s in limits), limits
    assert f"voltage limit ±{m.voltage_limit:g} V" in titles(figs[2])[0]


def test_demo_forces_of_120_s_are_decimated(model, tmp_path):
    t, q, qd, qdd = demo_trajectory(model, LONG)
    traj = tmp_path / "demo_trajectory.csv"
    io.write_csv(traj, io.trajectory_table(t, q, qd, qdd))
    progress = Progress()
    try:
        _, table = run_inverse(model, traj, tmp_path / "demo_forces.csv", True, progress,
                               keep=True)
    finally:
        progress.close()
    assert len(table) > 20 * MAX_POINTS
    check_figure(forces_figure(table, present_parts(model), "demo"))


def test_link_figures_have_units_a_legend_and_decimated_lines():
    n = int(LONG * 1000) + 1
    t = np.linspace(0.0, LONG, n)
    names = [f"{p}{i}" for p in ("l", "l_ref", "e", "force") for i in range(1, 7)]
    table = np.zeros(n, dtype=[("time", "f8")] + [(c, "f8") for c in names])
    table["time"] = t
    for i in range(1, 7):
        table[f"l_ref{i}"] = 0.17 + 0.01 * np.sin(t + i)
        table[f"l{i}"] = table[f"l_ref{i}"] - 1e-5 * np.cos(40 * t)
        table[f"e{i}"] = table[f"l_ref{i}"] - table[f"l{i}"]
        table[f"force{i}"] = 3.0 * np.sin(5 * t + i)
    fig = run_link_figure(table, "link")
    check_figure(fig)
    assert fig.axes[0].get_legend() is not None           # run_link.png has its legend
    rows = [{"latency": lat, "loss": loss, "rms": 1e-5, "max": 3e-5, "lost": 0,
             "setpoints_lost": 0} for lat, loss in ((0, 0), (0.002, 0), (0, 0.1), (0, 0.3))]
    check_figure(tracking_vs_link_figure(rows))


def test_motion_figure_of_a_long_table_is_decimated():
    n = 120_001
    table = np.zeros(n, dtype=[(c, "f8") for c in ("t", "x", "y", "z", "thx", "thy", "thz",
                                                   *(f"l{i}" for i in range(1, 7)))])
    table["t"] = np.linspace(0.0, LONG, n)
    table["x"] = np.sin(table["t"])
    check_figure(motion_figure(table, "motion"))


SWEEP = """
evaluation = "envelope"
[envelope]
x = [-0.03, 0.03]
z = [-0.04, 0.04]
points = 7
accelerations = [[0, 0, 0, 0, 0, 0], [10, 0, 0, 0, 0, 0]]
[axes]
"platform.mass" = [0.5, 1.0, 2.0]
"drive.gear_ratio" = [5.0, 10.0, 40.0]
"""


def test_sweep_figures_have_units_and_colour_bars_with_ticks(model):
    grid = grid_from_dict(tomllib.loads(SWEEP))
    mass, ratio = np.meshgrid([0.5, 1.0, 2.0], [5.0, 10.0, 40.0])
    table = {"platform.mass": mass.ravel(), "drive.gear_ratio": ratio.ravel(),
             "sigma_max": 1.0 + mass.ravel() * ratio.ravel(),
             "status": np.array(["ok"] * 8 + ["failed"], dtype=object)}
    fig = results_figure(table, grid, "sweep")
    check_figure(fig)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "drive.gear_ratio (-)"
    assert "platform.mass (kg)" in [a.get_ylabel() for a in fig.axes]
    for envelope in (None, grid.envelope):
        for fig in workspace_figures(model, envelope):
            check_figure(fig)


@pytest.mark.parametrize("key, unit", [("platform.mass", "kg"), ("friction.viscous", "N.s/m"),
                                       ("controller.bandwidth", "Hz"),
                                       ("controller.motor.voltage_limit", "V"),
                                       ("trajectory.duration", "s")])
def test_axis_labels_take_the_unit_of_the_key(key, unit):
    assert axis_label(key) == f"{key} ({unit})"
