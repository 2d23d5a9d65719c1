"""numba kernels of :class:`asvtwin.tracking.tracker.Tracker`'s per-tick bookkeeping.

With 200 tracks, numpy calls on the small per-track arrays (gather, update, scatter,
gate, test) cost more in call overhead than in arithmetic; these kernels do each step
in one pass over the tracks. The algebra is that of :mod:`asvtwin.tracking.kalman`
(the same Joseph-form kernel) and :mod:`asvtwin.tracking.association` (the same gate
arithmetic), so decisions and numbers are unchanged.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# numba's on-disk cache keys a kernel on its own file only: pair_measurements below
# compiles _hull_box_one into itself, so a change to hull_model.py must come with a change
# to this file (or a cleared __pycache__), else the cached kernel keeps the old model
# (it did once, silently, while the range-limit model was written).
from asvtwin.tracking.hull_model import _hull_box_one
from asvtwin.tracking.kalman import _update_kernel

__all__: list[str] = []  # internal kernels


@njit(cache=True)
def update_rows(x, P, G, rows, z, R, H):  # type: ignore[no-untyped-def]
    """Kalman update (Joseph form) of ``rows`` in place; ``G = K H`` of those rows.

    ``z``/``R`` are indexed by track row like ``x``/``P``.
    """
    k, m = rows.shape[0], H.shape[0]
    xs, Ps = np.empty((k, 4)), np.empty((k, 4, 4))
    zs, Rs = np.empty((k, m)), np.empty((k, m, m))
    for a in range(k):
        i = rows[a]
        xs[a] = x[i]
        Ps[a] = P[i]
        zs[a] = z[i]
        Rs[a] = R[i]
    xn, Pn, K, _, _, _ = _update_kernel(xs, Ps, zs, Rs, H)
    for a in range(k):
        i = rows[a]
        x[i] = xn[a]
        P[i] = Pn[a]
        for r in range(4):
            for c in range(4):
                acc = 0.0
                for l in range(m):
                    acc += K[a, r, l] * H[l, c]
                G[i, r, c] = acc


@njit(cache=True)
def position_mahalanobis(dz, P, R):  # type: ignore[no-untyped-def]
    """Squared Mahalanobis distances of position residuals ``dz (k, 2)`` with ``S = P + R``
    (2×2 blocks of ``P (k, 2, 2)``, ``R (k, 2, 2)``); ``inf`` where ``S`` is not PD."""
    k = dz.shape[0]
    out = np.empty(k)
    for i in range(k):
        a = P[i, 0, 0] + R[i, 0, 0]
        b = P[i, 0, 1] + R[i, 0, 1]
        c = P[i, 1, 1] + R[i, 1, 1]
        det = a * c - b * b
        dn, de = dz[i, 0], dz[i, 1]
        out[i] = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det if det > 0.0 else np.inf
    return out


@njit(cache=True)
def near_tracks(z, R, x, P, axes_major, min_sep, gamma):  # type: ignore[no-untyped-def]
    """Which measurements ``z (k, 2)`` lie near a track: closer than
    ``max(min_sep, semi-major + 10 m)`` or inside its χ² gate (the arithmetic of
    :func:`asvtwin.tracking.association.gated_costs`)."""
    k, n = z.shape[0], x.shape[0]
    out = np.zeros(k, np.bool_)
    for j in range(k):
        for i in range(n):
            dn, de = z[j, 0] - x[i, 0], z[j, 1] - x[i, 1]
            ax = axes_major[i]
            sep = max(min_sep, (0.0 if np.isnan(ax) else ax) + 10.0)
            if np.hypot(dn, de) < sep:
                out[j] = True
                break
            a = P[i, 0, 0] + R[j, 0, 0]
            b = P[i, 0, 1] + R[j, 0, 1]
            c = P[i, 1, 1] + R[j, 1, 1]
            if dn * dn + de * de > gamma * (a + c):
                continue
            det = a * c - b * b
            if not det > 0.0:
                continue
            if (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det <= gamma:
                out[j] = True
                break
    return out


@njit(cache=True)
def coincident(x, P, mmsi, gamma):  # type: ignore[no-untyped-def]
    """Pairs (i < j) whose position and velocity differences are within the χ² gate."""
    n = x.shape[0]
    out_i, out_j = [], []
    for i in range(n):
        for j in range(i + 1, n):
            if mmsi[i] >= 0 and mmsi[j] >= 0:
                continue  # two identified vessels are never one
            ok = True
            for o in (0, 2):  # position block, then velocity block
                a = P[i, o, o] + P[j, o, o]
                b = P[i, o, o + 1] + P[j, o, o + 1]
                c = P[i, o + 1, o + 1] + P[j, o + 1, o + 1]
                dn, de = x[i, o] - x[j, o], x[i, o + 1] - x[j, o + 1]
                det = a * c - b * b
                if not (det > 0.0 and (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det <= gamma):
                    ok = False
                    break
            if ok:
                out_i.append(i)
                out_j.append(j)
    return np.array(out_i, np.int64), np.array(out_j, np.int64)


@njit(cache=True)
def pair_measurements(cost, x, P, z0, R0, Ru0, use_course, points, offsets, origin, shadow, prm, heading_floor,
                      min_speed2, max_course_var, gamma, forbidden, min_returns, dims):  # type: ignore[no-untyped-def]
    """The measurement of every gated (track, cluster) pair (``cost < forbidden``, in
    ``np.nonzero`` order), measured again with the track's course where it has one
    (speed² ≥ ``min_speed2``, course variance ≤ ``max_course_var``; clusters of at least
    ``min_returns`` returns) and re-gated with it;
    ``cost`` is updated in place (:meth:`asvtwin.tracking.tracker.Tracker._pair_measurements`
    says why). ``dims (n, 2)``: each track's known length and beam [m] (NaN: unknown),
    used with its course. Returns ``ti, cj, z, R (single scan), R_update, with_course``."""
    n, k = cost.shape
    cnt = 0
    for i in range(n):
        for j in range(k):
            if cost[i, j] < forbidden:
                cnt += 1
    ti = np.empty(cnt, np.int64)
    cj = np.empty(cnt, np.int64)
    zp = np.empty((cnt, 2))
    Rp = np.empty((cnt, 2, 2))
    Rpu = np.empty((cnt, 2, 2))
    ext = np.empty((cnt, 2))
    wc = np.zeros(cnt, np.bool_)
    p = 0
    for i in range(n):
        for j in range(k):
            if not cost[i, j] < forbidden:
                continue
            ti[p], cj[p] = i, j
            zp[p] = z0[j]
            Rp[p] = R0[j]
            Rpu[p] = Ru0[j]
            if use_course and offsets[j + 1] - offsets[j] >= min_returns:
                v0, v1 = x[i, 2], x[i, 3]
                sp2 = v0 * v0 + v1 * v1
                # var ψ = (v_e² P_nn − 2 v_n v_e P_ne + v_n² P_ee) / |v|⁴ (course of the CV velocity)
                var = v1 * v1 * P[i, 2, 2] - 2.0 * v0 * v1 * P[i, 2, 3] + v0 * v0 * P[i, 3, 3]
                var = var / max(sp2, 1e-12) ** 2
                if sp2 >= min_speed2 and var <= max_course_var:
                    _hull_box_one(points, offsets[j], offsets[j + 1] - offsets[j], origin[0], origin[1],
                                  np.arctan2(v1, v0), max(np.sqrt(var), heading_floor), shadow, j, prm,
                                  zp, Rpu, ext, Rp, p, dims[i, 0], dims[i, 1])
                    wc[p] = True
                    # the pair's gate and cost with its own measurement (gated_costs' arithmetic)
                    a = P[i, 0, 0] + Rp[p, 0, 0]
                    b = P[i, 0, 1] + Rp[p, 0, 1]
                    c = P[i, 1, 1] + Rp[p, 1, 1]
                    det = a * c - b * b
                    dn, de = zp[p, 0] - x[i, 0], zp[p, 1] - x[i, 1]
                    d2 = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det if det > 0.0 else np.inf
                    det2 = a * c - b * (P[i, 1, 0] + Rp[p, 1, 0])
                    cost[i, j] = d2 + np.log(det2) if d2 <= gamma else forbidden
            p += 1
    return ti, cj, zp, Rp, Rpu, wc
