"""The constant-orientation workspace map (maps.WorkspaceMap) drawn as a surface: the boundary
of the union of its runs, each run the prism of its x-y cell (side h, centred on the run's x, y)
between z_low and z_high, as a closed triangle mesh (every edge shared by exactly two
triangles) with outward normals.

Faces: each run's top and bottom square at z_high and z_low; on each of a cell's four sides,
a vertical wall over the part of the cell's z-intervals that the neighbour cell across that side
does not hold (all of them where the neighbour holds no run). Every vertex is a corner of the
grid at a run's end; a wall's vertical edges are split at every vertex on their corner line, so
no vertex sits inside another triangle's edge, and a wall is triangulated as a ladder between
its two edges' vertices. Where two diagonal cells alone meet along a stretch of a corner line
(four walls on one edge), each cell's walls get their own vertex at the stretch's midpoint, so
the two stay apart and every edge bounds exactly two triangles. The mesh encloses the runs'
volume exactly: the map's volume (its z-lengths times h^2).

A map of many columns draws on a coarser grid (drawing_step): every k-th column in x and in y
(k odd, the centre column of each k x k block), as a cell of side k h; the volume reported
stays the map's, the drawing's own is that of the columns it draws.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_sim.studies.workspace.maps import WorkspaceMap

MAX_DRAWN_COLUMNS = 12000  # columns drawn at most (about 700 bytes of page each)
# a cell's four sides: the neighbour's offset, and the side's two grid corners (from the
# cell's lower corner) in the order that makes the wall counter-clockwise seen from outside
SIDES = (((1, 0), (1, 0), (1, 1)), ((-1, 0), (0, 1), (0, 0)),
         ((0, 1), (1, 1), (0, 1)), ((0, -1), (0, 0), (1, 0)))


@dataclass(frozen=True)
class Surface:
    """A closed triangle mesh: vertices (V, 3) m, triangles (T, 3) indices (counter-clockwise
    seen from outside), normals (V, 3) unit (the adjacent triangles' area-weighted mean), the
    drawing's grid step (m) and its columns drawn."""

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    step: float
    columns: int


def drawing_step(m: WorkspaceMap, max_columns: int = MAX_DRAWN_COLUMNS) -> int:
    """The least odd k whose grid (every k-th column in x and y) draws at most max_columns."""
    columns = len(np.unique(m.runs[:, :2], axis=0))
    k = 1
    while columns / (k * k) > max_columns:
        k += 2
    return k


def _columns(m: WorkspaceMap, k: int) -> dict[tuple[int, int], list[tuple[float, float]]]:
    """The drawn cells (indices on the grid of step k h) and their runs' (z_low, z_high),
    ascending."""
    cell = np.rint((m.runs[:, :2] - m.lo[:2]) / m.h - 0.5).astype(np.int64)
    out: dict[tuple[int, int], list[tuple[float, float]]] = {}
    for (i, j), (zl, zh) in zip(cell.tolist(), m.runs[:, 2:].tolist()):
        if i % k == k // 2 and j % k == k // 2:
            out.setdefault((i // k, j // k), []).append((zl, zh))
    for runs in out.values():
        runs.sort()
    return out


def _minus(a: list[tuple[float, float]], b: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The parts of the intervals a that no interval of b covers (both ascending, disjoint)."""
    out = []
    for lo, hi in a:
        for blo, bhi in b:
            if bhi <= lo or blo >= hi:
                continue
            if blo > lo:
                out.append((lo, blo))
            lo = max(lo, bhi)
            if lo >= hi:
                break
        if lo < hi:
            out.append((lo, hi))
    return out


def _ladder(left: list[float], right: list[float]) -> list[tuple[int, int, int]]:
    """Triangles between two vertical edges' vertices (each edge's z, ascending, from the same
    bottom to the same top), as (edge, position) pairs (edge 0 left, 1 right), counter-clockwise
    seen from the side where left comes before right."""
    tris, a, b = [], 0, 0
    while a < len(left) - 1 or b < len(right) - 1:
        if b < len(right) - 1 and (a == len(left) - 1 or right[b + 1] <= left[a + 1]):
            tris.append(((0, a), (1, b), (1, b + 1)))
            b += 1
        else:
            tris.append(((0, a), (1, b), (0, a + 1)))
            a += 1
    return tris


def _holds(runs: list[tuple[float, float]], z: float) -> bool:
    return any(lo < z < hi for lo, hi in runs)


def _diagonal(cols: dict, c: tuple[int, int], zs: np.ndarray) -> set[float]:
    """The lower ends of the stretches of corner line c (between its vertices zs) where only
    two diagonal cells about the line hold runs."""
    around = [cols.get((c[0] + di, c[1] + dj), []) for di, dj in ((-1, -1), (0, -1), (-1, 0),
                                                                    (0, 0))]
    out = set()
    for z0, z1 in zip(zs.tolist(), zs[1:].tolist()):
        held = [_holds(runs, 0.5 * (z0 + z1)) for runs in around]
        if held in ([True, False, False, True], [False, True, True, False]):
            out.add(z0)
    return out


def _edge(zs: np.ndarray, diagonal: set[float], a: float, b: float) -> list[tuple[float, bool]]:
    """A wall's vertical edge on a corner line from a to b: the line's vertices zs there, and a
    midpoint (z, True) inside each of its `diagonal` stretches (four walls on one edge: the
    midpoint, one per cell, keeps the two cells' walls apart)."""
    inside = zs[(zs >= a) & (zs <= b)].tolist()
    out = [(inside[0], False)]
    for z0, z1 in zip(inside, inside[1:]):
        if z0 in diagonal:
            out.append((0.5 * (z0 + z1), True))
        out.append((z1, False))
    return out


def _faces(cols: dict) -> tuple[list, list]:
    """The faces before triangulation: tops (cell, z, up: top or bottom) and walls (cell, P, Q,
    a, b: on the side from grid corner P to Q, from z a to b)."""
    tops, walls = [], []
    for (i, j), runs in cols.items():
        for zl, zh in runs:
            tops += [((i, j), zh, True), ((i, j), zl, False)]
        for (di, dj), p, q in SIDES:
            for a, b in _minus(runs, cols.get((i + di, j + dj), [])):
                walls.append(((i, j), (i + p[0], j + p[1]), (i + q[0], j + q[1]), a, b))
    return tops, walls


def _corner_lines(tops: list, walls: list) -> dict[tuple[int, int], np.ndarray]:
    """Each grid corner's vertical line: the z of every face's vertex on it, ascending."""
    line: dict[tuple[int, int], set[float]] = {}
    for (i, j), z, _ in tops:
        for c in ((i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)):
            line.setdefault(c, set()).add(z)
    for _, P, Q, a, b in walls:
        for c in (P, Q):
            line.setdefault(c, set()).update((a, b))
    return {c: np.array(sorted(zs)) for c, zs in line.items()}


def surface(m: WorkspaceMap, k: int = 1) -> Surface:
    """The boundary of the map's runs drawn on the grid of every k-th column (k odd; 1: all)."""
    if k < 1 or k % 2 == 0:
        raise ValueError(f"drawing step {k}: must be an odd count of columns")
    cols = _columns(m, k)
    tops, walls = _faces(cols)
    ordered = _corner_lines(tops, walls)
    diagonal = {c: _diagonal(cols, c, zs) for c, zs in ordered.items()}
    index: dict[tuple, int] = {}      # (corner i, corner j, z[, the cell of a midpoint])

    def vertex(c: tuple[int, int], z: float, cell: tuple = ()) -> int:
        return index.setdefault((c[0], c[1], z, *cell), len(index))

    tris = []
    for (i, j), z, up in tops:
        quad = [vertex(c, z) for c in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1))]
        if not up:
            quad.reverse()
        tris += [(quad[0], quad[1], quad[2]), (quad[0], quad[2], quad[3])]
    for cell, P, Q, a, b in walls:
        edges = [_edge(ordered[c], diagonal[c], a, b) for c in (P, Q)]
        for tri in _ladder(*([z for z, _ in e] for e in edges)):
            tris.append(tuple(vertex((P, Q)[s], edges[s][n][0], cell * edges[s][n][1])
                              for s, n in tri))
    triangles = np.array(tris, dtype=np.int64).reshape(-1, 3)
    keys = np.array([key[:3] for key in index], dtype=float).reshape(-1, 3)
    step = k * m.h
    vertices = np.column_stack([m.lo[0] + keys[:, 0] * step, m.lo[1] + keys[:, 1] * step,
                                keys[:, 2]])
    return Surface(vertices, triangles, vertex_normals(vertices, triangles), step, len(cols))


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Each vertex's unit normal: the sum of its triangles' (area-weighted) normals."""
    v = vertices[triangles]
    face = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n = np.zeros_like(vertices)
    for c in range(3):
        np.add.at(n, triangles[:, c], face)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def enclosed_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """The volume a closed, outward-oriented mesh encloses (the divergence theorem: the sum of
    the tetrahedra from the origin to each triangle), about its centroid for precision."""
    v = vertices[triangles] - vertices.mean(axis=0)
    return float(np.sum(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2]))) / 6.0)


SURFACE = 0x3f7fd0        # the workspace's blue
SURFACE_OPACITY = 0.35    # translucent: the mechanism inside shows through


def surface_object(path: str, m: WorkspaceMap, model=None) -> tuple[dict, Surface]:
    """The map's surface as a meshcat set_object at `path` (drawing_step's grid), in N: with
    `model`, the map's positions (the frame's, at the map's angles) moved to C's (a rigid
    motion: the mesh stays closed and its volume the same)."""
    s = surface(m, drawing_step(m))
    vertices, normals = s.vertices, s.normals
    if model is not None and m.frame != "platform":
        from stewart_fmu.frames import to_platform

        poses = np.column_stack([vertices, np.tile(m.angles, (len(vertices), 1))])
        vertices = to_platform(model, poses, m.frame)[:, :3]
        normals = vertex_normals(vertices, s.triangles)
    from stewart_sim.view.meshcat_scene import triangle_mesh

    return triangle_mesh(path, vertices, normals, s.triangles, SURFACE, SURFACE_OPACITY), s
