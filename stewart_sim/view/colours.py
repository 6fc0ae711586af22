"""The force colour map of the view: matplotlib's diverging "coolwarm" (Moreland 2009), blue for
pull, light grey at zero, red for push, sampled once into a table that the page interpolates
linearly exactly as `force_colours` does here (the browser tests compare the two)."""
from __future__ import annotations

import math

import matplotlib
import numpy as np

TABLE_SIZE = 33   # odd: zero force falls on an entry (the map's neutral grey)


def colour_table() -> np.ndarray:
    """(TABLE_SIZE, 3) RGB in [0, 1], from -scale (row 0) to +scale (last row)."""
    cmap = matplotlib.colormaps["coolwarm"]
    return np.asarray(cmap(np.linspace(0.0, 1.0, TABLE_SIZE))[:, :3], dtype=float)


def force_colours(forces, scale: float, table: np.ndarray | None = None) -> np.ndarray:
    """RGB of each force (N) on the colour bar [-scale, +scale] (clipped): shape (..., 3)."""
    table = colour_table() if table is None else table
    s = (np.clip(np.asarray(forces, dtype=float) / scale, -1.0, 1.0) + 1.0) / 2.0
    x = s * (len(table) - 1)
    k = np.minimum(np.floor(x).astype(int), len(table) - 2)
    w = (x - k)[..., None]
    return table[k] * (1.0 - w) + table[k + 1] * w


def nice_ceiling(x: float) -> float:
    """The smallest of 1, 2, 2.5, 5 x 10^k at or above x (> 0): the colour bar's end."""
    if not (x > 0 and math.isfinite(x)):
        return 1.0
    e = math.floor(math.log10(x))
    for m in (1.0, 2.0, 2.5, 5.0, 10.0):
        if m * 10.0 ** e >= x * (1 - 1e-12):
            return m * 10.0 ** e
    return 10.0 ** (e + 1)
