"""Adaptive refinement of a design sweep (`sweep --adaptive N`): after the grid, N more points
where the outcome changes, found by bisecting the grid's edges whose two ends differ.

The outcome (GRID.toml's [adaptive] table, grid.AdaptiveSettings) is a point's feasibility
(target "feasible": status ok or error) or a result column against a threshold (at or above it,
or below; a point with status error has no value there and ends no edge). An edge joins two
neighbours of the full grid along one numeric axis (adjacent values of that axis, every other
value equal); one whose ends differ straddles the boundary. Each round bisects straddling edges
(the geometric mean on a log axis), evaluates the midpoints like any point, and keeps the halves
that still straddle: the boundary's crossing of every grid line is bracketed ever closer, by
half the bracket a round. Rounds take the longest straddling edges first (every crossing is
bracketed as closely before any is bisected again); among edges of one length the largest
change of the target first (1 for feasibility), then the axis and the point in grid order: the
points added are a function of the grid's rows alone, so a resumed sweep picks the same ones.
A grid line crossed twice between two grid points (an island smaller than the grid's spacing)
shows no change there and is not refined.

Round k's points take the ids after the grid's and the earlier rounds', in the order picked,
and its chunk files are DIR/adaptive/round-KKK/chunks/part-*.csv, the grid's form and rules
(stewart_sim/studies/sweep/chunks.py) under a fingerprint of their own (the sweep's and the
round's), so
a chunk of the grid or another round is refused there. The table gains the column `refinement`:
0 for the grid's points, k for round k's.

Why not python-adaptive's learners: they pick each point from the results in the order they
arrive (a resumed sweep would not pick the same points, nor fit the checked chunk files), they
learn a scalar over a continuous box (not a grid's lines with value lists and string axes, nor a
point's failure), and they would add a dependency for the few lines of bisection here.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from stewart_fmu.errors import SweepError
from stewart_sim.studies.sweep.chunks import (ChunkRules, Ledger, chunk_rules, ledger_rows,
                                              resume_ledger)
from stewart_sim.studies.sweep.evaluate import RESULTS
from stewart_sim.studies.sweep.grid import FEASIBLE, NUMBER_AXES, GridSpec
from stewart_sim.studies.sweep.result_table import CHUNKS

ROUNDS = "adaptive"          # DIR/adaptive/round-KKK/: each round's chunk files
REFINEMENT = "refinement"    # the table's column: 0 for a grid point, k for round k's
MAX_ADDED = 1_000_000        # the most points --adaptive may add

Point = tuple[int, dict[str, Any]]
# Evaluate the points not yet in the ledger into chunk files under a directory with the given
# rules, recording them in the ledger; returns the points computed (run.py's runner).
Evaluate = Callable[[Sequence[Point], Path, ChunkRules, Ledger], int]


def check_adaptive(grid: GridSpec, n: int, drive: bool) -> None:
    """SweepError naming the input: N out of range, a target that is no result of the grid's
    evaluation (or torque_max without a [drive]: NaN at every point), and with N > 0 a grid
    with nothing to bisect (a Latin hypercube, no numeric axis of two values)."""
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_ADDED:
        raise SweepError(None, f"--adaptive: must be an integer from 0 to {MAX_ADDED:,}, "
                               f"got {n!r}")
    target, results = grid.adaptive.target, RESULTS[grid.evaluation]
    if target != FEASIBLE and target not in results:
        raise SweepError("adaptive.target", f"must be \"{FEASIBLE}\" or a result of evaluation "
                                            f"'{grid.evaluation}' {results}, got {target!r}",
                         grid.source)
    if target == "torque_max" and not drive:
        raise SweepError("adaptive.target", "torque_max is NaN at every point: the scene has "
                                            "no [drive] table", grid.source)
    if n and grid.method != "grid":
        raise SweepError(None, f"--adaptive {n}: refinement bisects the edges of a full grid; "
                               f"method = \"{grid.method}\" has none (use method = \"grid\")",
                         grid.source)
    if n and not refinable_axes(grid):
        raise SweepError(None, f"--adaptive {n}: no numeric axis with two values or more to "
                               "refine along", grid.source)


def refinable_axes(grid: GridSpec) -> tuple[int, ...]:
    """The indices of the axes an edge may run along: numeric, two distinct values or more."""
    return tuple(j for j, a in enumerate(grid.axes)
                 if a.key in NUMBER_AXES and len(set(a.grid_values())) >= 2)


@dataclass(frozen=True)
class Edge:
    """Two points of the sweep that differ in one axis: `lo` (all the axes' values) and the
    point whose value of that axis is above lo's, by id; `level` k: 2^-k of a grid edge."""

    axis: int
    lo: tuple[Any, ...]
    hi: tuple[Any, ...]
    ids: tuple[int, int]
    level: int
    change: float       # |outcome(hi) - outcome(lo)|

    def order(self) -> tuple:
        """The refinement order: longest first, then the largest change, then grid order."""
        return (self.level, -self.change, self.axis, self.lo)


class Refinement:
    """The rounds of `--adaptive n` after the grid (see the module doc); `rounds` maps each
    added point's id to its round as soon as the point is picked; `parts` holds each round's
    chunk rules and ledger (its rows stay in its chunk files: the table is merged from them).
    Of the rows, only the outcome of each point is held."""

    def __init__(self, grid: GridSpec, fingerprint: str, columns: Sequence[str], drive: bool,
                 n: int):
        self.grid, self.fingerprint, self.columns, self.drive, self.n = (
            grid, fingerprint, tuple(columns), drive, n)
        self.rounds: dict[int, int] = {}
        self.parts: list[tuple[ChunkRules, Ledger]] = []
        self.resumed = self.computed = 0
        self._grid_outcome = np.empty(0)
        self._added: dict[int, float] = {}      # the outcome of each added point computed
        self._status = self.columns.index("status")
        self._target = (None if grid.adaptive.target == FEASIBLE
                        else self.columns.index(grid.adaptive.target))

    def outcome(self, cells: Sequence[str]) -> float:
        """A row's outcome: feasibility 1 or 0; the target's value (NaN for an error row)."""
        ok = cells[self._status] == "ok"
        if self._target is None:
            return 1.0 if ok else 0.0
        return float(cells[self._target]) if ok else math.nan

    def run(self, grid_rows: Iterable[tuple[int, Sequence[str]]], out: Path,
            evaluate: Evaluate, refuse: Callable[[str], None]) -> None:
        """Add up to n points round by round, given every grid point's row (by point id, e.g.
        read back from the grid's chunk files: chunks.ledger_rows); stops early when no edge
        straddles the boundary any more."""
        frontier = self.grid_edges(grid_rows)
        next_id, left = self.grid.size(), self.n
        for k in range(1, self.n + 1):   # each round adds one point at least
            if not frontier or not left:
                break
            picked, frontier = pick(frontier, left)
            points = [(next_id + i, dict(zip(self.grid.keys, midpoint(self.grid, e))))
                      for i, e in enumerate(picked)]
            self.rounds.update((pid, k) for pid, _ in points)
            next_id += len(points)
            left -= len(points)
            self._evaluate(k, points, out, evaluate, refuse)
            for e, (pid, values) in zip(picked, points):
                mid = tuple(values.values())
                for lo, hi, ids in ((e.lo, mid, (e.ids[0], pid)), (mid, e.hi, (pid, e.ids[1]))):
                    a, b = (self._outcome_of(i) for i in ids)
                    half = Edge(e.axis, lo, hi, ids, e.level + 1, abs(b - a))
                    if self.straddles(a, b) and can_bisect(self.grid, half):
                        frontier.append(half)

    def straddles(self, a: float, b: float) -> bool:
        """Whether the outcome changes between two points."""
        return bool(self._straddle_mask(np.array(a), np.array(b)))

    def _evaluate(self, k: int, points: list[Point], out: Path, evaluate: Evaluate,
                  refuse: Callable[[str], None]) -> None:
        """Round k's points: taken back from its chunk files, the rest computed; then their
        outcomes read from the round's chunk files."""
        where = out / ROUNDS / f"round-{k:03d}"
        (where / CHUNKS).mkdir(parents=True, exist_ok=True)
        fp = hashlib.sha256(f"{self.fingerprint} adaptive round {k}".encode()).hexdigest()
        rules = chunk_rules(fp, self.columns, points, self.grid.batch, self.drive)
        ledger = resume_ledger(where, rules, refuse)
        self.parts.append((rules, ledger))   # before computing: an interrupted round is merged
        self.resumed += ledger.count
        self.computed += evaluate(points, where, rules, ledger)
        for pid, cells in ledger_rows(ledger, rules):
            self._added[pid] = self.outcome(cells)

    def _outcome_of(self, pid: int) -> float:
        """The outcome of a grid point or of an added point already computed."""
        return float(self._grid_outcome[pid]) if pid < self.grid.size() else self._added[pid]

    def grid_edges(self, rows: Iterable[tuple[int, Sequence[str]]]) -> list[Edge]:
        """Every straddling edge between neighbours of the grid (rows: every grid point's, by
        id); keeps the grid's outcomes (one float per point), not its rows."""
        axes = [a.grid_values() for a in self.grid.axes]
        shape = tuple(len(v) for v in axes)
        outcome = np.full(self.grid.size(), np.nan)
        seen = np.zeros(self.grid.size(), dtype=bool)
        for pid, cells in rows:
            outcome[pid], seen[pid] = self.outcome(cells), True
        if not seen.all():
            raise SweepError(None, f"refinement needs every grid point's row: "
                                   f"{int((~seen).sum())} missing")
        self._grid_outcome = outcome
        outcome = outcome.reshape(shape)   # ids in C order: the last axis fastest
        edges = []
        for j in refinable_axes(self.grid):
            order = np.argsort(np.asarray(axes[j], float), kind="stable")
            o = np.take(outcome, order, axis=j)
            a = np.take(o, range(len(order) - 1), axis=j)
            b = np.take(o, range(1, len(order)), axis=j)
            for idx in zip(*np.nonzero(self._straddle_mask(a, b))):
                lo, hi = list(idx), list(idx)
                lo[j], hi[j] = order[idx[j]], order[idx[j] + 1]
                e = Edge(j, tuple(v[i] for v, i in zip(axes, lo)),
                         tuple(v[i] for v, i in zip(axes, hi)),
                         (int(np.ravel_multi_index(lo, shape)),
                          int(np.ravel_multi_index(hi, shape))),
                         0, abs(float(b[idx]) - float(a[idx])))
                if can_bisect(self.grid, e):
                    edges.append(e)
        return edges

    def _straddle_mask(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        if self._target is None:
            return a != b
        t = self.grid.adaptive.threshold
        with np.errstate(invalid="ignore"):
            return np.isfinite(a) & np.isfinite(b) & ((a >= t) != (b >= t))


def pick(frontier: list[Edge], most: int) -> tuple[list[Edge], list[Edge]]:
    """A round's edges (the longest, by Edge.order, at most `most`) and the rest."""
    frontier = sorted(frontier, key=Edge.order)
    level = frontier[0].level
    longest = [e for e in frontier if e.level == level]
    return longest[:most], longest[most:] + frontier[len(longest):]


def midpoint(grid: GridSpec, e: Edge) -> tuple[Any, ...]:
    """The edge's middle: lo with its axis's value half way (geometric on a log axis)."""
    a, b = e.lo[e.axis], e.hi[e.axis]
    axis = grid.axes[e.axis]
    mid = math.sqrt(a * b) if axis.log else a + (b - a) / 2
    return (*e.lo[:e.axis], float(mid), *e.lo[e.axis + 1:])


def can_bisect(grid: GridSpec, e: Edge) -> bool:
    """Whether the edge's middle is a float strictly between its ends."""
    a, b = e.lo[e.axis], e.hi[e.axis]
    return a < midpoint(grid, e)[e.axis] < b
