"""Land polygons in the local NED frame: containment, distance to shore, ray casting.

:class:`LandMask` holds the coast as a numpy array of segments ``(S, 4)`` =
``[n0, e0, n1, e1]`` [m] and a uniform grid over them (compressed-sparse-row lists of the
segments whose bounding box touches each cell), built once. Every query runs in a numba
kernel over that grid:

- ``contains``: each cell knows whether its centre is on land (from shapely, at build
  time); a query point flips that state once per coast segment crossed by the short
  segment centre -> point, which only meets segments of its own cell (half-open
  crossing rule, as in PNPOLY).
- ``distance_to_shore`` / ``nearest_shore_point``: each cell has, built once, the list of
  coast segments that can be nearest to any point of it (those within ``D + 2h`` of its
  centre, ``D`` the centre's distance to the coast, ``h`` the half diagonal), so a query
  checks a handful of segments. Off the grid, cells are visited in growing square rings.
- ``cast_rays``: the segments of the cells within ``max_range_m`` of the origin are gathered
  once per scan, then every ray is intersected with every candidate
  (:math:`o + t\\,(\\cos a, \\sin a)`, :math:`t \\in [0, R]`).

Angles follow the NED convention: measured from north (x) clockwise towards east (y), so a
ray's direction is ``(cos a, sin a)`` in ``(north, east)``. A ray that hits nothing returns
``np.inf``.

Edges created by clipping the land to the scene box are not coast: pass the box as
``clip_boundary`` and they stay in the polygons (``contains`` is exact) but are left out of
the distance, nearest-point, segment and ray queries.
"""

from __future__ import annotations

import numpy as np
import shapely
from numba import njit
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError

__all__ = ["LandMask"]



@njit(cache=True)
def _cell_range(segs, s, g0n, g0e, cell, ni, nj):
    """Cell index ranges (inclusive, clipped) of the bounding box of segment ``s``."""
    i0 = max(int((min(segs[s, 0], segs[s, 2]) - g0n) / cell), 0)
    i1 = min(int((max(segs[s, 0], segs[s, 2]) - g0n) / cell), ni - 1)
    j0 = max(int((min(segs[s, 1], segs[s, 3]) - g0e) / cell), 0)
    j1 = min(int((max(segs[s, 1], segs[s, 3]) - g0e) / cell), nj - 1)
    return i0, i1, j0, j1


@njit(cache=True)
def _build_grid(segs, g0n, g0e, cell, ni, nj):
    """CSR lists of segment ids per cell (cell id = i * nj + j); bbox insertion."""
    start = np.zeros(ni * nj + 1, np.int64)
    for s in range(segs.shape[0]):
        i0, i1, j0, j1 = _cell_range(segs, s, g0n, g0e, cell, ni, nj)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                start[i * nj + j + 1] += 1
    start = np.cumsum(start)
    items = np.empty(start[-1], np.int64)
    fill = start[:-1].copy()
    for s in range(segs.shape[0]):
        i0, i1, j0, j1 = _cell_range(segs, s, g0n, g0e, cell, ni, nj)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                items[fill[i * nj + j]] = s
                fill[i * nj + j] += 1
    return start, items


@njit(cache=True)
def _contains(pts, segs, start, items, state, g0n, g0e, cell, ni, nj):
    out = np.zeros(pts.shape[0], np.bool_)
    for k in range(pts.shape[0]):
        qn, qe = pts[k, 0], pts[k, 1]
        fi, fj = (qn - g0n) / cell, (qe - g0e) / cell
        if not (fi >= 0.0 and fj >= 0.0 and fi < ni and fj < nj):
            continue  # outside the grid (or NaN): no land there
        c = int(fi) * nj + int(fj)
        cn, ce = g0n + (int(fi) + 0.5) * cell, g0e + (int(fj) + 0.5) * cell
        dn, de = qn - cn, qe - ce
        inside = state[c]
        for p in range(start[c], start[c + 1]):
            s = items[p]
            an, ae, bn, be = segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3]
            # half-open side test of a and b against the line centre -> query
            sa = dn * (ae - ce) - de * (an - cn) > 0.0
            sb = dn * (be - ce) - de * (bn - cn) > 0.0
            if sa == sb:
                continue
            # centre and query on opposite sides of the line a -> b
            en, ee = bn - an, be - ae
            oc = en * (ce - ae) - ee * (cn - an)
            oq = en * (qe - ae) - ee * (qn - an)
            if (oc > 0.0) != (oq > 0.0):
                inside = not inside
        out[k] = inside
    return out


