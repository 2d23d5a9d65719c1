"""Small dense matrices in numba kernels: products, matrix–vector, inverses, 3×3 algebra.

Per-target 2×2 to 6×6 algebra inside the batched kernels (Kalman update, fusion, ellipse
fit). numba sends ``@`` and ``np.linalg`` to BLAS/LAPACK, which costs ~0.5–1 µs per call
on such sizes, more than the arithmetic; these loops are inlined instead. The ``*_into``
variants write into caller-owned buffers: a numba array allocation costs ~40 ns, and the
ellipse fit made ~35 of them per cluster (2 µs, more than the fit's arithmetic).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["chol3_into", "eig_sym3_into", "inv3_into", "inv_into", "inv_into_m", "inv_lower3_into",
           "inv_small", "mm", "mm_into", "mv", "top_eig_sym3_into"]


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


@njit(cache=True, inline="always")
def inv_into_m(A, Inv, M, m):  # type: ignore[no-untyped-def]
    """:func:`inv_into` of an ``m``×``m`` matrix, inlined (numba IR) into its caller: with
    ``m`` a constant there the loops unroll (the Kalman and fusion rows: ~1.4x faster).
    The same operations in the same order, so the result equals :func:`inv_into`'s bit
    for bit."""
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
def inv_into(A, Inv, M):  # type: ignore[no-untyped-def]
    """:func:`inv_small` writing into ``Inv``, with ``M`` as scratch (same shape)."""
    inv_into_m(A, Inv, M, A.shape[0])


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


@njit(cache=True)
def mm_into(A, B, C):  # type: ignore[no-untyped-def]
    """:func:`mm` writing into ``C`` (same arithmetic, same rounding)."""
    n, k, m = A.shape[0], A.shape[1], B.shape[1]
    for i in range(n):
        for j in range(m):
            C[i, j] = 0.0
    for i in range(n):
        for p in range(k):
            a = A[i, p]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[p, j]


@njit(cache=True)
def inv3_into(A, B):  # type: ignore[no-untyped-def]
    """Inverse of a 3×3 matrix by its adjugate, into ``B`` (caller guarantees it is regular)."""
    B[0, 0] = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    B[0, 1] = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    B[0, 2] = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    B[1, 0] = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    B[1, 1] = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    B[1, 2] = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    B[2, 0] = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    B[2, 1] = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    B[2, 2] = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    det = A[0, 0] * B[0, 0] + A[0, 1] * B[1, 0] + A[0, 2] * B[2, 0]
    for i in range(3):
        for j in range(3):
            B[i, j] /= det


@njit(cache=True)
def chol3_into(A, L):  # type: ignore[no-untyped-def]
    """Cholesky factor of a 3×3 symmetric matrix into ``L``; False (a zero pivot left) when not PD."""
    for i in range(3):
        for j in range(3):
            L[i, j] = 0.0
    for i in range(3):
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if acc <= 0.0:
                    return False
                L[i, i] = np.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@njit(cache=True)
def inv_lower3_into(L, Li):  # type: ignore[no-untyped-def]
    """Inverse of a 3×3 lower-triangular matrix by forward substitution, into ``Li``."""
    for i in range(3):
        for j in range(3):
            Li[i, j] = 0.0
    for c in range(3):
        for i in range(c, 3):
            acc = 1.0 if i == c else 0.0
            for k in range(c, i):
                acc -= L[i, k] * Li[k, c]
            Li[i, c] = acc / L[i, i]


@njit(cache=True)
def top_eig_sym3_into(G, v):  # type: ignore[no-untyped-def]
    """Largest eigenvalue of a symmetric 3×3 matrix (returned) and a unit eigenvector (into ``v``).

    Eigenvalues by the trigonometric method (Smith 1961); the eigenvector is the largest
    cross product of two rows of ``G - mu I`` (orthogonal to both, so in its null space).
    """
    p1 = G[0, 1] ** 2 + G[0, 2] ** 2 + G[1, 2] ** 2
    q = (G[0, 0] + G[1, 1] + G[2, 2]) / 3.0
    p2 = (G[0, 0] - q) ** 2 + (G[1, 1] - q) ** 2 + (G[2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    v[0], v[1], v[2] = 0.0, 0.0, 0.0
    if p == 0.0:
        v[0] = 1.0
        return q
    b00, b11, b22 = (G[0, 0] - q) / p, (G[1, 1] - q) / p, (G[2, 2] - q) / p
    b01, b02, b12 = G[0, 1] / p, G[0, 2] / p, G[1, 2] / p
    b10, b20, b21 = G[1, 0] / p, G[2, 0] / p, G[2, 1] / p
    r = 0.5 * (b00 * (b11 * b22 - b12 * b21) - b01 * (b10 * b22 - b12 * b20) + b02 * (b10 * b21 - b11 * b20))
    r = min(max(r, -1.0), 1.0)
    mu = q + 2.0 * p * np.cos(np.arccos(r) / 3.0)
    best = -1.0
    for i, j in ((0, 1), (0, 2), (1, 2)):
        # rows i, j of A = G - mu I
        ai0 = G[i, 0] - (mu if i == 0 else 0.0)
        ai1 = G[i, 1] - (mu if i == 1 else 0.0)
        ai2 = G[i, 2] - (mu if i == 2 else 0.0)
        aj0 = G[j, 0] - (mu if j == 0 else 0.0)
        aj1 = G[j, 1] - (mu if j == 1 else 0.0)
        aj2 = G[j, 2] - (mu if j == 2 else 0.0)
        cx = ai1 * aj2 - ai2 * aj1
        cy = ai2 * aj0 - ai0 * aj2
        cz = ai0 * aj1 - ai1 * aj0
        nn = cx * cx + cy * cy + cz * cz
        if nn > best:
            best = nn
            v[0], v[1], v[2] = cx, cy, cz
    nrm = np.sqrt(best) if best > 0.0 else 1.0
    for i in range(3):
        v[i] /= nrm
    return mu


@njit(cache=True)
def eig_sym3_into(A, w, V, B):  # type: ignore[no-untyped-def]
    """All eigenpairs of a symmetric 3×3 matrix by cyclic Jacobi rotations.

    Eigenvalues ascending into ``w`` (3,), unit eigenvectors in the columns of ``V``
    (3, 3); ``B`` (3, 3) is scratch. Jacobi is accurate to ~eps·‖A‖ in every eigenpair
    (no cancellation of a closed-form cubic), which the ellipse fit needs when the
    reduced scatter is nearly singular (five points on a conic).
    """
    for i in range(3):
        for j in range(3):
            B[i, j] = 0.5 * (A[i, j] + A[j, i])
            V[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(50):
        off = B[0, 1] * B[0, 1] + B[0, 2] * B[0, 2] + B[1, 2] * B[1, 2]
        diag = B[0, 0] * B[0, 0] + B[1, 1] * B[1, 1] + B[2, 2] * B[2, 2]
        if off <= 1e-36 * diag or off == 0.0:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = B[p, q]
            if apq == 0.0:
                continue
            # rotation angle that zeroes B[p, q] (Golub & Van Loan, Algorithm 8.4.1)
            tau = (B[q, q] - B[p, p]) / (2.0 * apq)
            t = (1.0 if tau >= 0.0 else -1.0) / (abs(tau) + np.sqrt(1.0 + tau * tau))
            c = 1.0 / np.sqrt(1.0 + t * t)
            s = t * c
            for k in range(3):  # B <- B J
                bkp, bkq = B[k, p], B[k, q]
                B[k, p] = c * bkp - s * bkq
                B[k, q] = s * bkp + c * bkq
            for k in range(3):  # B <- Jᵀ B
                bpk, bqk = B[p, k], B[q, k]
                B[p, k] = c * bpk - s * bqk
                B[q, k] = s * bpk + c * bqk
            for k in range(3):  # V <- V J
                vkp, vkq = V[k, p], V[k, q]
                V[k, p] = c * vkp - s * vkq
                V[k, q] = s * vkp + c * vkq
    for i in range(3):
        w[i] = B[i, i]
    # sort ascending (3 elements: insertion sort, columns of V along)
    for i in range(1, 3):
        j = i
        while j > 0 and w[j - 1] > w[j]:
            w[j - 1], w[j] = w[j], w[j - 1]
            for k in range(3):
                V[k, j - 1], V[k, j] = V[k, j], V[k, j - 1]
            j -= 1
