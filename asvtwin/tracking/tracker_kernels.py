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
from asvtwin.tracking.fusion import _product_row_h
from asvtwin.tracking.hull_model import _hull_box_one
from asvtwin.tracking.kalman import _update_row_h

__all__: list[str] = []  # internal kernels


@njit(cache=True)
def _initial_row(z, R, i, x, P, G, v2):  # type: ignore[no-untyped-def]
    """:meth:`Tracker._initial_state` of track row ``i`` from ``z[i]``, ``R[i]`` (position
    only, or position and velocity) into ``x[i]``, ``P[i]``; ``G[i] = I``."""
    for r in range(4):
        x[i, r] = 0.0
        for c in range(4):
            P[i, r, c] = 0.0
            G[i, r, c] = 1.0 if r == c else 0.0
    x[i, 0], x[i, 1] = z[i, 0], z[i, 1]
    for r in range(2):
        for c in range(2):
            P[i, r, c] = R[i, r, c]
    if z.shape[1] == 4 and not R[i, 2, 2] > v2:  # a velocity that is known
        x[i, 2], x[i, 3] = z[i, 2], z[i, 3]
        for r in range(2):
            for c in range(2):
                P[i, r + 2, c + 2] = R[i, r + 2, c + 2]
                P[i, r, c + 2] = R[i, r, c + 2]
                P[i, r + 2, c] = R[i, r + 2, c]
    else:
        P[i, 2, 2] = v2
        P[i, 3, 3] = v2


@njit(cache=True, inline="always")
def _take_row(x, P, G, i, xs, Ps, K, m):  # type: ignore[no-untyped-def]
    """Row ``i`` of a per-sensor filter from an update's ``xs[0]``, ``Ps[0]``, and its gain
    mapped to the state, ``G = K H`` for ``H = [I_m 0]`` (the sum ``0.0 + K`` as the
    generic product has it)."""
    for r in range(4):
        x[i, r] = xs[0, r]
        for c in range(4):
            P[i, r, c] = Ps[0, r, c]
            G[i, r, c] = 0.0 + K[0, r, c] if c < m else 0.0


@njit(cache=True, error_model="numpy")
def update_and_fuse(x, P, xL, PL, GL, hasL, tL, gotL, zL, RL, xA, PA, GA, hasA, tA, gotA, zA, RA, t, v2,
                    product):  # type: ignore[no-untyped-def]
    """The tick's updater in one pass over the tracks, in place: each per-sensor filter
    that got a measurement is updated (Joseph form, ``G = K H``: the arithmetic of the
    generic row, :func:`~asvtwin.tracking.kalman._update_row_h`) or started (:func:`_initial_row`) and stamped ``t``; with ``product`` the
    fused estimate ``x``, ``P`` is the product of its prediction and the measurements
    (:func:`asvtwin.tracking.fusion._product_kernel`'s arithmetic, specialised for the two
    ``H``: :func:`~asvtwin.tracking.fusion._product_row_h`): LiDAR measures the position
    (:data:`~asvtwin.tracking.kalman.H_POSITION`), AIS position and velocity
    (:data:`~asvtwin.tracking.kalman.H_FULL`).

    ``error_model="numpy"``: a division by zero (a singular matrix, which the covariances
    here never are) gives inf/NaN, and the track is deleted as non-finite
    (:func:`bookkeeping`), instead of raising. Without the zero checks numba prunes most
    of the reference counting of the inlined rows' array arguments (~25 % of the kernel);
    the arithmetic is the same."""
    n = x.shape[0]
    xs, Ps = np.empty((1, 4)), np.empty((1, 4, 4))
    A, B = np.empty((4, 4)), np.empty((4, 4))
    KL, SL, SiL, wL = np.empty((1, 4, 2)), np.empty((2, 2)), np.empty((2, 2)), np.empty((2, 2))
    KA, SA, SiA, wA = np.empty((1, 4, 4)), np.empty((4, 4)), np.empty((4, 4)), np.empty((4, 4))
    Y, Pn, w4, yv = np.empty((4, 4)), np.empty((4, 4)), np.empty((4, 4)), np.empty(4)
    for i in range(n):
        # LiDAR (position, H_POSITION) and AIS (position and velocity, H_FULL) filters
        if gotL[i]:
            if hasL[i]:
                _update_row_h(xL, PL, zL, RL, 2, i, xs, Ps, KL, SL, SiL, wL, A, B)
                _take_row(xL, PL, GL, i, xs, Ps, KL, 2)
            else:
                _initial_row(zL, RL, i, xL, PL, GL, v2)
                hasL[i] = True
            tL[i] = t
        if gotA[i]:
            if hasA[i]:
                _update_row_h(xA, PA, zA, RA, 4, i, xs, Ps, KA, SA, SiA, wA, A, B)
                _take_row(xA, PA, GA, i, xs, Ps, KA, 4)
            else:
                _initial_row(zA, RA, i, xA, PA, GA, v2)
                hasA[i] = True
            tA[i] = t
        # in place: the row's prior is read before its posterior is written; a row no sensor
        # measured is left alone (case 4: N(x, P)), without entering the inlined row (its
        # array arguments cost ~0.2 µs of reference counting per row)
        if product and (gotL[i] or gotA[i]):
            _product_row_h(x, P, zL, RL, gotL, zA, RA, gotA, i, x, P, Y, Pn, w4, yv, SiL, wL, SiA, wA)


