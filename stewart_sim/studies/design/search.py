"""The multi-objective search: NSGA-II (pymoo) over the free parameters, each generation's
population evaluated on Dask (the sweep's cluster: stewart_sim.studies.sweep.cluster), then
the chosen design re-checked densely.

Objectives, both minimised: the base radius (m: the footprint) and minus the least relative
margin over the requirements (robustness); constraints: every relative margin >= 0. pymoo's
random state is seeded from design.toml's [search] seed and the evaluations are deterministic
C calls, gathered in the population's order: a seed gives the same generations on any number
of workers."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .candidate import Candidate, evaluate, evaluate_many, requirement_names
from .spec import DRIVE, DesignSpec

TASKS_PER_WORKER = 2
MAX_DENSE_TRIES = 8     # front designs re-checked densely before giving up


@dataclass(frozen=True)
class SearchResult:
    names: tuple[str, ...]          # requirements, the columns of `margins`
    X: np.ndarray                   # (N, free) every candidate evaluated, in order
    margins: np.ndarray             # (N, requirements) relative margins
    generation: np.ndarray          # (N,) the generation of each
    front: np.ndarray               # indices into X of the final non-dominated feasible set
    chosen: Candidate | None        # the chosen design, its dense check's margins
    chosen_index: int | None
    dense_failed: tuple[int, ...]   # front designs the dense check rejected
    closest: Candidate | None       # no design chosen: the least-violating candidate's margins
    seconds: float                  # the search's wall time (evaluations and NSGA-II)
    workers: int


def objectives(spec: DesignSpec, X: np.ndarray, margins: np.ndarray) -> np.ndarray:
    """(N, 2): base radius (m), minus the least relative margin; (N, 3) with the catalogue
    drive's cost (price, else mass) when the drive is free."""
    values = [spec.values(x) for x in X]
    cols = [np.array([v["base_radius"] for v in values]), -margins.min(axis=1)]
    if drive_free(spec):
        cols.append(np.array([spec.drive(v).cost for v in values], dtype=float))
    return np.column_stack(cols)


def drive_free(spec: DesignSpec) -> bool:
    """Whether the search chooses the drive among several catalogue drives."""
    return any(p.free and p.name == DRIVE for p in spec.parameters)


def run(spec: DesignSpec, client, workers: int, progress=print,
        checkpoint=None) -> SearchResult:
    """The search on the Dask client, then the dense check of the chosen design. `checkpoint`
    (a checkpoint.Checkpoint, or None): the generations it holds are told from it instead of
    evaluated, and each generation evaluated is added to it."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem

    names = requirement_names(spec)
    free = spec.free
    problem = Problem(n_var=len(free), n_obj=3 if drive_free(spec) else 2, n_ieq_constr=len(names),
                      xl=np.array([p.low for p in free]), xu=np.array([p.high for p in free]))
    algorithm = NSGA2(pop_size=spec.search.population)
    algorithm.setup(problem, seed=spec.search.seed, termination=("n_gen", spec.search.generations),
                    verbose=False)
    spec_future = client.scatter(spec, broadcast=True)
    Xs, Ms, gens = [], [], []
    t0 = time.perf_counter()
    g = 0
    while algorithm.has_next():
        pop = algorithm.ask()
        X = pop.get("X")
        M = None if checkpoint is None else checkpoint.stored(g, X)
        kept = M is not None
        if not kept:
            M = _evaluate(client, spec_future, X, names, workers)
            if checkpoint is not None:
                checkpoint.record(g, X, M)
        pop.set("F", objectives(spec, X, M), "G", -M)
        algorithm.tell(infills=pop)
        Xs.append(X), Ms.append(M), gens.append(np.full(len(X), g))
        feasible = int(np.sum(np.all(M >= 0, axis=1)))
        progress(f"generation {g + 1}/{spec.search.generations}: {len(X)} candidates, "
                 f"{feasible} feasible, best least margin {M.min(axis=1).max():+.3f}"
                 + (" (from the checkpoint)" if kept else ""))
        g += 1
    seconds = time.perf_counter() - t0
    X, M, gen = np.vstack(Xs), np.vstack(Ms), np.concatenate(gens)
    front = _front(spec, X, M)
    chosen, index, failed = _choose(spec, X, M, front, names)
    closest = None if chosen is not None else evaluate(spec, X[least_violating(M)], names)
    return SearchResult(names, X, M, gen, front, chosen, index, failed, closest, seconds,
                        workers)


def _evaluate(client, spec_future, X: np.ndarray, names, workers: int) -> np.ndarray:
    """Relative margins of X (N, free) on the cluster, a few tasks per worker, in X's order
    (results placed by their part, whatever order they finish in); a lost task is a
    SweepError, and Ctrl-C cancels what is still pending (as the sweep's tasks are)."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    from stewart_fmu.errors import SweepError

    parts = [p for p in np.array_split(X, min(len(X), max(1, workers * TASKS_PER_WORKER)))
             if len(p)]
    futures = {client.submit(evaluate_many, spec_future, part, names, pure=False): k
               for k, part in enumerate(parts)}
    results: list = [None] * len(parts)
    try:
        for fut in as_completed(futures):
            results[futures.pop(fut)] = fut.result()
    except (KilledWorker, FutureCancelledError) as exc:
        raise SweepError(None, f"a design task was lost on the cluster: {exc}") from None
    finally:
        if futures:
            client.cancel(list(futures))
    return np.vstack(results)


def _front(spec: DesignSpec, X: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Indices of the feasible candidates no other feasible one dominates (every one
    evaluated, not only the last population), sorted by base radius; duplicates dropped."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    ok = np.flatnonzero(np.all(M >= 0, axis=1))
    if not len(ok):
        return ok
    F = objectives(spec, X[ok], M[ok])
    _, first = np.unique(np.round(F, 12), axis=0, return_index=True)
    ok, F = ok[np.sort(first)], F[np.sort(first)]
    nd = NonDominatedSorting().do(F, only_non_dominated_front=True)
    idx = ok[nd]
    return idx[np.argsort(objectives(spec, X[idx], M[idx])[:, 0], kind="stable")]


def _choose(spec: DesignSpec, X, M, front, names):
    """The most compact front design (with a free drive: the cheapest drive's, then the most
    compact) keeping the [search] reserve on every requirement whose dense check passes (every
    requirement met on the workspace's check_points grid and on every sample of the motions);
    else the front's most robust that passes; (None, None, rejected) when none does."""
    reserve = spec.search.reserve
    order = [i for i in front if M[i].min() >= reserve]
    if drive_free(spec) and order:
        cost = objectives(spec, X[order], M[order])[:, 2]
        order = [order[k] for k in np.argsort(cost, kind="stable")]
    order += [i for i in front[np.argsort(-M[front].min(axis=1), kind="stable")]
              if i not in order]
    failed = []
    for i in order[:MAX_DENSE_TRIES]:
        c = evaluate(spec, X[i], names, points=spec.workspace.check_points, every=1)
        if c.feasible:
            return c, int(i), tuple(failed)
        failed.append(int(i))
    return None, None, tuple(failed)


def binding(names: tuple[str, ...], M: np.ndarray) -> list[tuple[str, float]]:
    """The requirements no candidate met, with the best relative margin any reached (most
    negative first); empty when each was met by some candidate."""
    best = M.max(axis=0)
    out = [(n, float(b)) for n, b in zip(names, best) if b < 0]
    return sorted(out, key=lambda t: t[1])


def least_violating(M: np.ndarray) -> int:
    """The candidate with the least sum of negative relative margins."""
    return int(np.argmax(np.minimum(M, 0.0).sum(axis=1)))
