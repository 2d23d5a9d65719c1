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
