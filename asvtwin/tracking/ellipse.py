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

from asvtwin.errors import ParameterError, StateError
from asvtwin.tracking.smallmat import inv_small, mm, mv

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

_F8 = NDArray[np.float64]

FIT_OK = 0
FIT_TOO_FEW_POINTS = 1
FIT_COLLINEAR = 2
FIT_NO_ELLIPSE = 3
#: Status code -> name.
FIT_STATUS = ("ok", "too_few_points", "collinear", "no_ellipse")
#: Fitting methods: name -> kernel code.
METHODS = {"halir_flusser": 0, "mlr": 1}

_C1 = np.array([[0.0, 0.0, 2.0], [0.0, -1.0, 0.0], [2.0, 0.0, 0.0]])


@njit(cache=True)
def _distinct_finite(p):  # type: ignore[no-untyped-def]
    """Rows of p that are finite, exact duplicates removed (first kept)."""
    n = p.shape[0]
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


@njit(cache=True)
def _inv3(A):  # type: ignore[no-untyped-def]
    """Inverse of a 3x3 matrix by its adjugate (caller guarantees it is regular)."""
    B = np.empty((3, 3))
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
    return B / det


@njit(cache=True)
def _top_eig_sym3(G):  # type: ignore[no-untyped-def]
    """Largest eigenvalue of a symmetric 3x3 matrix and a unit eigenvector (closed form).

    Eigenvalues by the trigonometric method (Smith 1961); the eigenvector is the largest
    cross product of two rows of ``G - mu I`` (orthogonal to both, so in its null space).
    """
    p1 = G[0, 1] ** 2 + G[0, 2] ** 2 + G[1, 2] ** 2
    q = (G[0, 0] + G[1, 1] + G[2, 2]) / 3.0
    p2 = (G[0, 0] - q) ** 2 + (G[1, 1] - q) ** 2 + (G[2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    v = np.zeros(3)
    if p == 0.0:
        v[0] = 1.0
        return q, v
    B = (G - q * np.eye(3)) / p
    r = 0.5 * (B[0, 0] * (B[1, 1] * B[2, 2] - B[1, 2] * B[2, 1])
               - B[0, 1] * (B[1, 0] * B[2, 2] - B[1, 2] * B[2, 0])
               + B[0, 2] * (B[1, 0] * B[2, 1] - B[1, 1] * B[2, 0]))
    r = min(max(r, -1.0), 1.0)
    mu = q + 2.0 * p * np.cos(np.arccos(r) / 3.0)
    A = G - mu * np.eye(3)
    best = -1.0
    for i, j in ((0, 1), (0, 2), (1, 2)):
        cx = A[i, 1] * A[j, 2] - A[i, 2] * A[j, 1]
        cy = A[i, 2] * A[j, 0] - A[i, 0] * A[j, 2]
        cz = A[i, 0] * A[j, 1] - A[i, 1] * A[j, 0]
        nn = cx * cx + cy * cy + cz * cz
        if nn > best:
            best = nn
            v[0], v[1], v[2] = cx, cy, cz
    v /= np.sqrt(best) if best > 0.0 else 1.0
    return mu, v


@njit(cache=True)
def _chol3(A):  # type: ignore[no-untyped-def]
    """Cholesky factor of a 3x3 symmetric matrix (zero diagonal entry when not PD)."""
    L = np.zeros((3, 3))
    for i in range(3):
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if acc <= 0.0:
                    return L
                L[i, i] = np.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return L


@njit(cache=True)
def _inv_lower3(L):  # type: ignore[no-untyped-def]
    """Inverse of a 3x3 lower-triangular matrix by forward substitution."""
    Li = np.zeros((3, 3))
    for c in range(3):
        for i in range(c, 3):
            acc = 1.0 if i == c else 0.0
            for k in range(c, i):
                acc -= L[i, k] * Li[k, c]
            Li[i, c] = acc / L[i, i]
    return Li


@njit(cache=True)
def _fit_one(p, method, C1, out):  # type: ignore[no-untyped-def]
    """Fit one cluster; writes [status, n, cn, ce, a_major, b_minor, angle, coverage, cond, resid]."""
    q = _distinct_finite(p)
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
    x = np.empty(n)
    y = np.empty(n)
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
    # moments m[i, j] = sum x^i y^j, i + j <= 4, in one pass (no design matrix)
    m = np.zeros((5, 5))
    for k in range(n):
        xk, yk = x[k], y[k]
        px = 1.0
        for i in range(5):
            py = px
            for j in range(5 - i):
                m[i, j] += py
                py *= yk
            px *= xk
    # S1 = D1'D1, S2 = D1'D2, S3 = D2'D2 with D1 = [x^2, xy, y^2], D2 = [x, y, 1]
    S1 = np.array([[m[4, 0], m[3, 1], m[2, 2]],
                   [m[3, 1], m[2, 2], m[1, 3]],
                   [m[2, 2], m[1, 3], m[0, 4]]])
    S2 = np.array([[m[3, 0], m[2, 1], m[2, 0]],
                   [m[2, 1], m[1, 2], m[1, 1]],
                   [m[1, 2], m[0, 3], m[0, 2]]])
    S3 = np.array([[m[2, 0], m[1, 1], m[1, 0]],
                   [m[1, 1], m[0, 2], m[0, 1]],
                   [m[1, 0], m[0, 1], m[0, 0]]])
    coef = np.zeros(6)
    if method == 0:
        Tm = -mm(_inv3(S3), np.ascontiguousarray(S2.T))  # a2 = Tm a1
        T = S1 + mm(S2, Tm)  # reduced scatter, symmetric PSD
        T = 0.5 * (T + T.T)
        T += (1e-13 * np.trace(T) + 1e-300) * np.eye(3)  # exact conics make T singular
        L = _chol3(T)
        if L[0, 0] <= 0.0 or L[1, 1] <= 0.0 or L[2, 2] <= 0.0:
            out[0] = 3
            return
        Li = _inv_lower3(L)
        G = mm(mm(Li, C1), np.ascontiguousarray(Li.T))  # L^-1 C1 L^-T: one positive eigenvalue
        G = 0.5 * (G + G.T)
        mu, y1 = _top_eig_sym3(G)
        if not mu > 0.0:  # no eigenvector with 4ac - b^2 > 0
            out[0] = 3
            return
        a1 = mv(np.ascontiguousarray(Li.T), y1)
        a2 = mv(Tm, a1)
        coef[:3] = a1
        coef[3:] = a2
    else:
        # normal equations of [x^2, xy, y^2, x, y] w = 1 (MLR, f = -1)
        N = np.empty((5, 5))
        N[:3, :3] = S1
        N[:3, 3:] = S2[:, :2]
        N[3:, :3] = S2[:, :2].T
        N[3:, 3:] = S3[:2, :2]
        rhs = np.array([m[2, 0], m[1, 1], m[0, 2], m[1, 0], m[0, 1]])
        coef[:5] = mv(inv_small(N), rhs)
        coef[5] = -1.0
    a, b, c, d, e, f = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
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
    theta = 0.5 * np.arctan2(b, a - c) + 0.5 * np.pi  # direction of the smaller eigenvalue
    theta = (theta + 0.5 * np.pi) % np.pi - 0.5 * np.pi
    # quality: arc coverage about the fitted centre (in the ellipse's own parameter),
    # RMS Sampson distance
    ct, st = np.cos(theta), np.sin(theta)
    ang = np.empty(n)
    samp = 0.0
    for k in range(n):
        dx, dy = x[k] - x0, y[k] - y0
        ang[k] = np.arctan2((-dx * st + dy * ct) / ax_minor, (dx * ct + dy * st) / ax_major)
        F = a * x[k] * x[k] + b * x[k] * y[k] + c * y[k] * y[k] + d * x[k] + e * y[k] + f
        gx = 2.0 * a * x[k] + b * y[k] + d
        gy = b * x[k] + 2.0 * c * y[k] + e
        samp += F * F / max(gx * gx + gy * gy, 1e-300)
    ang.sort()
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
    for i in range(k):
        _fit_one(points[offsets[i]:offsets[i + 1]], method, C1, out[i])
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
    out = _fit_many(p, off, code, _C1)
    return EllipseFits(
        status=out[:, 0].astype(np.int64),
        centre=out[:, 2:4].copy(),
        semi_axes=out[:, 4:6].copy(),
        angle_rad=out[:, 6].copy(),
        n_points=out[:, 1].astype(np.int64),
        arc_coverage_rad=out[:, 7].copy(),
        condition=out[:, 8].copy(),
        residual_m=out[:, 9].copy(),
    )


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
