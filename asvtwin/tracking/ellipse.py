"""Ellipse fits to point clusters: Halir–Flusser direct least squares and the paper's MLR.

Both fit the conic of the paper's eq. (ellipse_equation)

.. math:: F(x, y) = a x^2 + b x y + c y^2 + d x + e y + f = 0,

to the points of one cluster, after centring them on their mean and scaling them to unit
RMS radius (large NED coordinates would ruin the scatter matrices).

**Halir–Flusser** (paper eqs. shape_fitting_opt_prob, shape_fitting_final_1/2): minimise
:math:`\\|D a\\|^2` s.t. :math:`a^T C a = 4ac - b^2 = 1`. Split :math:`a = (a_1, a_2)` with
:math:`a_1 = (a, b, c)`; the linear part is eliminated, :math:`a_2 = -S_3^{-1} S_2^T a_1`,
leaving the reduced scatter :math:`T = S_1 - S_2 S_3^{-1} S_2^T` (symmetric, positive
semi-definite) and the 3×3 pencil :math:`T a_1 = \\lambda C_1 a_1`. We solve it as the
symmetric problem :math:`L^{-1} C_1 L^{-T} y = \\mu y` with :math:`T = L L^T` and
:math:`\\mu = 1/\\lambda`: its eigenvalues are real, and by Sylvester's law of inertia
exactly one is positive (:math:`C_1` has one positive eigenvalue), the one whose eigenvector
satisfies :math:`4ac - b^2 > 0` — Halir and Flusser's choice, reached without a
non-symmetric eigen-solver. The choice is checked explicitly; none valid means no fit.

**MLR** (the paper's alternative, section "LiDAR Shape Fitting"): ordinary multiple linear
regression of :math:`a x^2 + b x y + c y^2 + d x + e y = 1` (i.e. ``f = -1``); it does not
force an ellipse, so a hyperbola or parabola is reported as no fit.

Both run in one numba kernel over many clusters at once (points concatenated, clusters
given by offsets); :func:`fit_ellipse` is the one-cluster convenience. A fit is data: a
status code, never an exception, for < 5 distinct finite points, collinear points or no
valid ellipse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.tracking.smallmat import (
    eig_sym3_into,
    inv3_into,
    mm_into,
)

__all__ = [
    "FIT_COLLINEAR",
    "FIT_NO_ELLIPSE",
    "FIT_OK",
    "FIT_STATUS",
    "FIT_TOO_FEW_POINTS",
    "METHODS",
    "EllipseFit",
    "EllipseFits",
    "fit_ellipse",
    "fit_ellipses",
]


FIT_OK = 0
FIT_TOO_FEW_POINTS = 1
FIT_COLLINEAR = 2
FIT_NO_ELLIPSE = 3
#: Status code -> name.
FIT_STATUS = ("ok", "too_few_points", "collinear", "no_ellipse")
#: Fitting methods: name -> kernel code.
METHODS = {"halir_flusser": 0, "mlr": 1}

_C1 = np.array([[0.0, 0.0, 2.0], [0.0, -1.0, 0.0], [2.0, 0.0, 0.0]])


#: Longest run :func:`_sort_small` sorts by insertion (longer: numba's quicksort).
_INSERTION_MAX = 64


@njit(cache=True, inline="always")
def _sort_small(v, n):  # type: ignore[no-untyped-def]
    """Sort ``v[:n]`` ascending in place, as ``v[:n].sort()`` does (the same values in the
    same order; NaN last). A cluster's returns come in scan order, so their coordinates
    and angles are mostly one monotone run or two: an insertion sort (after reversing a
    mostly descending run) is nearly linear there, and without numba's quicksort calls it
    costs about half (the two sorts were a third of the fit)."""
    if n > _INSERTION_MAX:
        v[:n].sort()
        return
    down = 0
    for i in range(1, n):
        if v[i] < v[i - 1]:
            down += 1
        elif not v[i] >= v[i - 1]:  # a NaN: numba's sort places it
            v[:n].sort()
            return
    if 2 * down > n:  # mostly descending: reverse first (the sorted result is the same)
        for i in range(n // 2):
            v[i], v[n - 1 - i] = v[n - 1 - i], v[i]
    for i in range(1, n):
        t = v[i]
        j = i - 1
        while j >= 0 and v[j] > t:
            v[j + 1] = v[j]
            j -= 1
        v[j + 1] = t


@njit(cache=True)
def _distinct_finite(p, xs):  # type: ignore[no-untyped-def]
    """Rows of p that are finite, exact duplicates removed (first kept).

    Fast path (the usual LiDAR cluster): all finite and no two equal north coordinates,
    seen on a sorted copy in the scratch ``xs``: ``p`` itself, no argsort, no copy.
    """
    n = p.shape[0]
    clean = True
    for i in range(n):
        xs[i] = p[i, 0]
        if not (np.isfinite(p[i, 0]) and np.isfinite(p[i, 1])):
            clean = False
    if clean:
        _sort_small(xs, n)
        for i in range(1, n):
            if xs[i] == xs[i - 1]:
                clean = False
                break
        if clean:
            return p
    keep = np.zeros(n, np.bool_)
    for i in range(n):
        keep[i] = np.isfinite(p[i, 0]) and np.isfinite(p[i, 1])
    order = np.argsort(p[:, 0])
    for a in range(n):
        i = order[a]
        if not keep[i]:
            continue
        b = a + 1
        while b < n and p[order[b], 0] == p[i, 0]:
            j = order[b]
            if keep[j] and p[j, 1] == p[i, 1]:
                keep[j] = False
            b += 1
    if keep.all():
        return p
    return p[keep]


#: Relative size of an eigenvalue of the reduced scatter below which it counts as zero
#: (an exact conic through the points); rounding leaves ~1e-15.
_SINGULAR = 1e-10
#: A fitted semi-major axis beyond this many RMS radii of the points is not determined by
#: them (two parallel lines, a nearly straight arc): reported as no ellipse.
_MAX_AXIS_RATIO = 100.0


@njit(cache=True)
def _hf_deflated(T, C1, v0, v1, v2):  # type: ignore[no-untyped-def]
    """Ellipse optimum of ``T a = λ C1 a`` on the plane ``(C1 v)ᵀ a = 0`` (v: the exact
    non-elliptic conic). Returns (ok, a1)."""
    g0, g1, g2 = C1[0, 0] * v0 + C1[0, 1] * v1 + C1[0, 2] * v2, C1[1, 0] * v0 + C1[1, 1] * v1 + C1[1, 2] * v2, \
        C1[2, 0] * v0 + C1[2, 1] * v1 + C1[2, 2] * v2
    gn = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    g0, g1, g2 = g0 / gn, g1 / gn, g2 / gn
    # orthonormal basis (p, q) of the plane g^⊥: p from the axis least aligned with g
    if abs(g0) <= abs(g1) and abs(g0) <= abs(g2):
        e0, e1, e2 = 1.0, 0.0, 0.0
    elif abs(g1) <= abs(g2):
        e0, e1, e2 = 0.0, 1.0, 0.0
    else:
        e0, e1, e2 = 0.0, 0.0, 1.0
    d = e0 * g0 + e1 * g1 + e2 * g2
    p0, p1, p2 = e0 - d * g0, e1 - d * g1, e2 - d * g2
    pn = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    p0, p1, p2 = p0 / pn, p1 / pn, p2 / pn
    q0, q1, q2 = g1 * p2 - g2 * p1, g2 * p0 - g0 * p2, g0 * p1 - g1 * p0
    P = ((p0, p1, p2), (q0, q1, q2))
    A = np.zeros((2, 2))
    C = np.zeros((2, 2))
    for i in range(2):
        for j in range(2):
            for k in range(3):
                for m in range(3):
                    A[i, j] += P[i][k] * T[k, m] * P[j][m]
                    C[i, j] += P[i][k] * C1[k, m] * P[j][m]
    # A c = λ C c with A > 0: A = L Lᵀ, (L⁻¹ C L⁻ᵀ) y = (1/λ) y, the positive eigenvalue
    if not (A[0, 0] > 0.0):
        return False, (0.0, 0.0, 0.0)
    l00 = np.sqrt(A[0, 0])
    l10 = A[1, 0] / l00
    r = A[1, 1] - l10 * l10
    if not r > 0.0:
        return False, (0.0, 0.0, 0.0)
    l11 = np.sqrt(r)
    # Li = L⁻¹
    i00, i10, i11 = 1.0 / l00, -l10 / (l00 * l11), 1.0 / l11
    w00 = i00 * i00 * C[0, 0]
    w01 = i00 * (i10 * C[0, 0] + i11 * C[0, 1])
    w11 = i10 * i10 * C[0, 0] + 2.0 * i10 * i11 * C[0, 1] + i11 * i11 * C[1, 1]
    tr, det = w00 + w11, w00 * w11 - w01 * w01
    mu = 0.5 * tr + np.sqrt(max(0.25 * tr * tr - det, 0.0))
    if not mu > 0.0:
        return False, (0.0, 0.0, 0.0)
    # eigenvector of [[w00, w01], [w01, w11]] for mu (the better-conditioned row)
    if abs(w00 - mu) + abs(w01) >= abs(w11 - mu) + abs(w01):
        y0, y1 = -w01, w00 - mu
    else:
        y0, y1 = w11 - mu, -w01
    if y0 == 0.0 and y1 == 0.0:
        y0 = 1.0
    # c = L⁻ᵀ y
    c1 = i11 * y1
    c0 = i00 * y0 + i10 * y1
    return True, (c0 * p0 + c1 * q0, c0 * p1 + c1 * q1, c0 * p2 + c1 * q2)


@njit(cache=True)
def _solve_in_place(A, b):  # type: ignore[no-untyped-def]
    """Solve A x = b (Gaussian elimination, partial pivoting), x into ``b``; A is destroyed.

    False, and b undefined, when a pivot is at most ``_SINGULAR`` times A's largest entry:
    a singular system answers "no solution" instead of dividing by zero.
    """
    m = A.shape[0]
    scale = 0.0
    for i in range(m):
        for j in range(m):
            scale = max(scale, abs(A[i, j]))
    if not scale > 0.0:
        return False
    for c in range(m):
        piv = c
        for r in range(c + 1, m):
            if abs(A[r, c]) > abs(A[piv, c]):
                piv = r
        if not abs(A[piv, c]) > _SINGULAR * scale:
            return False
        if piv != c:
            for k in range(m):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            b[c], b[piv] = b[piv], b[c]
        for r in range(c + 1, m):
            f = A[r, c] / A[c, c]
            if f != 0.0:
                for k in range(c, m):
                    A[r, k] -= f * A[c, k]
                b[r] -= f * b[c]
    for c in range(m - 1, -1, -1):
        acc = b[c]
        for k in range(c + 1, m):
            acc -= A[c, k] * b[k]
        b[c] = acc / A[c, c]
    return True


@njit(cache=True)
def _fit_one(p, method, C1, out, x, y, ang, ws, v3):  # type: ignore[no-untyped-def]
    """Fit one cluster; writes [status, n, cn, ce, a_major, b_minor, angle, coverage, cond, resid].

    ``x``, ``y``, ``ang`` (>= len(p)), ``ws`` (12, 3, 3) and ``v3`` (3,) are scratch buffers
    owned by the caller, so the usual path allocates nothing.
    """
    q = _distinct_finite(p, ang)
    n = q.shape[0]
    out[1] = n
    if n < 5:
        out[0] = 1
        return
    mn, me = 0.0, 0.0
    for k in range(n):
        mn += q[k, 0]
        me += q[k, 1]
    mn /= n
    me /= n
    ss = 0.0
    for k in range(n):
        x[k] = q[k, 0] - mn
        y[k] = q[k, 1] - me
        ss += x[k] * x[k] + y[k] * y[k]
    s = np.sqrt(ss / n)
    if not s > 0.0:
        out[0] = 2
        return
    sxx, sxy, syy = 0.0, 0.0, 0.0
    for k in range(n):
        x[k] /= s
        y[k] /= s
        sxx += x[k] * x[k]
        sxy += x[k] * y[k]
        syy += y[k] * y[k]
    sxx, sxy, syy = sxx / n, sxy / n, syy / n
    # collinearity: eigenvalues of the 2x2 scatter of the normalised points
    tr, det = sxx + syy, sxx * syy - sxy * sxy
    disc = np.sqrt(max(0.25 * tr * tr - det, 0.0))
    lmin, lmax = 0.5 * tr - disc, 0.5 * tr + disc
    out[8] = lmax / lmin if lmin > 0.0 else np.inf
    if lmin <= 1e-12 * lmax:
        out[0] = 2
        return
    # moments m_ij = sum x^i y^j, i + j <= 4, in one pass (no design matrix); each power
    # is built as x^i first, then times y j times
    m00 = m01 = m02 = m03 = m04 = m10 = m11 = m12 = m13 = m20 = m21 = m22 = m30 = m31 = m40 = 0.0
    for k in range(n):
        xk, yk = x[k], y[k]
        y2 = yk * yk
        y3 = y2 * yk
        x2 = xk * xk
        x3 = x2 * xk
        xy = xk * yk
        xy2 = xy * yk
        x2y = x2 * yk
        m00 += 1.0
        m01 += yk
        m02 += y2
        m03 += y3
        m04 += y3 * yk
        m10 += xk
        m11 += xy
        m12 += xy2
        m13 += xy2 * yk
        m20 += x2
        m21 += x2y
        m22 += x2y * yk
        m30 += x3
        m31 += x3 * yk
        m40 += x3 * xk
    # S1 = D1'D1, S2 = D1'D2, S3 = D2'D2 with D1 = [x^2, xy, y^2], D2 = [x, y, 1]
    S1, S2, S3 = ws[0], ws[1], ws[2]
    S1[0, 0], S1[0, 1], S1[0, 2] = m40, m31, m22
    S1[1, 0], S1[1, 1], S1[1, 2] = m31, m22, m13
    S1[2, 0], S1[2, 1], S1[2, 2] = m22, m13, m04
    S2[0, 0], S2[0, 1], S2[0, 2] = m30, m21, m20
    S2[1, 0], S2[1, 1], S2[1, 2] = m21, m12, m11
    S2[2, 0], S2[2, 1], S2[2, 2] = m12, m03, m02
    S3[0, 0], S3[0, 1], S3[0, 2] = m20, m11, m10
    S3[1, 0], S3[1, 1], S3[1, 2] = m11, m02, m01
    S3[2, 0], S3[2, 1], S3[2, 2] = m10, m01, m00
    if method == 0:
        S3i, S2T, Tm, M, T, W = ws[3], ws[4], ws[5], ws[6], ws[7], ws[10]
        inv3_into(S3, S3i)
        for i in range(3):
            for j in range(3):
                S2T[i, j] = S2[j, i]
        mm_into(S3i, S2T, Tm)
        for i in range(3):
            for j in range(3):
                Tm[i, j] = -Tm[i, j]  # a2 = Tm a1
        mm_into(S2, Tm, M)
        for i in range(3):
            for j in range(3):
                M[i, j] += S1[i, j]  # S1 + S2 Tm
        for i in range(3):
            for j in range(3):
                T[i, j] = 0.5 * (M[i, j] + M[j, i])  # reduced scatter, symmetric PSD
        # eigen-decomposition of T (Jacobi; no regulariser: it moved the optimum of exact
        # 5-point conics, the issue of a 1e-13 ridge with a Cholesky factor)
        tw, V = ws[8], ws[9]
        eig_sym3_into(T, v3, V, W)
        t0, t1, t2 = max(v3[0], 0.0), max(v3[1], 0.0), v3[2]
        tw[0, 0], tw[0, 1], tw[0, 2] = t0, t1, t2
        if not t2 > 0.0 or t1 <= _SINGULAR * t2:
            out[0] = 1  # a pencil of conics fits exactly: < 5 points in general position
            return
        if t0 <= _SINGULAR * t2:
            # one conic passes through the points exactly (the null vector v0 of T)
            v00, v01, v02 = V[0, 0], V[1, 0], V[2, 0]
            if 4.0 * v00 * v02 - v01 * v01 > 0.0:
                a1 = (v00, v01, v02)  # an exact ellipse: the optimum (λ = 0)
            else:
                # a hyperbola or parabola: the ellipse optimum is C1-orthogonal to v0
                # (v0ᵀ T a = λ v0ᵀ C1 a = 0), so solve the 2×2 pencil on that plane
                ok, a1 = _hf_deflated(T, C1, v00, v01, v02)
                if not ok:
                    out[0] = 3
                    return
        else:
            # T = V diag(t) Vᵀ, a1 = V diag(t)^-1/2 y:  W y = (1/λ) y with
            # W = diag(t)^-1/2 Vᵀ C1 V diag(t)^-1/2 (one positive eigenvalue: the ellipse)
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for k in range(3):
                        for m in range(3):
                            acc += V[k, i] * C1[k, m] * V[m, j]
                    M[i, j] = acc / np.sqrt(tw[0, i] * tw[0, j])
            U = ws[11]
            eig_sym3_into(M, v3, U, W)
            if not v3[2] > 0.0:  # no eigenvector with 4ac - b^2 > 0
                out[0] = 3
                return
            y0, y1, y2 = U[0, 2] / np.sqrt(t0), U[1, 2] / np.sqrt(t1), U[2, 2] / np.sqrt(t2)
            a1 = (V[0, 0] * y0 + V[0, 1] * y1 + V[0, 2] * y2,
                  V[1, 0] * y0 + V[1, 1] * y1 + V[1, 2] * y2,
                  V[2, 0] * y0 + V[2, 1] * y1 + V[2, 2] * y2)
        a, b, c = a1
        d = Tm[0, 0] * a + Tm[0, 1] * b + Tm[0, 2] * c
        e = Tm[1, 0] * a + Tm[1, 1] * b + Tm[1, 2] * c
        f = Tm[2, 0] * a + Tm[2, 1] * b + Tm[2, 2] * c
    else:
        # normal equations of [x^2, xy, y^2, x, y] w = 1 (MLR, f = -1)
        N = np.empty((5, 5))
        N[:3, :3] = S1
        N[:3, 3:] = S2[:, :2]
        N[3:, :3] = S2[:, :2].T
        N[3:, 3:] = S3[:2, :2]
        w = np.array([m20, m11, m02, m10, m01])
        if not _solve_in_place(N, w):
            # the points lie on a conic through their centroid (e.g. two lines crossing
            # there), which f = -1 cannot express: no MLR ellipse
            out[0] = 3
            return
        a, b, c, d, e, f = w[0], w[1], w[2], w[3], w[4], -1.0
    det4 = 4.0 * a * c - b * b
    if not det4 > 0.0:  # 4ac - b^2 > 0: ellipse condition, eq. (shape_fitting_unequality)
        out[0] = 3
        return
    if a + c < 0.0:
        a, b, c, d, e, f = -a, -b, -c, -d, -e, -f
    x0 = (b * e - 2.0 * c * d) / det4
    y0 = (b * d - 2.0 * a * e) / det4
    f0 = f + 0.5 * (d * x0 + e * y0)
    root = np.sqrt(0.25 * (a - c) ** 2 + 0.25 * b * b)
    l1, l2 = 0.5 * (a + c) - root, 0.5 * (a + c) + root  # 0 < l1 <= l2
    if not (f0 < 0.0 and l1 > 0.0):
        out[0] = 3  # imaginary ellipse
        return
    ax_major, ax_minor = np.sqrt(-f0 / l1), np.sqrt(-f0 / l2)
    if not ax_major <= _MAX_AXIS_RATIO:  # the points have unit RMS radius here
        out[0] = 3  # unbounded: the data do not determine the ellipse
        return
    theta = 0.5 * np.arctan2(b, a - c) + 0.5 * np.pi  # direction of the smaller eigenvalue
    theta = (theta + 0.5 * np.pi) % np.pi - 0.5 * np.pi
    # quality: arc coverage about the fitted centre (in the ellipse's own parameter),
    # RMS Sampson distance
    ct, st = np.cos(theta), np.sin(theta)
    samp = 0.0
    for k in range(n):
        dx, dy = x[k] - x0, y[k] - y0
        ang[k] = np.arctan2((-dx * st + dy * ct) / ax_minor, (dx * ct + dy * st) / ax_major)
        F = a * x[k] * x[k] + b * x[k] * y[k] + c * y[k] * y[k] + d * x[k] + e * y[k] + f
        gx = 2.0 * a * x[k] + b * y[k] + d
        gy = b * x[k] + 2.0 * c * y[k] + e
        samp += F * F / max(gx * gx + gy * gy, 1e-300)
    _sort_small(ang, n)
    gap = ang[0] + 2.0 * np.pi - ang[n - 1]
    for i in range(1, n):
        gap = max(gap, ang[i] - ang[i - 1])
    out[0] = 0
    out[2] = mn + s * x0
    out[3] = me + s * y0
    out[4] = s * ax_major
    out[5] = s * ax_minor
    out[6] = theta
    out[7] = 2.0 * np.pi - gap
    out[9] = s * np.sqrt(samp / n)


@njit(cache=True)
def _fit_many(points, offsets, method, C1):  # type: ignore[no-untyped-def]
    k = offsets.shape[0] - 1
    out = np.full((k, 10), np.nan)
    big = 1
    for i in range(k):
        big = max(big, offsets[i + 1] - offsets[i])
    x, y, ang = np.empty(big), np.empty(big), np.empty(big)
    ws, v3 = np.empty((12, 3, 3)), np.empty(3)
    for i in range(k):
        _fit_one(points[offsets[i]:offsets[i + 1]], method, C1, out[i], x, y, ang, ws, v3)
    return out


@dataclass(frozen=True)
class EllipseFit:
    """One ellipse fit (plain values).

    Attributes
    ----------
    ok : bool
        Whether a valid ellipse was found.
    status : str
        One of :data:`FIT_STATUS`.
    centre : ndarray, shape (2,)
        Centre ``[north_m, east_m]`` [m] (NaN when not ok).
    semi_axes : ndarray, shape (2,)
        Semi-major and semi-minor axis [m], major >= minor.
    angle_rad : float
        Direction of the major axis from north, clockwise, in [-π/2, π/2) [rad].
    n_points : int
        Distinct finite points used.
    arc_coverage_rad : float
        Angular extent of the points about the centre, in the ellipse's own parameter
        (2π minus the largest gap) [rad].
    condition : float
        Elongation of the point set: ratio of the eigenvalues of its 2×2 scatter
        (``inf`` for collinear points) [-].
    residual_m : float
        RMS Sampson (first-order geometric) distance of the points to the conic [m].
    """

    ok: bool
    status: str
    centre: _F8
    semi_axes: _F8
    angle_rad: float
    n_points: int
    arc_coverage_rad: float
    condition: float
    residual_m: float


@dataclass(frozen=True)
class EllipseFits:
    """Many fits as arrays (index ``i`` is cluster ``i``); fields as in :class:`EllipseFit`.

    ``status`` holds the integer codes (:data:`FIT_OK`, ...), ``ok = status == FIT_OK``.
    """

    status: NDArray[np.int64]
    centre: _F8
    semi_axes: _F8
    angle_rad: _F8
    n_points: NDArray[np.int64]
    arc_coverage_rad: _F8
    condition: _F8
    residual_m: _F8

    @property
    def ok(self) -> NDArray[np.bool_]:
        """Whether each fit is a valid ellipse."""
        return self.status == FIT_OK

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @classmethod
    def from_array(cls, out: _F8) -> EllipseFits:
        """From the fit kernel's rows ``[status, n, cn, ce, a, b, angle, coverage, cond, resid]``."""
        return cls(status=out[:, 0].astype(np.int64), centre=out[:, 2:4].copy(), semi_axes=out[:, 4:6].copy(),
                   angle_rad=out[:, 6].copy(), n_points=out[:, 1].astype(np.int64),
                   arc_coverage_rad=out[:, 7].copy(), condition=out[:, 8].copy(), residual_m=out[:, 9].copy())

    def __getitem__(self, i: int) -> EllipseFit:
        code = int(self.status[i])
        return EllipseFit(
            ok=code == FIT_OK, status=FIT_STATUS[code], centre=self.centre[i].copy(),
            semi_axes=self.semi_axes[i].copy(), angle_rad=float(self.angle_rad[i]),
            n_points=int(self.n_points[i]), arc_coverage_rad=float(self.arc_coverage_rad[i]),
            condition=float(self.condition[i]), residual_m=float(self.residual_m[i]),
        )