@njit(cache=True)
def bookkeeping(x, P, gotL, gotA, hist, age, n_ais, t_last, axes, fit_axes, confirmed, mmsi, t, mask_n, confirm_m,
                confirm_n, check_velocity, velocity_var, max_coast_s, max_coast_ais_s, max_position_std):  # type: ignore[no-untyped-def]
    """After the updater, in one pass, in place: hit history, age, AIS count, time of the
    last update, smoothed semi-axes, M-of-N confirmation (with the settled-velocity rule
    when ``check_velocity``), and the deleter's tests but the land one. Returns the number
    of newly confirmed tracks, the tracks to delete (land aside), the non-finite ones and
    the largest position-covariance eigenvalue of each (the land test's)."""
    n = x.shape[0]
    dead = np.zeros(n, np.bool_)
    bad = np.zeros(n, np.bool_)
    lmax = np.empty(n)
    newly = 0
    for i in range(n):
        hit = gotL[i] or gotA[i]
        h = ((hist[i] << 1) | (1 if hit else 0)) & mask_n
        hist[i] = h
        age[i] += 1
        if gotA[i]:
            n_ais[i] += 1
        if hit:
            t_last[i] = t
        f0, f1 = fit_axes[i, 0], fit_axes[i, 1]
        if not np.isnan(f0):
            a0, a1 = axes[i, 0], axes[i, 1]
            axes[i, 0] = f0 if np.isnan(a0) else 0.7 * a0 + 0.3 * f0
            axes[i, 1] = f1 if np.isnan(a1) else 0.7 * a1 + 0.3 * f1
        hits = 0
        while h:
            hits += h & 1
            h >>= 1
        # confirmation
        settled = True
        if check_velocity:
            settled = mmsi[i] >= 0
            if not settled:
                tr = P[i, 2, 2] + P[i, 3, 3]
                det = P[i, 2, 2] * P[i, 3, 3] - P[i, 2, 3] * P[i, 2, 3]
                v = 0.25 * tr * tr - det
                settled = 0.5 * tr + np.sqrt(v if (v > 0.0 or np.isnan(v)) else 0.0) <= velocity_var
        if not confirmed[i] and ((hits >= confirm_m and settled) or n_ais[i] >= 2):
            confirmed[i] = True
            newly += 1
        # deleter (the land test is the caller's)
        window = min(age[i], confirm_n)
        d = (not confirmed[i]) and mmsi[i] < 0 and window - hits > confirm_n - confirm_m
        coast = max_coast_ais_s if mmsi[i] >= 0 else max_coast_s
        d = d or (t - t_last[i]) > coast
        tr = P[i, 0, 0] + P[i, 1, 1]
        det = P[i, 0, 0] * P[i, 1, 1] - P[i, 0, 1] * P[i, 0, 1]
        v = 0.25 * tr * tr - det
        lm = 0.5 * tr + np.sqrt(v if (v > 0.0 or np.isnan(v)) else 0.0)
        lmax[i] = lm
        d = d or np.sqrt(lm) > max_position_std
        fin = True
        for r in range(4):
            fin = fin and np.isfinite(x[i, r])
            for c in range(4):
                fin = fin and np.isfinite(P[i, r, c])
        bad[i] = not fin
        dead[i] = d or not fin
    return newly, dead, bad, lmax


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
def near_tracks(z, R, x, P, xA, PA, mmsi, hasA, tA, t, window, axes, min_sep, gamma):  # type: ignore[no-untyped-def]
    """Which measurements ``z (k, 2)`` lie near a track: closer than
    ``max(min_sep, semi-major + 10 m)`` or inside its χ² gate (the arithmetic of
    :func:`asvtwin.tracking.association.gated_costs`). A track tied to an MMSI
    (``mmsi >= 0``) with an AIS-only filter updated within ``window`` of ``t`` stands at
    that filter (``xA``, ``PA``), others at ``x``, ``P``; ``axes (n, 2)``: the semi-axes."""
    k, n = z.shape[0], x.shape[0]
    out = np.zeros(k, np.bool_)
    fresh = np.empty(n, np.bool_)
    for i in range(n):
        fresh[i] = mmsi[i] >= 0 and hasA[i] and t - tA[i] <= window
    for j in range(k):
        for i in range(n):
            xs, Ps = (xA, PA) if fresh[i] else (x, P)
            dn, de = z[j, 0] - xs[i, 0], z[j, 1] - xs[i, 1]
            ax = axes[i, 0]
            sep = max(min_sep, (0.0 if np.isnan(ax) else ax) + 10.0)
            if np.hypot(dn, de) < sep:
                out[j] = True
                break
            a = Ps[i, 0, 0] + R[j, 0, 0]
            b = Ps[i, 0, 1] + R[j, 0, 1]
            c = Ps[i, 1, 1] + R[j, 1, 1]
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
def tied_reports(am_mmsi, am_z, am_R, mmsi, x, P):  # type: ignore[no-untyped-def]
    """The track row tied to each AIS report's MMSI (-1: none; untied tracks hold -1,
    never a valid MMSI, and MMSIs are unique), the tied reports ``tj`` and their tracks
    ``ti``, and each tied report's squared position distance to its track
    (:func:`position_mahalanobis`' arithmetic)."""
    k, n = am_mmsi.shape[0], mmsi.shape[0]
    tied = np.full(k, -1, np.int64)
    if n:
        order = np.argsort(mmsi)
        srt = mmsi[order]
        pos = np.searchsorted(srt, am_mmsi)
        for j in range(k):
            p = min(pos[j], n - 1)
            if srt[p] == am_mmsi[j]:
                tied[j] = order[p]
    cnt = 0
    for j in range(k):
        if tied[j] >= 0:
            cnt += 1
    tj = np.empty(cnt, np.int64)
    ti = np.empty(cnt, np.int64)
    d2 = np.empty(cnt)
    q = 0
    for j in range(k):
        i = tied[j]
        if i < 0:
            continue
        tj[q], ti[q] = j, i
        a = P[i, 0, 0] + am_R[j, 0, 0]
        b = P[i, 0, 1] + am_R[j, 0, 1]
        c = P[i, 1, 1] + am_R[j, 1, 1]
        det = a * c - b * b
        dn, de = am_z[j, 0] - x[i, 0], am_z[j, 1] - x[i, 1]
        d2[q] = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det if det > 0.0 else np.inf
        q += 1
    return tied, tj, ti, d2


