"""How many points each task of a sweep takes: tasks sized to a target duration from the
measured cost of a point, so that the scheduler's own cost (about 1 ms a task on Dask) stays a
small share however cheap a point is, and the last tasks shrink so that every worker finishes at
about the same time.

The first tasks take PROBE points (the cost is not known yet); each later one
floor(TARGET_SECONDS / cost) points, cost being the mean seconds a point took in the tasks
finished so far (TaskCosts; measured on the workers: scheduling and transfer excluded); with more
than one worker, no more than 1/TAIL_SHARES of the remaining points per worker, unless that is
fewer than a task of MIN_SECONDS takes;
always 1 to `most` points (the grid's batch bound) and no more than remain. A grid that gives
`batch` gets tasks of exactly that many points (the last one: what remains).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

TARGET_SECONDS = 0.3   # a task: scheduler cost under 1 %, and short enough to balance
MIN_SECONDS = 0.02     # the shortest task the tail may take (its share of overhead ~5 %)
PROBE = 2              # points of each task sent before a cost is measured
TAIL_SHARES = 4        # the remaining points per worker are cut into at least this many tasks
TASKS_PER_WORKER = 2   # tasks kept submitted per worker: the next one waits while one runs


@dataclass(frozen=True)
class BatchSizer:
    """The size of the next task (see the module doc)."""

    most: int                  # points a task may take (a chunk file's bound)
    fixed: bool = False        # every task takes `most` points (the grid gives `batch`)
    target: float = TARGET_SECONDS

    def size(self, cost: float | None, remaining: int, workers: int) -> int:
        """Points of the next task, given the mean cost of a point (s; None: not measured
        yet), the points not yet sent and the workers."""
        if remaining <= 0:
            return 0
        if self.fixed:
            n = self.most
        elif cost is None:
            n = PROBE
        elif cost <= 0:
            n = self.most
        else:
            n = math.floor(self.target / cost)
            if workers > 1:     # one worker has nothing to balance
                tail = math.ceil(remaining / (workers * TAIL_SHARES))
                n = min(n, max(tail, math.ceil(MIN_SECONDS / cost)))
        return max(1, min(n, self.most, remaining))

    def in_flight(self, workers: int) -> int:
        """Tasks to keep submitted: enough that no worker waits on the client."""
        return TASKS_PER_WORKER * max(workers, 1)


class TaskCosts:
    """The mean seconds a point took over the tasks finished so far, each worker's first task
    of the sweep left out once others are in (it computes the trajectories the later ones
    reuse): an estimate dominated by the large tasks, not moved much by the small last ones."""

    def __init__(self) -> None:
        self.points, self.seconds = [0, 0], [0.0, 0.0]   # [later tasks, first tasks]

    def add(self, points: int, seconds: float, first: bool = False) -> None:
        self.points[first] += points
        self.seconds[first] += seconds

    @property
    def per_point(self) -> float | None:
        k = 0 if self.points[0] else 1
        return self.seconds[k] / self.points[k] if self.points[k] else None