def _method_code(method: str) -> int:
    if method not in METHODS:
        raise ParameterError(f"ellipse fit method must be one of {tuple(METHODS)}, actually: {method!r}")
    return METHODS[method]


def fit_ellipses(points: ArrayLike, offsets: ArrayLike, *, method: str = "halir_flusser") -> EllipseFits:
    """Fit an ellipse to each of many clusters in one call.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        All clusters' points concatenated, ``[north_m, east_m]`` [m]. Non-finite and
        duplicate points are ignored (counted out of ``n_points``).
    offsets : array_like of int, shape (k + 1,)
        Cluster ``i`` is ``points[offsets[i]:offsets[i + 1]]``; non-decreasing, from 0 to m.
    method : {"halir_flusser", "mlr"}
        The fit, see the module docstring.

    Returns
    -------
    EllipseFits
    """
    code = _method_code(method)
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise StateError(f"points must have shape (m, 2) [north_m, east_m], actually: {p.shape}")
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    if off.ndim != 1 or off.size < 1 or off[0] != 0 or off[-1] != p.shape[0] or (np.diff(off) < 0).any():
        raise StateError(
            f"offsets must be non-decreasing from 0 to {p.shape[0]} (the number of points), "
            f"actually: {off[:8].tolist()}{'...' if off.size > 8 else ''}"
        )
    return EllipseFits.from_array(_fit_many(p, off, code, _C1))