@njit(cache=True)
def take_tied(ti, tj, ok, am_z, am_R, gotA, zA, RA, ais_rej):  # type: ignore[no-untyped-def]
    """Tied AIS reports ``tj`` that passed their track's gate (``ok``) go to their track
    ``ti`` (``zA``, ``RA``, ``gotA``; the rejection count reset); the others count a
    rejection."""
    for q in range(ti.shape[0]):
        i, j = ti[q], tj[q]
        if ok[q]:
            gotA[i] = True
            for r in range(4):
                zA[i, r] = am_z[j, r]
                for c in range(4):
                    RA[i, r, c] = am_R[j, r, c]
            ais_rej[i] = 0
        else:
            ais_rej[i] += 1


@njit(cache=True)
def coincident(x, P, mmsi, gamma):  # type: ignore[no-untyped-def]
    """Pairs (i < j) whose position and velocity differences are within the χ² gate, in
    the order of the double loop over ``i < j``. Two identified vessels (``mmsi >= 0``)
    are never one: a tied ``i`` is tested only against the untied ``j > i`` (with most
    tracks tied, the n²/2 pairs were nearly all skipped one by one)."""
    n = x.shape[0]
    untied = np.empty(n, np.int64)
    nu = 0
    for i in range(n):
        if mmsi[i] < 0:
            untied[nu] = i
            nu += 1
    out_i, out_j = [], []
    u0 = 0  # the first untied row after i
    for i in range(n):
        while u0 < nu and untied[u0] <= i:
            u0 += 1
        tied = mmsi[i] >= 0
        for q in range(nu - u0 if tied else n - i - 1):
            j = untied[u0 + q] if tied else i + 1 + q
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
                      min_speed2, max_course_var, gamma, forbidden, min_returns, dims, mmsi, hasA, tA, xA, PA, t,
                      max_coast_ais, gamma_id, sight):  # type: ignore[no-untyped-def]
    """The measurement of every gated (track, cluster) pair (``cost < forbidden``, in
    ``np.nonzero`` order), measured again with the track's course where it has one
    (speed² ≥ ``min_speed2``, course variance ≤ ``max_course_var``; clusters of at least
    ``min_returns`` returns) and re-gated with it;
    ``cost`` is updated in place (:meth:`asvtwin.tracking.tracker.Tracker._pair_measurements`
    says why). ``dims (n, 2)``: each track's known length and beam [m] (NaN: unknown),
    used with its course; ``sight (k, 8)``: each cluster's line of sight
    (:func:`~asvtwin.tracking.hull_model._sight`, from the scan's axis-free pass).

    Then the AIS identity gate (:meth:`asvtwin.tracking.tracker.Tracker._ais_identity_gate`
    says why): a pair of a track tied to an MMSI (``mmsi >= 0``) with an AIS-only filter
    (``hasA``) updated within ``max_coast_ais`` of ``t`` stays allowed only when its
    measurement lies within ``gamma_id`` of that filter's position (``xA``, ``PA``; the
    arithmetic of :func:`position_mahalanobis`). Returns ``ti, cj, z, R (single scan),
    R_update, with_course`` and the number of pairs the identity gate vetoed."""
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
    vetoed = 0
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
                                  zp, Rpu, ext, Rp, p, dims[i, 0], dims[i, 1], sight[j])
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
            if mmsi[i] >= 0 and hasA[i] and t - tA[i] <= max_coast_ais:  # the identity gate
                a = PA[i, 0, 0] + Rp[p, 0, 0]
                b = PA[i, 0, 1] + Rp[p, 0, 1]
                c = PA[i, 1, 1] + Rp[p, 1, 1]
                det = a * c - b * b
                dn, de = zp[p, 0] - xA[i, 0], zp[p, 1] - xA[i, 1]
                d2 = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det if det > 0.0 else np.inf
                if d2 > gamma_id and cost[i, j] < forbidden:
                    cost[i, j] = forbidden
                    vetoed += 1
            p += 1
    return ti, cj, zp, Rp, Rpu, wc, vetoed


