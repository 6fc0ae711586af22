"""Small dense solves for the 6x6 systems of the compiled kernels (no allocation, no BLAS call)."""
from __future__ import annotations

import numpy as np
from numba import njit



@njit(cache=True, error_model="numpy", inline="always")
def lu_factor(A, piv) -> float:
    """LU of a 6x6 with partial pivoting in place; returns min |pivot| (0 when singular).

    Callers scale rows to entries of order one, so the smallest pivot measures singularity."""
    n = 6
    pmin = np.inf
    for k in range(n):
        p, best = k, abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > best:
                p, best = i, abs(A[i, k])
        piv[k] = p
        if p != k:
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
def lu_solve(LU, piv, b) -> None:
    """Solve a 6x6 in place with the factors of lu_factor."""
    n = 6
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
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