@njit(cache=True)
def _closer(qn, qe, segs, s, best, near):
    """Squared distance to segment ``s`` if below ``best`` (then ``near`` gets the point)."""
    an, ae = segs[s, 0], segs[s, 1]
    en, ee = segs[s, 2] - an, segs[s, 3] - ae
    l2 = en * en + ee * ee
    t = 0.0
    if l2 > 0.0:
        t = min(max(((qn - an) * en + (qe - ae) * ee) / l2, 0.0), 1.0)
    pn, pe = an + t * en, ae + t * ee
    d2 = (qn - pn) ** 2 + (qe - pe) ** 2
    if d2 < best:
        near[0], near[1] = pn, pe
        return d2
    return best


@njit(cache=True)
def _nearest_listed(pts, segs, shore, start, items, nstart, nitems, g0n, g0e, cell, ni, nj):
    """Nearest coast point using the per-cell candidate lists (ring search off the grid)."""
    n = pts.shape[0]
    dist = np.empty(n)
    near = np.full((n, 2), np.nan)
    for k in range(n):
        qn, qe = pts[k, 0], pts[k, 1]
        fi, fj = (qn - g0n) / cell, (qe - g0e) / cell
        if not (fi >= 0.0 and fj >= 0.0 and fi < ni and fj < nj):
            d, q = _nearest(pts[k : k + 1], segs, shore, start, items, g0n, g0e, cell, ni, nj)
            dist[k], near[k, 0], near[k, 1] = d[0], q[0, 0], q[0, 1]
            continue
        c = int(fi) * nj + int(fj)
        best = np.inf
        for p in range(nstart[c], nstart[c + 1]):
            best = _closer(qn, qe, segs, nitems[p], best, near[k])
        dist[k] = np.sqrt(best)
    return dist, near


@njit(cache=True)
def _nearest(pts, segs, shore, start, items, g0n, g0e, cell, ni, nj):
    n = pts.shape[0]
    dist = np.full(n, np.inf)
    near = np.full((n, 2), np.nan)
    for k in range(n):
        qn, qe = pts[k, 0], pts[k, 1]
        if not (np.isfinite(qn) and np.isfinite(qe)):
            dist[k] = np.nan
            continue
        ci = min(max(int(np.floor((qn - g0n) / cell)), 0), ni - 1)
        cj = min(max(int(np.floor((qe - g0e) / cell)), 0), nj - 1)
        best = np.inf
        for r in range(max(ni, nj)):
            for i in range(ci - r, ci + r + 1):
                if i < 0 or i >= ni:
                    continue
                step = 1 if (i == ci - r or i == ci + r) else 2 * r  # ring cells only
                for j in range(cj - r, cj + r + 1, max(step, 1)):
                    if j < 0 or j >= nj:
                        continue
                    c = i * nj + j
                    for p in range(start[c], start[c + 1]):
                        if shore[items[p]]:
                            best = _closer(qn, qe, segs, items[p], best, near[k])
            # unvisited cells lie at least r * cell away
            if best < np.inf and np.sqrt(best) <= r * cell:
                break
        dist[k] = np.sqrt(best)
    return dist, near


@njit(cache=True)
def _candidates(on, oe, radius, segs, shore, start, items, g0n, g0e, cell, ni, nj):
    """Ids of the coast segments in the cells touching the square origin +- radius."""
    i0 = max(int(np.floor((on - radius - g0n) / cell)), 0)
    i1 = min(int(np.floor((on + radius - g0n) / cell)), ni - 1)
    j0 = max(int(np.floor((oe - radius - g0e) / cell)), 0)
    j1 = min(int(np.floor((oe + radius - g0e) / cell)), nj - 1)
    seen = np.zeros(segs.shape[0], np.bool_)
    out = np.empty(segs.shape[0], np.int64)
    k = 0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            c = i * nj + j
            for p in range(start[c], start[c + 1]):
                s = items[p]
                if shore[s] and not seen[s]:
                    seen[s] = True
                    out[k] = s
                    k += 1
    return out[:k]


