"""numba kernels of the measurement models (:mod:`asvtwin.tracking.measurement`).

One pass per scan does what took a dozen numpy calls on small arrays: every cluster's
ellipse fit (:func:`asvtwin.tracking.ellipse._fit_many`), its centroid, RMS spread and
visible half-width, the plausibility test of the fit and the line-of-sight covariance.
The AIS kernel turns report columns into position/velocity measurements at the tick
time. The arithmetic is the numpy code's, operation for operation (sums of cluster
points use numpy's pairwise summation, :func:`_pairwise`), so the results equal the
earlier numpy implementation bit for bit or to the last few ulps; the formulas and
their meaning are documented in :mod:`asvtwin.tracking.measurement`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# numba's on-disk cache keys a kernel on its own file only: lidar_model_kernel compiles
# ellipse._fit_many into itself, so a change to ellipse.py must come with a change to this
# file (or a cleared __pycache__), else the cached kernel keeps the old fit (the insertion
# sorts of the fit, 2026-12-01, reached the tracker only through such a change; so did
# the MLR fit's singular normal equations answering "no_ellipse", not ZeroDivisionError).
from asvtwin.tracking.ellipse import _fit_many

__all__: list[str] = []  # internal kernels; the public API is asvtwin.tracking.measurement

_DBL_MAX = np.finfo(np.float64).max
_NO_VELOCITY_VAR = 1.0e6  # [m²/s²]: "no velocity information"


@njit(cache=True)
def _pairwise_block(a, s, n, col):  # type: ignore[no-untyped-def]
    """numpy's pairwise sum of ``a[s:s+n, col]`` for ``n <= 128``: 8 accumulators."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[s + i, col]
        return res
    r0, r1, r2, r3 = a[s, col], a[s + 1, col], a[s + 2, col], a[s + 3, col]
    r4, r5, r6, r7 = a[s + 4, col], a[s + 5, col], a[s + 6, col], a[s + 7, col]
    i = 8
    while i < n - (n % 8):
        r0 += a[s + i, col]
        r1 += a[s + i + 1, col]
        r2 += a[s + i + 2, col]
        r3 += a[s + i + 3, col]
        r4 += a[s + i + 4, col]
        r5 += a[s + i + 5, col]
        r6 += a[s + i + 6, col]
        r7 += a[s + i + 7, col]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[s + i, col]
        i += 1
    return res


@njit(cache=True)
def _pairwise(a, s, n, col):  # type: ignore[no-untyped-def]
    """Sum of ``a[s:s+n, col]`` in numpy's pairwise order (blocks <= 128 split in halves
    rounded to multiples of 8), so it equals ``np.add.reduce`` bit for bit. Iterative with
    an explicit stack: numba's cache mishandles recursive functions."""
    if n <= 128:
        return _pairwise_block(a, s, n, col)
    st_s = np.empty(192, np.int64)
    st_n = np.empty(192, np.int64)
    st_done = np.empty(192, np.bool_)
    vals = np.empty(96)
    top, nv = 0, 0
    st_s[0], st_n[0], st_done[0] = s, n, False
    top = 1
    while top > 0:
        top -= 1
        ss, nn, done = st_s[top], st_n[top], st_done[top]
        if nn <= 128:
            vals[nv] = _pairwise_block(a, ss, nn, col)
            nv += 1
        elif done:  # both halves summed: left + right
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
        else:
            n2 = nn // 2
            n2 -= n2 % 8
            st_s[top], st_n[top], st_done[top] = ss, nn, True
            st_s[top + 1], st_n[top + 1], st_done[top + 1] = ss + n2, nn - n2, False  # right, summed second
            st_s[top + 2], st_n[top + 2], st_done[top + 2] = ss, n2, False  # left, summed first
            top += 3
    return vals[0]


@njit(cache=True)
def _finite_or_zero(v):  # type: ignore[no-untyped-def]
    """``np.nan_to_num`` of one value."""
    if np.isnan(v):
        return 0.0
    if np.isinf(v):
        return _DBL_MAX if v > 0.0 else -_DBL_MAX
    return v


