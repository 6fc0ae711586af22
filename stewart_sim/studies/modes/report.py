"""The result set of `stewart-sim modes`, written whole or not at all (outputs.result_set):
modes.csv (the contract's first columns mode,frequency_hz), stiffness.csv (per axis at the
pivot), stiffness_matrix.csv (K in SI), and with --map, map.csv and its figures."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from stewart_fmu import io
from stewart_sim.shell.outputs import result_set
from stewart_sim.studies.sweep.result_table import csv_text

from .study import POSE, Grid, MapResult, ModesResult

SHAPE = ("dx", "dy", "dz", "dthx", "dthy", "dthz")      # the mode's twist (mass-normalised)
LEG_RATES = tuple(f"ldot{i}" for i in range(1, 7))      # the legs' length rates in the mode
AXES = ("x", "y", "z", "thx", "thy", "thz")
# per axis at the pivot: stiffness in N/um or N m/urad, compliance in um/N or urad/(N m)
STIFFNESS_COLUMNS = ("axis", "stiffness", "stiffness_unit", "compliance", "compliance_unit")
MAP_COLUMNS = (*POSE, "inside", "lowest_hz", "weakest_n_per_um", "weak_x", "weak_y", "weak_z")


def mode_rows(r: ModesResult) -> tuple[list[str], list[dict]]:
    """modes.csv: mode, frequency_hz, damping_ratio (with [friction]), the shape, the leg rates."""
    m = r.modes
    columns = ["mode", "frequency_hz", *(["damping_ratio"] if m.damping is not None else []),
               *SHAPE, *LEG_RATES]
    rows = []
    for j in range(r.count):
        row = {"mode": str(j + 1), "frequency_hz": float(m.frequency_hz[j])}
        if m.damping is not None:
            row["damping_ratio"] = float(m.damping[j])
        row |= dict(zip(SHAPE, map(float, m.shapes[j])))
        row |= dict(zip(LEG_RATES, map(float, m.leg_rates[j])))
        rows.append(row)
    return columns, rows


def stiffness_rows(r: ModesResult) -> tuple[list[str], list[dict]]:
    """stiffness.csv: each axis's stiffness at the pivot, every other direction free."""
    s = r.stiffness
    rows = []
    for k, axis in enumerate(AXES):
        c = float(s.axis_compliance[k]) * 1e6     # um/N or urad/(N m)
        rows.append({"axis": axis, "stiffness": 1.0 / c, "compliance": c,
                     "stiffness_unit": "N/um" if k < 3 else "N.m/urad",
                     "compliance_unit": "um/N" if k < 3 else "urad/(N.m)"})
    return list(STIFFNESS_COLUMNS), rows


def matrix_rows(r: ModesResult) -> tuple[list[str], list[dict]]:
    """stiffness_matrix.csv: K (SI: N/m, N/rad, N m/rad) about C's origin in N, row by row."""
    K = r.stiffness.matrix
    return ["row", *AXES], [{"row": a, **dict(zip(AXES, map(float, K[k])))} for k, a in enumerate(AXES)]


def map_rows(m: MapResult) -> tuple[list[str], list[dict]]:
    """map.csv: every pose of the grid; the values where it is inside (empty cells outside)."""
    rows, k = [], 0
    for pose, inside in zip(m.poses, m.inside):
        row = dict(zip(POSE, map(float, pose))) | {"inside": "1" if inside else "0"}
        if inside:
            v = m.values
            d = v.weakest_direction[k]
            row |= {"lowest_hz": float(v.lowest_hz[k]), "weakest_n_per_um": float(v.weakest[k]) * 1e-6,
                    "weak_x": float(d[0]), "weak_y": float(d[1]), "weak_z": float(d[2])}
            k += 1
        else:
            row |= {c: "" for c in MAP_COLUMNS[7:]}
        rows.append(row)
    return list(MAP_COLUMNS), rows


def write(out: str | Path, result: ModesResult, map_result: MapResult | None = None,
          grid: Grid | None = None, view: bool = False) -> list[str]:
    """Write the set into out (whole or not at all); the names written. With a map, its
    figures too (map_lowest_hz.png, map_weakest.png: stewart_sim.studies.modes.plots); with
    `view`, view.html (the mode shapes animated: stewart_sim.studies.modes.animation)."""
    names = []
    with result_set(out) as stage:
        def table(name: str, columns_rows) -> None:
            io.write_text(stage / name, csv_text(*columns_rows))
            names.append(name)

        table("modes.csv", mode_rows(result))
        table("stiffness.csv", stiffness_rows(result))
        table("stiffness_matrix.csv", matrix_rows(result))
        if map_result is not None:
            from stewart_sim.shell.plots import save_figure   # matplotlib: only when writing a map

            from .plots import map_figures

            table("map.csv", map_rows(map_result))
            for name, fig in map_figures(result.model.name, grid, map_result).items():
                save_figure(fig, stage / name)
                names.append(name)
        if view:
            from stewart_sim.view.files import VIEW_FILE
            from stewart_sim.view.html import write_view

            from .animation import modes_view

            write_view(stage / VIEW_FILE, modes_view(result, source=str(out)))
            names.append(VIEW_FILE)
    return names


def summary(r: ModesResult) -> str:
    """The lines printed: the modes and the stiffness at the pivot."""
    m, s = r.modes, r.stiffness
    lines = [f"{r.model.name}: modes at pose {np.asarray(r.modes.pose).tolist()}"
             + (f" with a payload of {r.model.payload.mass:g} kg" if r.model.payload else "")]
    for j in range(r.count):
        zeta = f"  damping {m.damping[j]:.3g}" if m.damping is not None else ""
        lines.append(f"  mode {j + 1}: {m.frequency_hz[j]:10.4g} Hz{zeta}")
    k = s.axis_stiffness
    lines.append("  stiffness at the pivot " + np.array2string(s.pivot, separator=", ") + ": "
                 + ", ".join(f"{a} {k[i] * 1e-6:.4g} N/um" for i, a in enumerate("xyz")) + "; "
                 + ", ".join(f"{a} {k[3 + i] * 1e-6:.4g} N m/urad" for i, a in enumerate(AXES[3:])))
    return "\n".join(lines)