@njit(cache=True)
def _cast_one(on, oe, cosa, sina, rmax, segs, cand, out):
    for r in range(cosa.shape[0]):
        dn, de = cosa[r], sina[r]
        best = np.inf
        for s in cand:
            an, ae = segs[s, 0] - on, segs[s, 1] - oe
            en, ee = segs[s, 2] - segs[s, 0], segs[s, 3] - segs[s, 1]
            den = dn * ee - de * en  # cross(d, e)
            if den == 0.0:
                continue  # parallel: the neighbouring segments catch a grazing hit
            t = (an * ee - ae * en) / den  # along the ray [m]
            u = (an * de - ae * dn) / den  # along the segment [-]
            if 0.0 <= t <= rmax and 0.0 <= u <= 1.0 and t < best:
                best = t
        out[r] = best


@njit(cache=True)
def _cast_many(origins, cosa, sina, rmax, segs, shore, start, items, g0n, g0e, cell, ni, nj):
    out = np.empty((origins.shape[0], cosa.shape[0]))
    for k in range(origins.shape[0]):
        on, oe = origins[k, 0], origins[k, 1]
        cand = _candidates(on, oe, rmax, segs, shore, start, items, g0n, g0e, cell, ni, nj)
        _cast_one(on, oe, cosa, sina, rmax, segs, cand, out[k])
    return out


def _as_points(points: ArrayLike, name: str = "points") -> _F8:
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise StateError(f"{name} must have shape (n, 2) [north_m, east_m], actually: {p.shape}")
    return p


def _segments_of(geom: BaseGeometry) -> _F8:
    """All ring edges of polygons as (S, 4) ``[n0, e0, n1, e1]``."""
    rings = shapely.get_rings(shapely.get_parts(geom))
    xy, ring_id = shapely.get_coordinates(rings, return_index=True)
    same = ring_id[:-1] == ring_id[1:]
    return np.ascontiguousarray(np.hstack([xy[:-1][same], xy[1:][same]]))


