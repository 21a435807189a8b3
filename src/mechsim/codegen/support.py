"""Compiled helpers that generated kernel code calls (small dense linear algebra, array
allocation, a residual test).

Kernel code calls these rather than numpy's functions (``np.empty``, ``np.max``, ...): numba
compiles its own implementation of a numpy function anew in every process that compiles a
caller, while these are compiled once per machine and loaded
from numba's cache, so a new model's kernels compile without them. Same arithmetic and the
same arrays as the numpy calls they stand for. The allocators have explicit signatures: a
size written as a literal in kernel code converts to them (without, numba would compile one
per literal value). ``solve`` and ``project_onto`` are compiled for the arrays generated code
passes when this module is imported (``contract`` imports it, so set-up compiles them with
the shared loops) and stay open to other argument types."""

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


@njit("float64[::1](int64)", cache=True)
def vector(n):  # type: ignore[no-untyped-def]
    """``np.empty(n)``."""
    return np.empty(n)


@njit("float64[:, ::1](int64, int64)", cache=True)
def matrix(m, n):  # type: ignore[no-untyped-def]
    """``np.empty((m, n))``."""
    return np.empty((m, n))


@njit("float64[::1](int64)", cache=True)
def zero_vector(n):  # type: ignore[no-untyped-def]
    """``np.zeros(n)``."""
    return np.zeros(n)


@njit("float64[:, :, ::1](int64, int64, int64)", cache=True)
def tensor(a, b, c):  # type: ignore[no-untyped-def]
    """``np.empty((a, b, c))``."""
    return np.empty((a, b, c))


@njit("float64[:, ::1](int64, int64)", cache=True)
def zero_matrix(m, n):  # type: ignore[no-untyped-def]
    """``np.zeros((m, n))``."""
    return np.zeros((m, n))


@njit("boolean(float64[::1], float64)", cache=True)
def all_below(r, bound):  # type: ignore[no-untyped-def]
    """Whether every |r[k]| < bound (False where one is nan): ``np.max(np.abs(r)) < bound``
    for a non-empty r."""
    for k in range(r.size):
        if not abs(r[k]) < bound:
            return False
    return True


#: The argument types generated kernels pass (C-contiguous float64 matrices and vectors).
solve.compile("float64[::1](float64[:, ::1], float64[::1])")
project_onto.compile("void(float64[:, ::1], float64[::1], float64[::1])")