def fit_ellipse(points: ArrayLike, *, method: str = "halir_flusser") -> EllipseFit:
    """Fit one ellipse to the points of one cluster.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        ``[north_m, east_m]`` [m] (any planar coordinates work).
    method : {"halir_flusser", "mlr"}
        The fit, see the module docstring.

    Returns
    -------
    EllipseFit
        ``ok`` False with ``status`` "too_few_points", "collinear" or "no_ellipse" when
        no ellipse can be fitted; never raises for such data.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    >>> fit = fit_ellipse(np.column_stack([100 + 5 * np.cos(t), 200 + 1.5 * np.sin(t)]))
    >>> fit.status, np.round(fit.centre, 6).tolist(), np.round(fit.semi_axes, 6).tolist()
    ('ok', [100.0, 200.0], [5.0, 1.5])
    """
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise StateError(f"points must have shape (m, 2) [north_m, east_m], actually: {p.shape}")
    out = _fit_many(p, np.array([0, p.shape[0]], np.int64), _method_code(method), _C1)[0]
    code = int(out[0])
    return EllipseFit(
        ok=code == FIT_OK, status=FIT_STATUS[code], centre=out[2:4].copy(),
        semi_axes=out[4:6].copy(), angle_rad=float(out[6]), n_points=int(out[1]),
        arc_coverage_rad=float(out[7]), condition=float(out[8]), residual_m=float(out[9]),
    )
