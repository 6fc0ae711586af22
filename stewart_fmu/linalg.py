"""Small dense solves for the 6x6 systems of the compiled kernels (no allocation, no BLAS call)."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def lu_factor(A, order) -> float:
    """LU of a 6x6 with partial pivoting in place; returns min |pivot| (0 when singular).

    order[0, k] names the row of the caller's matrix stored in row k of A, order[1, r] is where
    row r is stored; the swaps of the pivoting update both, so that on return row k of the
    factors belongs to row order[0, k]. Callers store their rows where order[1] says (the
    previous factorization's pivot order), so that along a trajectory the pivoting finds its
    rows in place and swaps nothing: the swaps' memory round trips lie on the serial path of
    the elimination. Ties of |pivot| go to the smaller row name, which makes the factors
    independent of the order the rows came in (a batch gives what single calls give).
    Callers scale rows to entries of order one, so the smallest pivot measures singularity."""
    n = 6
    pmin = np.inf
    for k in range(n):
        p, best = k, abs(A[k, k])
        for i in range(k + 1, n):
            a = abs(A[i, k])
            if a > best or (a == best and order[0, i] < order[0, p]):
                p, best = i, a
        if p != k:
            order[0, k], order[0, p] = order[0, p], order[0, k]
            order[1, order[0, k]], order[1, order[0, p]] = k, p
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
        pmin = min(pmin, best)
        if best == 0.0:
            return 0.0
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] * inv
            A[i, k] = f
            for j in range(k + 1, n):
                A[i, j] -= f * A[k, j]
    return pmin


@njit(cache=True, error_model="numpy", inline="always")
def lu_solve(LU, b) -> None:
    """Solve a 6x6 in place with the factors of lu_factor; b[k] is the entry of row order[0, k]
    (the order lu_factor returned), the solution comes in the natural order."""
    n = 6
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= LU[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= LU[i, j] * b[j]
        b[i] = s / LU[i, i]


@njit(cache=True, error_model="numpy", inline="always")
def cholesky_solve(A, b) -> bool:
    """Solve a 6x6 A x = b in place for symmetric positive-definite A (A is overwritten)."""
    n = 6
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= A[j, k] * A[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        A[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / d
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= A[i, k] * b[k]
        b[i] = s / A[i, i]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, n):
            s -= A[k, i] * b[k]
        b[i] = s / A[i, i]
    return True