@njit(cache=True)
def lidar_model_kernel(points, offsets, method, C1, origin, prm):  # type: ignore[no-untyped-def]
    """Fits, centres, plausibility and line-of-sight variances of all clusters.

    ``prm`` = [max_semi_axis, min_coverage, fit_floor, needle_ratio, range_var, floor_var,
    depth_gain, coverage_gain, needle_depth_gain, default_half_depth, end_gain,
    bearing_std]. Returns ``fits (k, 10)``, ``z (k, 2)``, ``use (k,)``, ``var_los (k,)``,
    ``cross0 (k,)`` (the cross-range variance without the bearing term) and, when
    ``origin`` is finite, ``R (k, 2, 2)`` (else an empty array: the caller picks an origin
    and calls :func:`los_covariance`).
    """
    max_semi, min_cov, floor, needle, rs2, floor2 = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    dg, cg, ndg, dhd, eg = prm[6], prm[7], prm[8], prm[9], prm[10]
    k = offsets.shape[0] - 1
    fits = _fit_many(points, offsets, method, C1)
    z = np.empty((k, 2))
    use = np.zeros(k, np.bool_)
    var_los = np.empty(k)
    cross0 = np.empty(k)
    big = 1
    for i in range(k):
        big = max(big, offsets[i + 1] - offsets[i])
    d2 = np.empty((big, 1))
    for i in range(k):
        s, n = offsets[i], offsets[i + 1] - offsets[i]
        if n == 0:
            c0 = c1 = ext = half = np.nan
        else:
            # centroid, RMS spread and visible half-width, as np.add/maximum.reduceat
            c0 = (points[s, 0] + _pairwise(points, s + 1, n - 1, 0)) / n
            c1 = (points[s, 1] + _pairwise(points, s + 1, n - 1, 1)) / n
            dmax = 0.0
            for j in range(n):
                e0, e1 = points[s + j, 0] - c0, points[s + j, 1] - c1
                d2[j, 0] = e0 * e0 + e1 * e1
                dmax = d2[j, 0] if j == 0 else max(dmax, d2[j, 0])
            ext = np.sqrt((d2[0, 0] + _pairwise(d2, 1, n - 1, 0)) / n)
            half = np.sqrt(dmax)
        a, b, cov, res = fits[i, 4], fits[i, 5], fits[i, 7], fits[i, 9]
        u = (fits[i, 0] == 0 and a <= max_semi and cov >= min_cov and a <= 2.0 * half + floor
             and b >= needle * a and np.hypot(fits[i, 2] - c0, fits[i, 3] - c1) <= a + floor)
        use[i] = u
        z[i, 0], z[i, 1] = (fits[i, 2], fits[i, 3]) if u else (c0, c1)
        cov, res = _finite_or_zero(cov), _finite_or_zero(res)
        a0, b0 = _finite_or_zero(a), _finite_or_zero(b)
        var_fit = floor2 + res * res
        if u:
            # fitted centre: the unseen depth (~ the semi-minor axis), more for low coverage
            t1 = dg * b0
            t2 = cg * a0 * min(max(1.0 - cov / np.pi, 0.0), 1.0)
            var_los[i] = rs2 + var_fit + t1 * t1 + t2 * t2
            t3 = eg * a0
            cross0[i] = var_fit + t3 * t3
        else:
            # centroid (no usable fit, or a straight face): depth up to a few visible half-widths
            t1 = max(ndg * half, dhd)
            var_los[i] = (rs2 + floor2) + t1 * t1
            cross0[i] = floor2 + ext * ext
    if np.isfinite(origin[0]) and np.isfinite(origin[1]):
        R = los_covariance(z, origin, var_los, cross0, prm[11])
    else:
        R = np.empty((0, 2, 2))
    return fits, z, use, var_los, cross0, R


@njit(cache=True)
def los_covariance(z, origin, var_los, cross0, bearing_std):  # type: ignore[no-untyped-def]
    """``R = U diag(var_los, (r σθ)² + cross0) Uᵀ`` with ``U`` the bearing from ``origin``."""
    k = z.shape[0]
    R = np.empty((k, 2, 2))
    for i in range(k):
        d0, d1 = z[i, 0] - origin[0], z[i, 1] - origin[1]
        r = np.hypot(d0, d1)
        t = r * bearing_std
        vc = t * t + cross0[i]
        vl = var_los[i]
        if r > 1e-9:
            c, s = d0 / max(r, 1e-9), d1 / max(r, 1e-9)
        else:
            c, s = 1.0, 0.0
        R[i, 0, 0] = c * c * vl + s * s * vc
        R[i, 1, 1] = s * s * vl + c * c * vc
        R[i, 0, 1] = R[i, 1, 0] = c * s * (vl - vc)
    return R