class LandMask:
    """Land polygons in NED metres with fast vectorised coast queries.

    Parameters
    ----------
    polygons : shapely Polygon or MultiPolygon, or a sequence of Polygons
        Land in the local NED frame; shapely ``x`` is north [m], ``y`` is east [m].
    clip_boundary : shapely Polygon, optional
        The scene box in NED [m]. Polygon edges lying on its boundary (within 1 m) are
        artefacts of clipping, not coast: they are excluded from the coast segments.
    cell_size_m : float, default 250.0
        Side of the uniform grid cells [m].

    Raises
    ------
    ParameterError
        If there is no polygon, a polygon is invalid or the cell size is not positive.
    """

    def __init__(
        self,
        polygons: BaseGeometry | list[Polygon] | tuple[Polygon, ...],
        *,
        clip_boundary: Polygon | None = None,
        cell_size_m: float = 250.0,
    ) -> None:
        geom = polygons if isinstance(polygons, BaseGeometry) else MultiPolygon(list(polygons))
        parts = [p for p in shapely.get_parts(geom) if isinstance(p, Polygon) and not p.is_empty]
        if not parts:
            raise ParameterError("LandMask needs at least one non-empty polygon, actually: none")
        if not all(p.is_valid for p in parts):
            bad = next(p for p in parts if not p.is_valid)
            raise ParameterError(f"invalid land polygon: {shapely.is_valid_reason(bad)}")
        if not cell_size_m > 0:
            raise ParameterError(f"cell_size_m must be positive, actually: {cell_size_m!r}")
        self.polygons: MultiPolygon = MultiPolygon(parts)
        segs = _segments_of(self.polygons)
        shore = np.ones(len(segs), dtype=np.bool_)
        if clip_boundary is not None:
            edge = clip_boundary.exterior
            mid = 0.5 * (segs[:, :2] + segs[:, 2:])
            on_edge = [
                shapely.distance(edge, shapely.points(q)) < 1.0
                for q in (segs[:, :2], segs[:, 2:], mid)
            ]
            shore = ~(on_edge[0] & on_edge[1] & on_edge[2])
        self._all = segs
        self._shore = shore
        self.segments: _F8 = np.ascontiguousarray(segs[shore])
        self.segments.flags.writeable = False
        nmin, emin, nmax, emax = self.polygons.bounds
        self.bounds: tuple[float, float, float, float] = (nmin, emin, nmax, emax)
        self.cell_size_m = float(cell_size_m)
        self._last_directions: tuple[_F8, _F8, _F8] | None = None
        self._g0 = (nmin - 1.0, emin - 1.0)
        self._ni = int((nmax - nmin + 2.0) // cell_size_m) + 1
        self._nj = int((emax - emin + 2.0) // cell_size_m) + 1
        # grid origin [m], cell [m], rows (north), columns (east): the kernels' arguments
        self._grid = (*self._g0, self.cell_size_m, self._ni, self._nj)
        self._start, self._items = _build_grid(segs, *self._grid)
        ci = (np.arange(self._ni) + 0.5) * cell_size_m + self._g0[0]
        cj = (np.arange(self._nj) + 0.5) * cell_size_m + self._g0[1]
        cn, ce = np.meshgrid(ci, cj, indexing="ij")
        shapely.prepare(self.polygons)
        centres = np.column_stack([cn.ravel(), ce.ravel()])
        self._state = shapely.contains_xy(self.polygons, centres[:, 0], centres[:, 1])
        self._nstart, self._nitems = self._nearest_lists(centres)

    def _nearest_lists(self, centres: _F8) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Per cell, the coast segments that can be nearest to a point of the cell.

        With ``D`` the distance from the cell centre to the coast and ``h`` the half
        diagonal, every point of the cell is within ``D + h`` of the coast, so its nearest
        segment is within ``D + 2 h`` of the centre (CSR lists, ids into all segments).
        """
        ncell = centres.shape[0]
        if not self._shore.any():
            return np.zeros(ncell + 1, np.int64), np.empty(0, np.int64)
        d, _ = _nearest(centres, self._all, self._shore, self._start, self._items, *self._grid)
        tree = shapely.STRtree(shapely.linestrings(self.segments.reshape(-1, 2, 2)))
        reach = d + np.sqrt(2.0) * self.cell_size_m + 1e-6
        cell_id, seg = tree.query(shapely.points(centres), predicate="dwithin", distance=reach)
        order = np.lexsort((seg, cell_id))
        nstart = np.zeros(ncell + 1, np.int64)
        np.cumsum(np.bincount(cell_id, minlength=ncell), out=nstart[1:])
        return nstart, np.flatnonzero(self._shore)[seg[order]].astype(np.int64)

    # All queries take ``points`` of shape (n, 2): ``[north_m, east_m]`` in the NED frame [m].
    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point is on land: bool (n,), False on water and off the land's bbox."""
        p = _as_points(points)
        return _contains(p, self._all, self._start, self._items, self._state, *self._grid)

    def _nearest(self, points: ArrayLike) -> tuple[_F8, _F8]:
        return _nearest_listed(
            _as_points(points),
            self._all,
            self._shore,
            self._start,
            self._items,
            self._nstart,
            self._nitems,
            *self._grid,
        )

    def distance_to_shore(self, points: ArrayLike) -> _F8:
        """Distance to the nearest coast segment [m], (n,), >= 0 (= distance to land on water)."""
        return self._nearest(points)[0]

    def signed_distance(self, points: ArrayLike) -> _F8:
        """Signed distance to the coast [m], (n,): positive on water, negative inland."""
        d = self.distance_to_shore(points)
        return np.where(self.contains(points), -d, d)

    def nearest_shore_point(self, points: ArrayLike) -> _F8:
        """Closest coast point ``[north_m, east_m]`` [m], (n, 2); NaN for non-finite input."""
        return self._nearest(points)[1]

    def cast_rays(self, origin: ArrayLike, angles_rad: ArrayLike, max_range_m: float) -> _F8:
        """Range from ``origin`` to the first coast crossing along each ray.

        Parameters
        ----------
        origin : array_like, shape (2,)
            Ray origin ``[north_m, east_m]`` [m].
        angles_rad : array_like, shape (m,)
            Ray directions [rad] from north, clockwise towards east: direction
            ``(cos a, sin a)`` in ``(north, east)``. Reusing the same angles from scan to scan
            skips recomputing their sines and cosines.
        max_range_m : float
            Maximum range [m], > 0; hits beyond it are ignored.

        Returns
        -------
        ndarray, shape (m,)
            Range to the first hit [m] in ``[0, max_range_m]``; ``np.inf`` where the ray meets
            no coast within ``max_range_m``.
        """
        o = np.asarray(origin, dtype=np.float64)
        if o.shape != (2,):
            raise StateError(f"origin must have shape (2,) [north_m, east_m], actually: {o.shape}")
        return self.cast_rays_many(o[None, :], angles_rad, max_range_m)[0]

    def cast_rays_many(self, origins: ArrayLike, angles_rad: ArrayLike, max_range_m: float) -> _F8:
        """:meth:`cast_rays` from many ``origins`` (n, 2) [m]: ranges (n, m) [m], inf = no hit."""
        o = _as_points(origins, "origins")
        rmax = float(max_range_m)
        if not rmax > 0:
            raise ParameterError(f"max_range_m must be positive, actually: {max_range_m!r}")
        cosa, sina = self._directions(angles_rad)
        return _cast_many(
            o, cosa, sina, rmax, self._all, self._shore, self._start, self._items, *self._grid
        )

    def _directions(self, angles_rad: ArrayLike) -> tuple[_F8, _F8]:
        """``cos`` and ``sin`` of the angles, reused while scans repeat the same angles."""
        a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
        last = self._last_directions  # one tuple, swapped atomically: safe across threads
        if last is not None and last[0].shape == a.shape and np.array_equal(last[0], a):
            return last[1], last[2]
        entry = (a.copy(), np.cos(a), np.sin(a))
        self._last_directions = entry
        return entry[1], entry[2]

    def segments_within(self, point: ArrayLike, radius_m: float) -> _F8:
        """Coast segments ``[n0, e0, n1, e1]`` [m], (k, 4), within ``radius_m`` of ``point``.

        Parameters
        ----------
        point : array_like, shape (2,)
            ``[north_m, east_m]`` [m].
        radius_m : float
            Search radius [m], >= 0; a segment is kept if its closest point is within it.
        """
        p = np.asarray(point, dtype=np.float64)
        if p.shape != (2,):
            raise StateError(f"point must have shape (2,) [north_m, east_m], actually: {p.shape}")
        idx = _candidates(
            p[0],
            p[1],
            float(radius_m),
            self._all,
            self._shore,
            self._start,
            self._items,
            *self._grid,
        )
        s = self._all[np.sort(idx)]
        e = s[:, 2:] - s[:, :2]
        l2 = np.maximum((e * e).sum(axis=1), 1e-300)
        t = np.clip(((p - s[:, :2]) * e).sum(axis=1) / l2, 0.0, 1.0)
        d = np.hypot(*(s[:, :2] + t[:, None] * e - p).T)
        return s[d <= radius_m]

    def terrain_height_m(
        self, points: ArrayLike, *, peak_m: float = 400.0, scale_m: float = 1500.0
    ) -> _F8:
        """Synthetic terrain height [m], (n,), for a 3-D view: derived from the coastline only.

        Not measured relief (no offline elevation model of the area exists): the height grows
        smoothly with the distance inland ``d`` and saturates,

        .. math:: h = h_{peak} \\tanh(d / L), \\qquad h = 0 \\text{ on water},

        with ``peak_m`` = :math:`h_{peak}` [m] and ``scale_m`` = :math:`L` [m] (at ``d = L``
        the height is 76 % of the peak).
        """
        inland = np.maximum(-self.signed_distance(points), 0.0)
        return peak_m * np.tanh(inland / scale_m)