@njit(cache=True)
def take_assigned(rows, cols, ti, cj, zp, Rpu, wc, x, P, used_fit, coverage, semi_axes, n_clusters, zL, RL, gotL,
                  fit_axes):  # type: ignore[no-untyped-def]
    """The LiDAR assignment's bookkeeping, in place: track ``rows[q]`` gets the measurement
    of its pair with cluster ``cols[q]`` (``zL``, ``RL``: the pair's ``z`` and
    ``R_update``; ``gotL``), and the fit's semi-axes when the fit was used and covers at
    least half a turn (``fit_axes``). The pairs ``ti``, ``cj`` are in ``np.nonzero``
    order. Returns the position NIS of each assignment (:func:`position_mahalanobis`'
    arithmetic), how many pairs were measured with the course, and which clusters are
    left free."""
    nq = rows.shape[0]
    nis = np.empty(nq)
    free = np.ones(n_clusters, np.bool_)
    n = x.shape[0]
    start = np.zeros(n + 1, np.int64)  # pairs of track i: start[i]..start[i + 1] - 1
    for p in range(ti.shape[0]):
        start[ti[p] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    n_course = 0
    for q in range(nq):
        i, j = rows[q], cols[q]
        p = start[i]
        while cj[p] != j:
            p += 1
        gotL[i] = True
        zL[i, 0], zL[i, 1] = zp[p, 0], zp[p, 1]
        for r in range(2):
            for c in range(2):
                RL[i, r, c] = Rpu[p, r, c]
        if wc[p]:
            n_course += 1
        a = P[i, 0, 0] + RL[i, 0, 0]
        b = P[i, 0, 1] + RL[i, 0, 1]
        c = P[i, 1, 1] + RL[i, 1, 1]
        det = a * c - b * b
        dn, de = zL[i, 0] - x[i, 0], zL[i, 1] - x[i, 1]
        nis[q] = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det if det > 0.0 else np.inf
        if used_fit[j] and coverage[j] >= 0.5 * np.pi:
            fit_axes[i, 0], fit_axes[i, 1] = semi_axes[j, 0], semi_axes[j, 1]
        free[j] = False
    return nis, n_course, free