@njit(cache=True)
def ais_model_kernel(mmsi, tr, n, e, sog, cog, t_s, prm):  # type: ignore[no-untyped-def]
    """AIS report columns -> (mmsi (k,), z (k, 4), R (k, 4, 4), n_rejected, n_stale) at ``t_s``.

    ``prm`` = [max_age, max_future, position_var, sog_var, cog_var, accel_q]. The latest
    valid report per MMSI is kept (ties: the later row), rows sorted by MMSI.
    """
    max_age, max_future, p2, sv2, cv2, aq = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    m = mmsi.shape[0]
    keep = np.empty(m, np.int64)
    nk, n_rej, n_stale = 0, 0, 0
    for i in range(m):
        good = np.isfinite(tr[i]) and np.isfinite(n[i]) and np.isfinite(e[i]) and mmsi[i] > 0 and not sog[i] < 0.0
        age = t_s - tr[i]
        if not good:
            n_rej += 1
        elif not (age <= max_age and age >= -max_future):
            n_stale += 1
        else:
            keep[nk] = i
            nk += 1
    keep = keep[:nk]
    # lexsort((t, mmsi)): stable by time, then stable by MMSI
    o1 = keep[np.argsort(tr[keep], kind="mergesort")]
    order = o1[np.argsort(mmsi[o1], kind="mergesort")]
    k = 0
    for a in range(nk):
        if a == nk - 1 or mmsi[order[a + 1]] != mmsi[order[a]]:
            order[k] = order[a]
            k += 1
    idx = order[:k]
    z = np.empty((k, 4))
    R = np.zeros((k, 4, 4))
    out_mmsi = np.empty(k, np.int64)
    for j in range(k):
        i = idx[j]
        out_mmsi[j] = mmsi[i]
        has_v = np.isfinite(sog[i]) and np.isfinite(cog[i])
        s, c = (sog[i], cog[i]) if has_v else (0.0, 0.0)
        cc, sc = np.cos(c), np.sin(c)
        vn, ve = s * cc, s * sc
        if has_v:
            # Rv = J diag(σ_sog², σ_cog²) Jᵀ, J = d(vn, ve)/d(sog, cog), kept regular at SOG = 0
            j00, j01, j10, j11 = cc, -s * sc, sc, s * cc
            a00, a01, a10, a11 = j00 * sv2, j01 * cv2, j10 * sv2, j11 * cv2
            reg = sv2 * 1e-2
            rv00 = a00 * j00 + a01 * j01 + reg
            rv01 = a00 * j10 + a01 * j11
            rv10 = a10 * j00 + a11 * j01
            rv11 = a10 * j10 + a11 * j11 + reg
            hv = 1.0
        else:
            rv00, rv01, rv10, rv11, hv = _NO_VELOCITY_VAR, 0.0, 0.0, _NO_VELOCITY_VAR, 0.0
        dt = t_s - tr[i]
        z[j, 0], z[j, 1], z[j, 2], z[j, 3] = n[i] + vn * dt, e[i] + ve * dt, vn, ve
        # aging by dt: position picks up the velocity uncertainty and the acceleration noise
        dt2 = dt * dt
        q3 = aq * np.abs(dt) ** 3.0 / 3.0
        q1 = aq * np.abs(dt)
        R[j, 0, 0] = p2 + hv * rv00 * dt2 + q3
        R[j, 0, 1] = 0.0 + hv * rv01 * dt2 + 0.0
        R[j, 1, 0] = 0.0 + hv * rv10 * dt2 + 0.0
        R[j, 1, 1] = p2 + hv * rv11 * dt2 + q3
        R[j, 2, 2], R[j, 2, 3], R[j, 3, 2], R[j, 3, 3] = rv00 + q1, rv01 + 0.0, rv10 + 0.0, rv11 + q1
        R[j, 0, 2], R[j, 0, 3], R[j, 1, 2], R[j, 1, 3] = hv * rv00 * dt, hv * rv01 * dt, hv * rv10 * dt, hv * rv11 * dt
        R[j, 2, 0], R[j, 3, 0], R[j, 2, 1], R[j, 3, 1] = R[j, 0, 2], R[j, 0, 3], R[j, 1, 2], R[j, 1, 3]
    return out_mmsi, z, R, n_rej, n_stale
