r"""What a LiDAR sees of a hull: the centre of a vessel from the near side of its outline.

A 2-D LiDAR sees only the faces of a hull that face it, sampled at its angular step. The
centre of a vessel is therefore *not* the centre of an ellipse fitted to the returns (that
sits towards the sensor: the unseen half is missing), nor the centroid. This model works
in the hull frame: ``h`` along the hull axis (the heading, when the track knows it; else
the orientation of the returns' smallest bounding rectangle), ``n`` across it. A hull
(rectangle, pointed bow, ellipse) fills the box ``[s_c ± L/2] × [t_c ± B/2]`` in that
frame, and the returns give the visible extents ``[s_min, s_max] × [t_min, t_max]``:

- the extreme **near** the sensor along each axis is seen up to the sampling gap at a
  corner or a pointed bow, :math:`G_{near} \sim U[0, \min(\delta, k_{tip} d)]`;
- the **far** extreme is seen only as the end of a face running away from the sensor,
  sampled every :math:`\delta = d / \sin\beta` along that face (``d = r Δφ`` the ray
  spacing at range ``r``, ``β`` the angle between the line of sight and the face), so
  :math:`G_{far} \sim U[g_{lo}, g_{hi}]` with :math:`g_{hi} = \min(\delta, \text{cap})`;
- the caps come from what a vessel can be: its length is ``ρ`` beams with
  :math:`\rho \in [\rho_{min}, \rho_{max}]`, so end-on (only the stern or the bow seen,
  ``B`` measured) the depth is :math:`L \in [\rho_{min} B, \rho_{max} B]`, and broadside
  (``L`` measured) it is :math:`B \in [L/\rho_{max}, L/\rho_{min}]`. Without a known
  heading the axes are ambiguous and both ranges apply (a wide, honest variance);
- an end of the cluster beside an occluder's shadow ``E`` (nearer returns,
  :attr:`~asvtwin.tracking.clustering.Clusters.end_shadow_m`) lets the hull go on
  behind it: on each axis ``a`` up to :math:`E / |w \cdot a|` on the side
  :math:`\operatorname{sign}(w \cdot a)`, ``w`` the end's direction across the line of
  sight (the near end of an axis within 20° of the line of sight excepted: its face is
  what the visible bearings show).

Per axis the centre is :math:`(x_{near} + x_{far})/2 + \sigma (G_{far} - G_{near})/2` with
``σ`` pointing away from the sensor, so the measurement is the mean of that and its
variance :math:`(\operatorname{var} G_{far} + \operatorname{var} G_{near})/4`. Range noise
goes along the line of sight, bearing noise across it, and the heading's uncertainty moves
the centre by about :math:`\sigma_\psi \sqrt{L^2 + B^2}/2`. The result is a position
measurement whose normalised error is close to its 2 degrees of freedom at every aspect
(tested by aspect sector in ``tests/tracking/test_hull_model.py``; figure in
docs/tracking.md). This is the rectangle ("L-shape") view of extended-object tracking of
vehicles (Zhang, Xu, Dolan et al. 2017, "Efficient L-shape fitting for vehicle detection
using laser scanners"), with the unseen extent bounded by the hull's proportions rather
than assumed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__: list[str] = []  # kernels; the public API is asvtwin.tracking.measurement.lidar_measurements

_COARSE = 18  # orientation search: 5° steps over 90°, then 1° around the best
_FINE = 11
#: |w·axis| (sine of the axis' angle to the line of sight) above which the near end of
#: that axis may hide behind an occluder (sin 20°)
_NEAR_HIDE = float(np.sin(np.deg2rad(20.0)))


@njit(cache=True)
def _extents(pts, s, n, c, sn):  # type: ignore[no-untyped-def]
    """Extents (s0, s1, t0, t1) of returns s..s+n-1 along (c, sn) and across it."""
    s0 = s1 = t0 = t1 = 0.0
    for j in range(n):
        a = pts[s + j, 0] * c + pts[s + j, 1] * sn
        b = -pts[s + j, 0] * sn + pts[s + j, 1] * c
        if j == 0:
            s0 = s1 = a
            t0 = t1 = b
        else:
            s0, s1, t0, t1 = min(s0, a), max(s1, a), min(t0, b), max(t1, b)
    return s0, s1, t0, t1


@njit(cache=True)
def _box_area(pts, s, n, c, sn):  # type: ignore[no-untyped-def]
    s0, s1, t0, t1 = _extents(pts, s, n, c, sn)
    return (s1 - s0) * (t1 - t0) + 1e-6 * ((s1 - s0) + (t1 - t0))


@njit(cache=True)
def _angle_table():  # type: ignore[no-untyped-def]
    """``[angle, cos, sin]`` of every angle the orientation search tries: rows
    ``0.._COARSE-1`` the coarse angles, row ``_COARSE + c _FINE + i`` the fine angle ``i``
    around coarse angle ``c`` (the search's own arithmetic, done once: the 29 cos/sin
    pairs per cluster were a sixth of its cost)."""
    step = 0.5 * np.pi / _COARSE
    tab = np.empty((_COARSE * (1 + _FINE), 3))
    for c in range(_COARSE):
        a = 0.5 * np.pi * c / _COARSE
        tab[c, 0], tab[c, 1], tab[c, 2] = a, np.cos(a), np.sin(a)
    for c in range(_COARSE):
        th0 = tab[c, 0]
        for i in range(_FINE):
            a = th0 - step + 2.0 * step * i / (_FINE - 1)
            r = _COARSE + c * _FINE + i
            tab[r, 0], tab[r, 1], tab[r, 2] = a, np.cos(a), np.sin(a)
    return tab


_ANGLES = _angle_table()


_COS = np.ascontiguousarray(_ANGLES[:, 1])  # the table's columns, contiguous (vector loads)
_SIN = np.ascontiguousarray(_ANGLES[:, 2])


@njit(cache=True)
def _box_areas(pts, s, n, r0, na, out, ext):  # type: ignore[no-untyped-def]
    """:func:`_box_area` of returns ``s..s+n-1`` for the ``na`` angles of rows
    ``r0..r0+na-1`` of :data:`_ANGLES` into ``out[:na]``: the same projections, extremes
    (the first return starts them, as in :func:`_extents`) and area, value for value.
    The angles are the inner loop, each with its running extremes in ``ext[:, a]``
    (``ext`` (4, >= na) scratch): independent per angle, so the loop runs in SIMD lanes
    (~1.5x faster than a pass over the returns per angle)."""
    x, y = pts[s, 0], pts[s, 1]
    for a in range(na):
        c, sn = _COS[r0 + a], _SIN[r0 + a]
        p = x * c + y * sn
        q = -x * sn + y * c
        ext[0, a] = p
        ext[1, a] = p
        ext[2, a] = q
        ext[3, a] = q
    for j in range(s + 1, s + n):
        x, y = pts[j, 0], pts[j, 1]
        for a in range(na):
            c, sn = _COS[r0 + a], _SIN[r0 + a]
            p = x * c + y * sn
            q = -x * sn + y * c
            # (selects, not min/max: the same values, and they vectorise)
            v = ext[0, a]
            ext[0, a] = p if p < v else v  # noqa: FURB136
            v = ext[1, a]
            ext[1, a] = p if p > v else v  # noqa: FURB136
            v = ext[2, a]
            ext[2, a] = q if q < v else v  # noqa: FURB136
            v = ext[3, a]
            ext[3, a] = q if q > v else v  # noqa: FURB136
    for a in range(na):
        s0, s1, t0, t1 = ext[0, a], ext[1, a], ext[2, a], ext[3, a]
        out[a] = (s1 - s0) * (t1 - t0) + 1e-6 * ((s1 - s0) + (t1 - t0))


@njit(cache=True)
def _box_orientation(pts, s, n):  # type: ignore[no-untyped-def]
    """Direction [rad] of the smallest-area bounding rectangle (mod π/2): 5° steps over
    90°, then 1° around the best (angles from :data:`_ANGLES`; the areas of each stage in
    one pass over the returns, :func:`_box_areas`)."""
    areas = np.empty(_COARSE)
    ext = np.empty((4, _COARSE))
    best, th, cb = np.inf, 0.0, 0
    _box_areas(pts, s, n, 0, _COARSE, areas, ext)
    for i in range(_COARSE):
        v = areas[i]
        if v < best:
            best, th, cb = v, _ANGLES[i, 0], i
    _box_areas(pts, s, n, _COARSE + cb * _FINE, _FINE, areas, ext)
    for i in range(_FINE):
        v = areas[i]
        if v < best:
            best, th = v, _ANGLES[_COARSE + cb * _FINE + i, 0]
    return th


@njit(cache=True)
def _axis(near, far, sign, g_near, g_far_lo, g_far_hi, kappa, near_kappa):  # type: ignore[no-untyped-def]
    """Centre coordinate and variance along one hull axis (see the module docstring).

    The far gap (the unseen depth: hull proportions, a hidden bow) stays the same from
    scan to scan, so its variance is scaled by ``kappa`` (the number of scans over which
    it is correlated) for a filter that would otherwise average it away; the near gap
    (sampling at a corner) changes with every scan (``near_kappa`` 1), unless it is a
    part hidden behind an occluder (then ``near_kappa = kappa``). Returns the centre,
    the variance for a filter and the single-scan variance."""
    m_far = 0.5 * (g_far_lo + g_far_hi)
    v_far = (g_far_hi - g_far_lo) ** 2 / 12.0
    m_near = 0.5 * g_near
    v_near = g_near * g_near / 12.0
    c = 0.5 * (near + far) + sign * 0.5 * (m_far - m_near)
    return c, 0.25 * (kappa * v_far + near_kappa * v_near), 0.25 * (v_far + v_near)


#: Per-cluster line-of-sight summary (:func:`_sight`): centroid (2), range to it, range of
#: the farthest return, unit line of sight (2), extreme bearings about it (2).
N_SIGHT = 8


@njit(cache=True)
def _sight(points, s, n, o0, o1, sg):  # type: ignore[no-untyped-def]
    """The line of sight to returns ``points[s:s + n]`` from ``(o0, o1)`` into ``sg``
    (:data:`N_SIGHT` values: ``c0, c1, r, r_far, l0, l1, amin, amax``). It depends on the
    returns alone, so a cluster measured with several hull axes computes it once."""
    c0 = c1 = 0.0
    for j in range(n):
        c0 += points[s + j, 0]
        c1 += points[s + j, 1]
    c0 /= n
    c1 /= n
    r = np.hypot(c0 - o0, c1 - o1)
    r_far = 0.0  # range of the farthest return
    for j in range(n):
        r_far = max(r_far, np.hypot(points[s + j, 0] - o0, points[s + j, 1] - o1))
    if r > 1e-9:
        l0, l1 = (c0 - o0) / r, (c1 - o1) / r
    else:
        l0, l1 = 1.0, 0.0
    amin, amax = 0.0, 0.0
    if n >= 2:  # bearings of the extreme returns about the line of sight to the centroid
        amin, amax = np.inf, -np.inf
        for j in range(n):
            a = np.arctan2(-(points[s + j, 0] - o0) * l1 + (points[s + j, 1] - o1) * l0,
                           (points[s + j, 0] - o0) * l0 + (points[s + j, 1] - o1) * l1)
            amin, amax = min(amin, a), max(amax, a)
    sg[0], sg[1], sg[2], sg[3], sg[4], sg[5], sg[6], sg[7] = c0, c1, r, r_far, l0, l1, amin, amax


@njit(cache=True)
def _hull_box_one(points, s, n, o0, o1, heading_i, heading_std_i, shadow, si, prm, z, R, ext, R1, row,  # type: ignore[no-untyped-def]
                  size_l, size_b, sg):
    """The hull-centre model of the ``n`` returns ``points[s:s + n]`` (hull axis
    ``heading_i``, NaN: unknown; occluder shadows ``shadow[si]``; line of sight ``sg``
    from :func:`_sight`), written to row ``row`` of ``z``, ``R``, ``ext``, ``R1`` (see
    :func:`hull_box_kernel`). ``size_l``, ``size_b``: the hull's known length and beam [m]
    (AIS static data of the track's MMSI; NaN: unknown, bounded by the length/beam ratio),
    used only with a known axis; they are taken to ``prm[15]`` relative (at least
    ``prm[16]`` m)."""
    rs, bs, step, rho_lo, rho_hi, ktip, ostd, floor = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7]
    kgap, taper, a_lo, a_hi, kappa, max_hidden = prm[8], prm[9], prm[10], prm[11], prm[12], prm[13]
    # line of sight to the centroid, range, ray spacing
    r, r_far, l0, l1, amin, amax = sg[2], sg[3], sg[4], sg[5], sg[6], sg[7]
    ray = prm[14]  # the scan's ray spacing (0: unknown)
    if step > 0.0 or n < 2:
        dphi = step if step > 0.0 else (ray if ray > 0.0 else 0.01)
    else:  # mean angular spacing of the returns (dropouts make it conservative)
        dphi = max((amax - amin) / (n - 1), 1e-5)
    d = r * dphi
    # the silhouette across the line of sight: the rays beside the cluster missed the
    # hull, so it spans at most the visible bearings plus one ray spacing on each side
    # (one or two returns of a far hull say little more than that)
    w_sil = r * (amax - amin + 2.0 * (ray if ray > 0.0 else dphi))
    known = np.isfinite(heading_i)
    th = heading_i if known else _box_orientation(points, s, n)
    ch, sh = np.cos(th), np.sin(th)
    # visible extents in the hull frame (h = (ch, sh), n = (-sh, ch))
    s0, s1, t0, t1 = _extents(points, s, n, ch, sh)
    es, et = s1 - s0, t1 - t0
    if not known and es < et:  # unknown heading: call the longer visible side the axis
        th += 0.5 * np.pi
        ch, sh = np.cos(th), np.sin(th)
        s0, s1, t0, t1 = t0, t1, -s1, -s0
        es, et = et, es
    so = o0 * ch + o1 * sh
    to = -o0 * sh + o1 * ch
    big = 1e6
    sign_h = 1.0 if so < 0.5 * (s0 + s1) else -1.0
    near_h, far_h = (s0, s1) if sign_h > 0 else (s1, s0)
    sign_n = 1.0 if to < 0.5 * (t0 + t1) else -1.0
    near_n, far_n = (t0, t1) if sign_n > 0 else (t1, t0)
    # a face along h (the flank at t = near_n) is hit at grazing angle sin β ≈ |t_o - near_n| / r,
    # so its returns are d / sin β apart along h; a face along n (stern, bow) likewise
    # (made conservative by two heading standard deviations: a grazing face may be
    # more grazing than the assumed heading says)
    ps = heading_std_i if known else ostd
    gh = abs(to - near_n) / r - 2.0 * ps
    gn = abs(so - near_h) / r - 2.0 * ps
    # (no flank faces the sensor when it looks along the hull from within its beam,
    # no end face when it looks across from within its length)
    dh = kgap * d / gh if (gh > 1e-9 and not t0 < to < t1) else big
    dn = kgap * d / gn if (gn > 1e-9 and not s0 < so < s1) else big
    es_hi = es + min(dh, big)  # what the sampling allows the extents to be
    et_hi = et + min(dn, big)
    sized = known and np.isfinite(size_l) and np.isfinite(size_b) and size_l > 0.0 and size_b > 0.0
    if sized:  # the vessel's own dimensions (AIS message 5, 19, 24): no ratio needed
        tl = max(prm[15] * size_l, prm[16])
        tb = max(prm[15] * size_b, prm[16])
        L_lo, L_hi = max(size_l - tl, 0.0), size_l + tl
        B_lo, B_hi = max(size_b - tb, 0.0), size_b + tb
    elif known:
        L_lo, L_hi = rho_lo * et, rho_hi * et_hi  # a hull seen end-on: L from the beam
        B_lo, B_hi = es / rho_hi, es_hi / rho_lo  # seen broadside: B from the length
    else:  # either side may be the hull axis: the unseen depth up to ρ_min times the
        # longer visible side (a flank seen broadside; a stern seen end-on is deeper, and
        # is measured again once the track has a course), or times the silhouette's
        # bound when the returns are too few to show the hull's width
        wide = max(es, et, w_sil)
        L_lo, L_hi = 0.0, rho_lo * wide
        B_lo, B_hi = 0.0, rho_lo * wide
    # a tapering bow hides part of itself. Off-axis angle of the sensor seen from the
    # hull, 0 end-on: below a_lo the bow's V faces are both seen from ahead and hidden
    # from aft; above a_hi the near V face is seen from aft and the far flank hidden
    # from ahead (the V shows half the beam); in between either (ρ-dependent)
    off = np.arctan2(abs(to - 0.5 * (t0 + t1)), abs(so - 0.5 * (s0 + s1)))
    w_all = 1.0 if off < a_lo else 0.0
    w_any = 1.0 if off < a_hi else 0.0
    L_est = size_l if sized else max(es, L_lo) / (1.0 - taper)
    tap_lo, tap_hi, half_lo, half_hi = 0.0, 0.0, 0.0, 0.0
    if not known:
        tap_hi, half_hi = taper * L_est, et
    elif sign_h > 0.0:  # sensor aft, bow away: the bow's tip beyond the shoulders
        tap_lo, tap_hi = w_all * taper * L_est, w_any * taper * L_est
    else:  # sensor ahead: the far half of the beam behind the near V face and flank
        half_lo, half_hi = (1.0 - w_any) * et, (1.0 - w_all) * et
    # an end hidden behind an occluder: the hull may go on behind it. The occluder's
    # shadow is E wide across the line of sight at the end's range; the end's
    # direction across the line of sight is w = ∓(−l1, l0) (lower / higher bearing).
    # Going ΔS along a hull axis a sweeps ΔS |w·a| of bearing, so up to
    # ΔS = E / |w·a| (at most max_hidden) of the hull may hide on the side sign(w·a)
    # of each axis: that extreme gets an unseen part U[0, ΔS] that repeats from scan
    # to scan. End-on, the whole length may hide behind a narrow occluder.
    # (sign_h > 0: the sensor is on the s0 side, so s1 is the far extreme)
    occ_h0 = occ_h1 = occ_t0 = occ_t1 = 0.0  # extensions beyond s0, s1, t0, t1
    for side in range(2):
        E = shadow[si, side]
        if not E > 0.0:
            continue
        w0, w1 = (l1, -l0) if side == 0 else (-l1, l0)
        wh = w0 * ch + w1 * sh
        wn = -w0 * sh + w1 * ch
        ext_h = min(E / max(abs(wh), 1e-9), max_hidden)
        ext_t = min(E / max(abs(wn), 1e-9), max_hidden)
        # the near extreme of an axis within ~20° of the line of sight cannot hide:
        # its face is what the visible bearings show (a stern seen end-on behind a
        # boat can, being across the line of sight by more than that)
        if wh > 0.0 and (sign_h > 0.0 or abs(wh) >= _NEAR_HIDE):
            occ_h1 = max(occ_h1, ext_h)
        elif wh <= 0.0 and (sign_h < 0.0 or abs(wh) >= _NEAR_HIDE):
            occ_h0 = max(occ_h0, ext_h)
        if wn > 0.0 and (sign_n > 0.0 or abs(wn) >= _NEAR_HIDE):
            occ_t1 = max(occ_t1, ext_t)
        elif wn <= 0.0 and (sign_n < 0.0 or abs(wn) >= _NEAR_HIDE):
            occ_t0 = max(occ_t0, ext_t)
    # the range limit: returns that reach the LiDAR's maximum range (within the range
    # noise and the sampling gap along a face running away) do not end the hull, they cut
    # it off. On each axis the hull may go on beyond what is seen by up to the longest it
    # can be (at most max_hidden): on the far side of an axis that points away from the sensor, on both sides
    # of an axis within ~20° of across the line of sight (the range circle curves away
    # from it both ways). Without this a hull entering or leaving the range was measured
    # metres towards the sensor, scan after scan (docs/tracking.md, "Tracking quality").
    # (within: the range noise and two sampling gaps of a face running away)
    lh, ln = abs(l0 * ch + l1 * sh), abs(-l0 * sh + l1 * ch)
    if r_far >= prm[17] - (3.0 * rs + 2.0 * kgap * d):
        cut = min(max(L_hi - es, 0.0), max_hidden)
        across = lh < _NEAR_HIDE
        if sign_h > 0.0 or across:
            occ_h1 = max(occ_h1, cut)
        if sign_h < 0.0 or across:
            occ_h0 = max(occ_h0, cut)
        cut = min(max(B_hi - et, 0.0), max_hidden)
        across = ln < _NEAR_HIDE
        if sign_n > 0.0 or across:
            occ_t1 = max(occ_t1, cut)
        if sign_n < 0.0 or across:
            occ_t0 = max(occ_t0, cut)
    if sized:  # the beam is known
        cap_t = max(B_hi - et, 0.0)
        occ_t0, occ_t1 = min(occ_t0, cap_t), min(occ_t1, cap_t)
        cap_h = max(L_hi - es, 0.0)  # and so is the length
        occ_h0, occ_h1 = min(occ_h0, cap_h), min(occ_h1, cap_h)
    elif known:  # the beam is at most 1/ρ_min of the longest the hull can be
        cap_t = max((es + occ_h0 + occ_h1 + min(dh, big)) / rho_lo - et, 0.0)
        occ_t0, occ_t1 = min(occ_t0, cap_t), min(occ_t1, cap_t)
    # along h
    far_occ, near_occ = (occ_h1, occ_h0) if sign_h > 0 else (occ_h0, occ_h1)
    hi = min(dh, max(L_hi - es, 0.0))
    lo = min(max(L_lo - es, 0.0), hi)
    g_near = min(dh, ktip * d)
    zs, vs, vs1 = _axis(near_h, far_h, sign_h, max(g_near, near_occ), lo + tap_lo,
                        max(hi + tap_hi, far_occ), kappa, kappa if near_occ > g_near else 1.0)
    L_max = es + max(hi + tap_hi, far_occ) + near_occ
    # along n
    far_occ, near_occ = (occ_t1, occ_t0) if sign_n > 0 else (occ_t0, occ_t1)
    hi = min(dn, max(B_hi - et, 0.0))
    lo = min(max(B_lo - et, 0.0), hi)
    g_near = min(dn, ktip * d)
    zt, vt, vt1 = _axis(near_n, far_n, sign_n, max(g_near, near_occ), lo + half_lo,
                        max(hi + half_hi, far_occ), kappa, kappa if near_occ > g_near else 1.0)
    B_max = et + max(hi + half_hi, far_occ) + near_occ
    z[row, 0] = zs * ch - zt * sh
    z[row, 1] = zs * sh + zt * ch
    ext[row, 0], ext[row, 1] = es, et
    # R = H diag(vs, vt) Hᵀ + range noise along the line of sight + bearing noise across it
    #     + heading uncertainty (the box turns about the visible corner) + a floor
    vpsi = ps * ps * 0.25 * (L_max * L_max + B_max * B_max)
    iso = floor * floor + vpsi
    vr, vb = rs * rs, (r * bs) ** 2
    R[row, 0, 0] = ch * ch * vs + sh * sh * vt + l0 * l0 * vr + l1 * l1 * vb + iso
    R[row, 1, 1] = sh * sh * vs + ch * ch * vt + l1 * l1 * vr + l0 * l0 * vb + iso
    R[row, 0, 1] = R[row, 1, 0] = ch * sh * (vs - vt) + l0 * l1 * (vr - vb)
    R1[row, 0, 0] = ch * ch * vs1 + sh * sh * vt1 + l0 * l0 * vr + l1 * l1 * vb + iso
    R1[row, 1, 1] = sh * sh * vs1 + ch * ch * vt1 + l1 * l1 * vr + l0 * l0 * vb + iso
    R1[row, 0, 1] = R1[row, 1, 0] = ch * sh * (vs1 - vt1) + l0 * l1 * (vr - vb)


@njit(cache=True)
def hull_box_kernel(points, offsets, origin, heading, heading_std, shadow, prm, only_known, sizes):  # type: ignore[no-untyped-def]
    """Centres ``z (k, 2)``, covariances ``R (k, 2, 2)`` (the unseen-depth part scaled by
    ``kappa``: for a filter), box extents ``ext (k, 2)`` ``[along, across]`` and the
    single-scan covariances ``R1`` (kappa = 1: for gates) of all clusters, and each
    cluster's line of sight (:func:`_sight`, ``(k, N_SIGHT)``; NaN rows where skipped).

    ``heading[i]`` is the hull axis of cluster ``i`` [rad] (NaN: unknown, the box
    orientation is used and the axes are ambiguous), ``heading_std`` its standard
    deviation [rad]; with ``only_known`` clusters without a heading are skipped (NaN
    rows). ``shadow (k, 2)`` is the occluder's shadow width [m] beyond the cluster's
    lower- and higher-bearing ends (:attr:`~asvtwin.tracking.clustering.Clusters.end_shadow_m`;
    0: a silhouette edge). ``prm`` = [range_std, bearing_std, angular_step (0: from the
    cluster), rho_min, rho_max, k_tip, orientation_std, floor_std, k_gap, taper,
    taper_angle_lo, taper_angle_hi, kappa (persistence of the unseen-depth error, scans),
    max_hidden (most of a hull taken to hide behind an occluder, m), ray_step (the scan's
    ray spacing, rad; 0: unknown), known_size_tol, known_size_floor (m), max_range (m; inf:
    unknown)]. ``sizes (k, 2)``:
    each hull's known length and beam [m] (NaN: unknown; used with a known heading).
    """
    k = offsets.shape[0] - 1
    z = np.full((k, 2), np.nan)
    R = np.full((k, 2, 2), np.nan)
    R1 = np.full((k, 2, 2), np.nan)
    ext = np.full((k, 2), np.nan)
    sight = np.full((k, N_SIGHT), np.nan)
    for i in range(k):
        s, n = offsets[i], offsets[i + 1] - offsets[i]
        if n == 0 or (only_known and not np.isfinite(heading[i])):
            continue
        _sight(points, s, n, origin[0], origin[1], sight[i])
        _hull_box_one(points, s, n, origin[0], origin[1], heading[i], heading_std[i], shadow, i, prm, z, R, ext, R1, i,
                      sizes[i, 0], sizes[i, 1], sight[i])
    return z, R, ext, R1, sight


@njit(cache=True)
def hull_box_pairs_kernel(points, offsets, origin, cols, heading, heading_std, shadow, prm):  # type: ignore[no-untyped-def]
    """:func:`hull_box_kernel` of cluster ``cols[p]`` with axis ``heading[p]`` for each
    ``p`` (a cluster measured once per track whose gate it is in, with that track's
    course): ``z (p, 2)``, ``R (p, 2, 2)``, ``ext (p, 2)``, ``R1 (p, 2, 2)``."""
    k = cols.shape[0]
    z = np.full((k, 2), np.nan)
    R = np.full((k, 2, 2), np.nan)
    R1 = np.full((k, 2, 2), np.nan)
    ext = np.full((k, 2), np.nan)
    sg = np.empty(N_SIGHT)
    for p in range(k):
        i = cols[p]
        s, n = offsets[i], offsets[i + 1] - offsets[i]
        if n == 0:
            continue
        _sight(points, s, n, origin[0], origin[1], sg)
        _hull_box_one(points, s, n, origin[0], origin[1], heading[p], heading_std[p], shadow, i, prm, z, R, ext, R1, p,
                      np.nan, np.nan, sg)
    return z, R, ext, R1
