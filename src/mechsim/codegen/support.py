"""Compiled helpers that generated kernel code calls (small dense linear algebra)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def solve(A, b):  # type: ignore[no-untyped-def]
    """Solve A x = b (small dense system) by Gaussian elimination with partial pivoting."""
    n = b.size
    M = A.copy()
    x = b.copy()
    for k in range(n):
        piv = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                piv = i
        if piv != k:
            for j in range(n):
                tmp = M[k, j]
                M[k, j] = M[piv, j]
                M[piv, j] = tmp
            tmp = x[k]
            x[k] = x[piv]
            x[piv] = tmp
        d = M[k, k]
        for i in range(k + 1, n):
            f = M[i, k] / d
            if f != 0.0:
                for j in range(k, n):
                    M[i, j] -= f * M[k, j]
                x[i] -= f * x[k]
    for k in range(n - 1, -1, -1):
        s = x[k]
        for j in range(k + 1, n):
            s -= M[k, j] * x[j]
        x[k] = s / M[k, k]
    return x


@njit(cache=True)
def project_onto(G, r, x):  # type: ignore[no-untyped-def]
    """x -= Gᵀ (G Gᵀ)⁻¹ r: the least-norm correction that removes the residual r.
    A zero row of G (a released constraint, with r = 0 there) is skipped."""
    nc = r.size
    GG = np.empty((nc, nc))
    for i in range(nc):
        for j in range(nc):
            s = 0.0
            for k in range(x.size):
                s += G[i, k] * G[j, k]
            GG[i, j] = s
        if GG[i, i] == 0.0:
            GG[i, i] = 1.0
    mu = solve(GG, r)
    for k in range(x.size):
        s = 0.0
        for i in range(nc):
            s += G[i, k] * mu[i]
        x[k] -= s
