"""Small dense matrices in numba kernels: products, matrix–vector, inverses.

Per-target 2×2 to 6×6 algebra inside the batched kernels (Kalman update, fusion, ellipse
fit). numba sends ``@`` and ``np.linalg`` to BLAS/LAPACK, which costs ~0.5–1 µs per call
on such sizes, more than the arithmetic; these loops are inlined instead.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["inv_into", "inv_small", "mm", "mv"]


@njit(cache=True)
def inv_small(A):  # type: ignore[no-untyped-def]
    """Inverse of a small regular matrix (Gauss–Jordan, partial pivoting); numba.

    The batched filters call it per target on 2×2 and 4×4 matrices, where a LAPACK call
    costs more than the arithmetic.
    """
    m = A.shape[0]
    Inv = np.empty((m, m))
    inv_into(A, Inv, np.empty((m, m)))
    return Inv


@njit(cache=True)
def inv_into(A, Inv, M):  # type: ignore[no-untyped-def]
    """:func:`inv_small` writing into ``Inv``, with ``M`` as scratch (same shape)."""
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            M[i, j] = A[i, j]
            Inv[i, j] = 1.0 if i == j else 0.0
    for c in range(m):
        piv = c
        for r in range(c + 1, m):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if piv != c:
            for k in range(m):
                M[c, k], M[piv, k] = M[piv, k], M[c, k]
                Inv[c, k], Inv[piv, k] = Inv[piv, k], Inv[c, k]
        d = M[c, c]
        for k in range(m):
            M[c, k] /= d
            Inv[c, k] /= d
        for r in range(m):
            if r != c:
                f = M[r, c]
                if f != 0.0:
                    for k in range(m):
                        M[r, k] -= f * M[c, k]
                        Inv[r, k] -= f * Inv[c, k]


@njit(cache=True)
def mm(A, B):  # type: ignore[no-untyped-def]
    """Small matrix product by loops (no BLAS call overhead); numba."""
    n, k, m = A.shape[0], A.shape[1], B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for p in range(k):
            a = A[i, p]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[p, j]
    return C


@njit(cache=True)
def mv(A, v):  # type: ignore[no-untyped-def]
    """Matrix–vector product by loops; numba."""
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            out[i] += A[i, j] * v[j]
    return out
