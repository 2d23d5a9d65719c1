"""Compiled (numba) kernels of the RL environment, batched over environments.

- :func:`cast_circles`: the LiDAR of n own ships against each one's circular obstacles
  (rays as half-lines, circles solved exactly: t = b − √(b² − c)).
- :func:`path_features`: the closest point on each own ship's path (a polyline, searched
  in a window around the previous closest segment), the cross-track error, the path's
  heading there and the look-ahead point's bearing.
- :func:`filter_reach`: which environments have an obstacle that could constrain the
  safety filter's plan (the pre-cull before any per-environment work).
- :func:`lidar_selection`: which LiDAR returns of one ship become the filter's circles
  (the selection rule of :func:`asvtwin.control.lidar_circles`, compiled).

One call handles every environment: no Python loop over environments on the hot path.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["cast_circles", "filter_reach", "lidar_selection", "path_features"]


@njit(cache=True)
def cast_circles(pos, psi, rel, circles, rmax, out_d, out_k):  # pragma: no cover - compiled
    """Ranges [m] of ``rel`` rays from each own ship against its circles.

    ``pos`` (n, 2) NED positions [m], ``psi`` (n,) headings [rad], ``rel`` (m,) bearings
    relative to the bow [rad], ``circles`` (n, k, 3) rows ``[north, east, radius]`` (radius
    <= 0: an unused slot), ``rmax`` range [m]. Writes ``out_d`` (n, m) ranges (``rmax``
    where nothing returned; 0 for a ship inside a circle) and ``out_k`` (n, m) the circle
    hit (-1 for none).
    """
    n = pos.shape[0]
    m = rel.shape[0]
    k = circles.shape[1]
    for i in range(n):
        on = pos[i, 0]
        oe = pos[i, 1]
        for j in range(m):
            out_d[i, j] = rmax
            out_k[i, j] = -1
        for c in range(k):
            rho = circles[i, c, 2]
            if rho <= 0.0:
                continue
            wn = circles[i, c, 0] - on
            we = circles[i, c, 1] - oe
            cc = wn * wn + we * we - rho * rho
            if cc <= 0.0:  # inside the circle: every ray returns at once
                for j in range(m):
                    out_d[i, j] = 0.0
                    out_k[i, j] = c
                continue
            dist = math.sqrt(wn * wn + we * we)
            if dist - rho >= rmax:
                continue
            # only rays within the circle's angular half-width can hit it
            centre = math.atan2(we, wn) - psi[i]
            half = math.asin(min(1.0, rho / dist))
            for j in range(m):
                da = rel[j] - centre
                da = (da + math.pi) % (2.0 * math.pi) - math.pi
                if abs(da) > half + 1e-12:
                    continue
                a = psi[i] + rel[j]
                b = wn * math.cos(a) + we * math.sin(a)
                disc = b * b - cc
                if b <= 0.0 or disc < 0.0:
                    continue
                t = b - math.sqrt(disc)
                if t < out_d[i, j]:
                    out_d[i, j] = t
                    out_k[i, j] = c
    return 0


@njit(cache=True)
def path_features(pos, psi, path, s_cum, idx, window, lookahead, out):  # pragma: no cover
    """Closest point, CTE and heading errors of n own ships on their paths.

    ``path`` (n, p, 2) polylines [m], ``s_cum`` (n, p) arc length at each vertex [m],
    ``idx`` (n,) previous closest segment (updated in place), ``window`` segments searched
    either side, ``lookahead`` [m]. Writes ``out`` (n, 5): arc length s [m], cross-track
    error ε [m] (positive with the path on the port side, i.e. the ship right of the path),
    heading error ψ̄ = χ_path − ψ [rad], look-ahead heading error [rad] (bearing to the
    path point ``lookahead`` further on, minus ψ), progress s / length.
    """
    n = pos.shape[0]
    p = path.shape[1]
    for i in range(n):
        x = pos[i, 0]
        y = pos[i, 1]
        lo = max(0, idx[i] - window)
        hi = min(p - 2, idx[i] + window)
        best = 1e300
        bj = lo
        bt = 0.0
        for j in range(lo, hi + 1):
            ax = path[i, j, 0]
            ay = path[i, j, 1]
            ex = path[i, j + 1, 0] - ax
            ey = path[i, j + 1, 1] - ay
            ll = ex * ex + ey * ey
            t = ((x - ax) * ex + (y - ay) * ey) / ll if ll > 0.0 else 0.0
            t = min(1.0, max(0.0, t))
            qx = ax + t * ex - x
            qy = ay + t * ey - y
            dd = qx * qx + qy * qy
            if dd < best:
                best = dd
                bj = j
                bt = t
        idx[i] = bj
        ax = path[i, bj, 0]
        ay = path[i, bj, 1]
        ex = path[i, bj + 1, 0] - ax
        ey = path[i, bj + 1, 1] - ay
        chi = math.atan2(ey, ex)
        px = ax + bt * ex
        py = ay + bt * ey
        s = s_cum[i, bj] + bt * (s_cum[i, bj + 1] - s_cum[i, bj])
        # ε: signed distance, positive to starboard of the path direction (NED, right-handed)
        # (the distance to the closest point, signed by the side of the segment)
        side = -math.sin(chi) * (x - px) + math.cos(chi) * (y - py)
        eps = math.copysign(math.sqrt(best), side)
        # the look-ahead point at arc length s + lookahead (clamped to the path's end)
        total = s_cum[i, p - 1]
        sl = min(s + lookahead, total)
        k = bj
        while k < p - 2 and s_cum[i, k + 1] < sl:
            k += 1
        seg = s_cum[i, k + 1] - s_cum[i, k]
        f = (sl - s_cum[i, k]) / seg if seg > 0.0 else 0.0
        f = min(1.0, max(0.0, f))
        lx = path[i, k, 0] + f * (path[i, k + 1, 0] - path[i, k, 0])
        ly = path[i, k, 1] + f * (path[i, k + 1, 1] - path[i, k, 1])
        look = math.atan2(ly - y, lx - x)
        out[i, 0] = s
        out[i, 1] = eps
        out[i, 2] = (chi - psi[i] + math.pi) % (2.0 * math.pi) - math.pi
        out[i, 3] = (look - psi[i] + math.pi) % (2.0 * math.pi) - math.pi
        out[i, 4] = s / total if total > 0.0 else 1.0
    return 0


@njit(cache=True)
def filter_reach(pos, ranges, hit, skip_from, lidar_lim, moving, vel, moving_range,
                 tk, speed, clearance, active, out):  # pragma: no cover - compiled
    """Which of n environments can need the safety filter, into ``out`` (n,) bool.

    Environment i needs it when it is ``active`` and either a LiDAR ray not from a moving
    obstacle (``hit < skip_from``) reads less than ``lidar_lim`` [m], or a moving circle
    ``moving[i, j] = [north, east, radius]`` (radius 0: unused) within ``moving_range``
    [m] of its edge comes, on its constant-velocity prediction ``vel[i, j]`` at the
    stage times ``tk`` [s], closer than ``clearance`` [m] to the farthest point the
    ship can reach by then (``speed · t``). These are exactly the first tests of the
    per-environment obstacle construction; an environment that fails both gets no
    obstacle there.
    """
    n = pos.shape[0]
    for i in range(n):
        need = False
        if active[i]:
            for k in range(ranges.shape[1]):
                if hit[i, k] < skip_from and ranges[i, k] < lidar_lim:
                    need = True
                    break
            j = 0
            while not need and j < moving.shape[1]:
                r = moving[i, j, 2]
                if r > 0:
                    dx = moving[i, j, 0] - pos[i, 0]
                    dy = moving[i, j, 1] - pos[i, 1]
                    if math.sqrt(dx * dx + dy * dy) - r < moving_range:
                        for k in range(tk.shape[0]):
                            ex = dx + tk[k] * vel[i, j, 0]
                            ey = dy + tk[k] * vel[i, j, 1]
                            if math.sqrt(ex * ex + ey * ey) - r - speed * tk[k] < clearance:
                                need = True
                                break
                j += 1
        out[i] = need


@njit(cache=True)
def lidar_selection(psi, rel, ranges, hit, skip_from, lidar_range, lim, max_range,
                    n_sectors, per_sector, out):  # pragma: no cover - compiled
    """The rays of one own ship whose returns become the safety filter's circles.

    The rule of :func:`asvtwin.control.lidar_circles` (with the environment's masking in
    front of it), without its per-sector Python loop: a ray j returns when
    ``ranges[j] < lidar_range`` and it did not hit a moving obstacle (``hit[j] <
    skip_from``); nothing is selected unless some return is closer than ``lim`` [m];
    otherwise returns in (0, ``max_range``) are binned by their absolute bearing
    ``psi + rel[j]`` (mod 2π) into ``n_sectors`` equal sectors and in each the
    ``per_sector`` closest are kept (equal ranges: the lower ray index first). Writes
    the chosen ray indices into ``out`` sector by sector, closest first (the order of
    ``lidar_circles``' circles) and returns how many.
    """
    m = rel.shape[0]
    r = np.empty(m)
    closest = np.inf
    for j in range(m):
        rj = ranges[j]
        if rj < lidar_range and hit[j] < skip_from:
            r[j] = rj
            closest = min(closest, rj)
        else:
            r[j] = np.inf
    if not closest < lim:
        return 0
    two_pi = 2.0 * math.pi
    sector = np.empty(m, dtype=np.int64)
    for j in range(m):
        sector[j] = -1
        if r[j] < max_range and r[j] > 0.0:
            a = psi + rel[j]
            if math.isfinite(a):
                sector[j] = math.floor((a % two_pi) / two_pi * n_sectors)
    n = 0
    for s in range(n_sectors):
        start = n
        for j in range(m):
            if sector[j] != s:
                continue
            # insertion into this sector's sorted list (ascending range, stable)
            pos = n
            while pos > start and r[out[pos - 1]] > r[j]:
                pos -= 1
            if pos - start >= per_sector:
                continue
            last = min(n, start + per_sector - 1)
            for q in range(last, pos, -1):
                out[q] = out[q - 1]
            out[pos] = j
            if n < start + per_sector:
                n += 1
    return n
