r"""Segmentation of a LiDAR scan into clusters, coast returns separated out.

Two steps, both vectorised:

1. **Coast removal.** With the scene's :class:`~asvtwin.geo.LandMask`, every return on land
   or within ``coast_margin_m`` of the shore is a coast return and is dropped (a vessel is
   never on land; one moored closer than the margin is lost, a documented limit).
2. **Euclidean clustering** (single linkage, DBSCAN with ``min_samples = 1``): two returns
   belong to the same cluster when they are closer than a link distance. For an ordered
   scan the link distance is the adaptive breakpoint detector of Borges & Aldon (2004),
   :math:`D = \max\big(\text{link}_m,\ r \sin\Delta\varphi / \sin(\lambda - \Delta\varphi)
   + 3\sigma_r\big)` for two returns :math:`\Delta\varphi < \lambda/2` apart in bearing
   (capped at ``max_link_m``, so a wide gap of empty bearings never links two vessels),
   i.e. the gap between returns on a surface seen at incidence down to :math:`\lambda`; only returns
   within ``window`` positions of each other are compared (an object occupies a contiguous
   run of bearings), which makes it O(m) in a numba union–find. Two returns are never
   linked across a **beam gap**: more than ``max_empty_rays`` rays between them that saw
   nothing or saw past both (the silhouette of one hull is an unbroken run of bearings).
   Unordered points use a k-d tree (scipy) and connected components.
3. **Occluded ends.** Beside each cluster's two angular ends, the run of nearer returns
   (an occluder) is measured as a width at the end's range
   (:attr:`Clusters.end_shadow_m`): how far the hull may go on unseen behind it.

:func:`split_clusters` cuts a cluster between known vessel positions (tracks, AIS).

Non-finite points are dropped and counted; nothing here raises on data.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.geo.land import LandMask
from asvtwin.sensors.lidar import LidarScan

__all__ = ["ClusterConfig", "Clusters", "cluster_points", "cluster_scan", "split_clusters"]



@dataclass(frozen=True)
class ClusterConfig:
    """Segmentation settings.

    Attributes
    ----------
    link_m : float
        Minimum link distance between returns of one object [m], > 0.
    incidence_rad : float
        Smallest incidence angle λ of a surface still linked across neighbouring rays
        [rad], in (0, π/2].
    range_std_m : float
        Range noise σ_r added (× 3) to the link distance [m], >= 0.
    max_link_m : float
        Upper bound of the adaptive link distance [m], >= ``link_m``.
    window : int
        For ordered scans: compare each return with the next ``window`` returns, >= 1.
    min_points : int
        Clusters with fewer returns are dropped (and counted), >= 1.
    coast_margin_m : float
        Returns within this distance of the shore are coast [m], >= 0.
    occlusion_tol_m : float
        A return beside a cluster's angular end counts as an occluder when it is closer
        than the end's range by more than this [m], >= 0; a return between two returns
        is "past" them when farther than both by more than this.
    max_empty_rays : int
        Beam-gap split (ordered scans): two returns are never linked when more than this
        many rays between them returned nothing or returned from beyond both (free water
        between two hulls; the silhouette of one hull is an unbroken run of bearings).
        It tolerates that many dropouts; -1 disables the split (the adaptive link alone).
    """

    link_m: float = 3.0
    incidence_rad: float = float(np.deg2rad(10.0))
    range_std_m: float = 0.05
    max_link_m: float = 25.0
    window: int = 4
    min_points: int = 1
    coast_margin_m: float = 2.0
    occlusion_tol_m: float = 1.0
    max_empty_rays: int = 1

    def __post_init__(self) -> None:
        for name, ok, expected in (
            ("link_m", 0.0 < self.link_m < np.inf, "finite and > 0 m"),
            ("incidence_rad", 0.0 < self.incidence_rad <= 0.5 * np.pi, "in (0, π/2]"),
            ("range_std_m", 0.0 <= self.range_std_m < np.inf, "finite and >= 0 m"),
            ("max_link_m", self.link_m <= self.max_link_m < np.inf, "finite and >= link_m"),
            ("window", int(self.window) >= 1, ">= 1"),
            ("min_points", int(self.min_points) >= 1, ">= 1"),
            ("coast_margin_m", 0.0 <= self.coast_margin_m < np.inf, "finite and >= 0 m"),
            ("occlusion_tol_m", 0.0 <= self.occlusion_tol_m < np.inf, "finite and >= 0 m"),
            ("max_empty_rays", int(self.max_empty_rays) == self.max_empty_rays and self.max_empty_rays >= -1,
             "an integer >= -1"),
        ):
            if not ok:
                raise ParameterError(f"ClusterConfig.{name} must be {expected}, actually: {getattr(self, name)!r}")


@dataclass(frozen=True)
class Clusters:
    """Clusters of points, concatenated (plain arrays).

    Attributes
    ----------
    points : ndarray, shape (m, 2)
        Points of all clusters ``[north_m, east_m]`` [m], cluster after cluster.
    offsets : ndarray of int64, shape (k + 1,)
        Cluster ``i`` is ``points[offsets[i]:offsets[i + 1]]``.
    t_s : float
        Time of the scan [s].
    origin_ned : ndarray, shape (2,)
        Sensor position [m] (NaN when unknown).
    n_coast : int
        Returns dropped as coast.
    n_invalid : int
        Non-finite returns dropped.
    n_small : int
        Returns dropped in clusters smaller than ``min_points``.
    end_shadow_m : ndarray, shape (k, 2), or None
        Occlusion at the cluster's two angular ends ``[lower bearing, higher bearing]``:
        the width [m], at the range of the end return, of the run of *closer* returns (or
        of the field of view's edge) just beyond that end, i.e. how far the hull may
        continue unseen behind an occluder; 0 where the next ray is empty or farther (a
        true silhouette edge). None when unknown (clusters not from an ordered scan).
    ray_step_rad : float
        Angular spacing of the scan's rays [rad] (NaN when unknown). A cluster of one or
        two returns does not show the ray spacing itself; the hull model needs it to
        bound the silhouette (the rays beside the cluster missed the hull).
    max_range_m : float
        The LiDAR's maximum range [m] (inf when unknown). A hull reaching beyond it is cut
        off there, and the hull model lets a cluster whose far returns reach the limit go
        on beyond it.
    """

    points: _F8
    offsets: NDArray[np.int64]
    t_s: float = 0.0
    origin_ned: _F8 = field(default_factory=lambda: np.full(2, np.nan))
    n_coast: int = 0
    n_invalid: int = 0
    n_small: int = 0
    end_shadow_m: _F8 | None = None
    ray_step_rad: float = float("nan")
    max_range_m: float = float("inf")

    def __len__(self) -> int:
        return int(self.offsets.shape[0] - 1)

    def __getitem__(self, i: int) -> _F8:
        return self.points[self.offsets[i]:self.offsets[i + 1]]

    @property
    def sizes(self) -> NDArray[np.int64]:
        """Number of points per cluster."""
        return np.diff(self.offsets)

    @property
    def centroids(self) -> _F8:
        """Mean point of each cluster [m], shape (k, 2)."""
        if len(self) == 0:
            return np.empty((0, 2))
        sums = np.add.reduceat(self.points, self.offsets[:-1], axis=0)
        return sums / self.sizes[:, None]

    @classmethod
    def from_list(cls, clusters: list[ArrayLike], *, t_s: float = 0.0,
                  origin_ned: ArrayLike | None = None) -> Clusters:
        """Build from a list of (k_i, 2) arrays (tests, external segmenters)."""
        arrs = [np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in clusters]
        pts = np.concatenate(arrs) if arrs else np.empty((0, 2))
        off = np.concatenate([[0], np.cumsum([len(a) for a in arrs])]).astype(np.int64)
        o = np.full(2, np.nan) if origin_ned is None else np.asarray(origin_ned, np.float64)
        return cls(points=pts, offsets=off, t_s=float(t_s), origin_ned=o)


@njit(cache=True)
def _find(parent, i):  # type: ignore[no-untyped-def]
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def _beam_gap(i0, i1, rmax, ranges, hit, m, full, max_empty):  # type: ignore[no-untyped-def]
    """Whether more than ``max_empty`` rays strictly between rays ``i0`` and ``i1`` (the
    short way round for a full circle) saw nothing or saw past ``rmax``: the silhouette of
    one hull is an unbroken run of bearings, so such a gap is free water between two
    objects (a dropout explains at most ``max_empty`` rays)."""
    d = i1 - i0
    if full:
        d %= m
        if d > m // 2:
            d -= m
    step = 1 if d > 0 else -1
    empty = 0
    j = i0  # (i0 + step k) % m, stepped without a division per ray
    for _ in range(1, abs(d)):
        j += step
        if j < 0:
            j += m
        elif j >= m:
            j -= m
        if not hit[j] or ranges[j] > rmax:
            empty += 1
            if empty > max_empty:
                return True
    return False


@njit(cache=True)
def _link_ordered(pts, r, ang, link_m, lam, noise, window, max_link, ix, ranges, hit, full, max_empty,
                  tol):  # type: ignore[no-untyped-def]
    """Union–find labels of angularly ordered points; neighbours within ``window``, cyclic.

    ``ix`` is each point's ray index in the scan (``ranges``, ``hit``: the whole scan);
    two points are never linked across a beam gap (:func:`_beam_gap`, ``max_empty``
    tolerated empty rays; ``max_empty < 0`` disables the test)."""
    n = pts.shape[0]
    m = ranges.shape[0]
    parent = np.arange(n)
    for i in range(n):
        for w in range(1, min(window, n - 1) + 1):
            j = (i + w) % n
            ri, rj = _find(parent, i), _find(parent, j)
            if ri == rj:
                continue  # already one cluster: the link would change nothing
            d2 = (pts[i, 0] - pts[j, 0]) ** 2 + (pts[i, 1] - pts[j, 1]) ** 2
            linked = d2 <= link_m * link_m
            if not linked:
                dphi = abs(ang[j] - ang[i])
                if dphi > np.pi:
                    dphi = 2.0 * np.pi - dphi % (2.0 * np.pi)
                if dphi < 0.5 * lam:  # adaptive breakpoint detector (not across wide gaps)
                    lim = min(min(r[i], r[j]) * np.sin(dphi) / np.sin(lam - dphi) + noise, max_link)
                    linked = d2 <= lim * lim
            if linked and max_empty >= 0 and abs(ix[j] - ix[i]) > 1.5:  # neighbouring rays: no gap
                linked = not _beam_gap(int(ix[i]), int(ix[j]), max(r[i], r[j]) + tol, ranges, hit, m, full,
                                       max_empty)
            if linked:
                parent[max(ri, rj)] = min(ri, rj)
    labels = np.empty(n, np.int64)
    for i in range(n):
        labels[i] = _find(parent, i)
    return labels


@njit(cache=True)
def _group_kernel(pts, labels, min_points):  # type: ignore[no-untyped-def]
    """Points grouped by label (labels in [0, m)), groups in ascending label order, points
    in input order within a group (what ``np.unique`` + a stable argsort give), groups
    smaller than ``min_points`` dropped: (points, offsets, n_dropped)."""
    n = pts.shape[0]
    counts = np.zeros(n + 1, np.int64)
    for i in range(n):
        counts[labels[i]] += 1
    start = np.full(n + 1, -1, np.int64)
    n_groups, total = 0, 0
    for lab in range(n):
        if counts[lab] >= min_points and counts[lab] > 0:
            start[lab] = total
            total += counts[lab]
            n_groups += 1
    out = np.empty((total, 2))
    off = np.empty(n_groups + 1, np.int64)
    off[0] = 0
    g = 0
    for lab in range(n):
        if start[lab] >= 0:
            off[g + 1] = start[lab] + counts[lab]
            g += 1
    for i in range(n):
        k = start[labels[i]]
        if k >= 0:
            out[k, 0] = pts[i, 0]
            out[k, 1] = pts[i, 1]
            start[labels[i]] = k + 1
    return out, off, n - total


def _group(pts: _F8, labels: NDArray[np.int64], min_points: int) -> tuple[_F8, NDArray[np.int64], int]:
    """Group points by label (in [0, m)), drop small groups: (points, offsets, n_dropped)."""
    p, off, small = _group_kernel(np.ascontiguousarray(pts, dtype=np.float64),
                                  np.ascontiguousarray(labels, dtype=np.int64), int(min_points))
    return p, off, int(small)


@njit(cache=True)
def _valid_returns(pts, r, ang, hit):  # type: ignore[no-untyped-def]
    """The returns with a hit, a finite point and a finite range, compacted: (pts, r, ang,
    ray index (as float), n_invalid)."""
    n = pts.shape[0]
    keep = np.zeros(n, np.bool_)
    k, n_hit = 0, 0
    for i in range(n):
        if hit[i]:
            n_hit += 1
            if np.isfinite(pts[i, 0]) and np.isfinite(pts[i, 1]) and np.isfinite(r[i]):
                keep[i] = True
                k += 1
    p, rr, aa, ix = np.empty((k, 2)), np.empty(k), np.empty(k), np.empty(k)
    j = 0
    for i in range(n):
        if keep[i]:
            p[j, 0], p[j, 1], rr[j], aa[j], ix[j] = pts[i, 0], pts[i, 1], r[i], ang[i], i
            j += 1
    return p, rr, aa, ix, n_hit - k


def _coast_filter(pts: _F8, land: LandMask | None, margin: float) -> tuple[_F8, NDArray[np.bool_]]:
    if land is None or pts.shape[0] == 0:
        return pts, np.ones(pts.shape[0], bool)
    water = ~land.contains(pts) & (land.distance_to_shore(pts) > margin)
    return pts[water], water


def cluster_scan(scan: LidarScan, land: LandMask | None = None, config: ClusterConfig | None = None) -> Clusters:
    """Segment one LiDAR scan into clusters of vessel returns.

    Parameters
    ----------
    scan : LidarScan
        The scan (its ``hit_id`` ground truth is not used).
    land : LandMask or None
        The scene's coast; ``None`` for open sea (no coast removal).
    config : ClusterConfig, optional
        Segmentation settings.

    Returns
    -------
    Clusters
    """
    cfg = config or ClusterConfig()
    pts, r, ang, ix, n_invalid = _valid_returns(
        np.ascontiguousarray(scan.points_ned, dtype=np.float64), np.ascontiguousarray(scan.ranges_m, dtype=np.float64),
        np.ascontiguousarray(scan.angles_rad, dtype=np.float64), np.ascontiguousarray(scan.hit, dtype=np.bool_))
    n_before = pts.shape[0]
    if land is not None and n_before:
        pts, water = _coast_filter(pts, land, cfg.coast_margin_m)
        pts, r, ang, ix = np.ascontiguousarray(pts), r[water], ang[water], ix[water]
    ranges = np.ascontiguousarray(scan.ranges_m, dtype=np.float64)
    hit = np.ascontiguousarray(scan.hit, dtype=np.bool_)
    step, full = _scan_geometry(scan.angles_rad)
    labels = _link_ordered(pts, r, ang, cfg.link_m, cfg.incidence_rad, 3.0 * cfg.range_std_m, int(cfg.window),
                           cfg.max_link_m, ix, ranges, hit, full, int(cfg.max_empty_rays), cfg.occlusion_tol_m)
    p, off, small = _group_kernel(pts, labels, int(cfg.min_points))
    # the ray index and range of every grouped return, in the same order (for the ends)
    g, _, _ = _group_kernel(np.ascontiguousarray(np.column_stack([ix, r])), labels, int(cfg.min_points))
    shadow = _end_shadows(g, off, ranges, hit, step, full, cfg.occlusion_tol_m)
    return Clusters(points=p, offsets=off, t_s=float(scan.t_s), origin_ned=np.array(scan.origin_ned, dtype=float),
                    n_coast=n_before - pts.shape[0], n_invalid=int(n_invalid), n_small=int(small),
                    end_shadow_m=shadow, ray_step_rad=step, max_range_m=float(scan.max_range_m))


def _scan_geometry(angles: _F8) -> tuple[float, bool]:
    """Angular step [rad] of an ordered scan and whether it closes the circle."""
    n = angles.shape[0]
    if n < 2:
        return 2.0 * np.pi, True
    step = abs(float(np.angle(np.exp(1j * (angles[1] - angles[0])))))
    return step, bool(n * step >= 2.0 * np.pi - 0.5 * step)


#: Rays counted at most beyond a cluster's end when measuring an occluder's shadow.
_MAX_SHADOW_RAYS = 400


@njit(cache=True)
def _end_shadows(g, off, ranges, hit, step, full, tol):  # type: ignore[no-untyped-def]
    """Shadow widths [m] beyond the two angular ends of each cluster (see
    :attr:`Clusters.end_shadow_m`). ``g[:, 0]`` holds the ray index of each grouped return
    (ascending within a cluster), ``g[:, 1]`` its range. The ends of a cluster sit on
    either side of its widest gap in ray index (cyclic for a full circle). Beyond an end,
    one empty ray (a dropout) is skipped; then every ray whose return is closer than the
    end's range by more than ``tol`` [m] is part of the occluder's shadow; the field of
    view's edge (a sector scan) counts as a shadow of ``_MAX_SHADOW_RAYS`` rays."""
    m = ranges.shape[0]
    k = off.shape[0] - 1
    out = np.zeros((k, 2))
    for c in range(k):
        s, e = off[c], off[c + 1]
        lo, hi = s, e - 1  # positions of the low and high ends within g
        if full and e - s > 1:
            best = int(g[s, 0]) + m - int(g[e - 1, 0])  # the wrap-around gap
            for j in range(s, e - 1):
                gap = int(g[j + 1, 0]) - int(g[j, 0])
                if gap > best:
                    best, lo, hi = gap, j + 1, j
        for side in range(2):
            pos = lo if side == 0 else hi
            i0, r0 = int(g[pos, 0]), g[pos, 1]
            d = -1 if side == 0 else 1
            cnt = 0
            skipped = False
            j = i0
            while cnt < _MAX_SHADOW_RAYS:
                j += d
                if j < 0 or j >= m:
                    if not full:
                        cnt = _MAX_SHADOW_RAYS  # the edge of the field of view
                        break
                    j = j + m if j < 0 else j - m  # j % m for a step of one (no division)
                if hit[j] and ranges[j] < r0 - tol:
                    cnt += 1
                elif not hit[j] and cnt == 0 and not skipped:
                    skipped = True
                else:
                    break
            out[c, side] = cnt * r0 * step
    return out


def cluster_points(
    points: ArrayLike,
    *,
    link_m: float = 3.0,
    min_points: int = 1,
    land: LandMask | None = None,
    coast_margin_m: float = 2.0,
    t_s: float = 0.0,
) -> Clusters:
    """Single-linkage clustering of unordered points (k-d tree + connected components).

    Parameters
    ----------
    points : array_like, shape (m, 2)
        ``[north_m, east_m]`` [m]; non-finite rows are dropped and counted.
    link_m : float, default 3.0
        Link distance [m], > 0.
    min_points : int, default 1
        Smaller clusters are dropped and counted.
    land : LandMask or None
        Coast for coast removal.
    coast_margin_m : float, default 2.0
        Returns within this distance of the shore are coast [m].
    t_s : float
        Time recorded in the result [s].

    Returns
    -------
    Clusters
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    if not link_m > 0:
        raise ParameterError(f"link_m must be > 0 m, actually: {link_m!r}")
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise StateError(f"points must have shape (m, 2) [north_m, east_m], actually: {p.shape}")
    fin = np.isfinite(p).all(axis=1)
    p = p[fin]
    n0 = p.shape[0]
    p, _ = _coast_filter(p, land, coast_margin_m)
    if p.shape[0] == 0:
        return Clusters(points=p.reshape(0, 2), offsets=np.zeros(1, np.int64), t_s=float(t_s),
                        n_coast=n0, n_invalid=int((~fin).sum()))
    pairs = cKDTree(p).query_pairs(link_m, output_type="ndarray")
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(p), len(p)))
    _, labels = connected_components(g, directed=False)
    q, off, small = _group(p, labels.astype(np.int64), int(min_points))
    return Clusters(points=q, offsets=off, t_s=float(t_s), n_coast=n0 - p.shape[0],
                    n_invalid=int((~fin).sum()), n_small=small)


def split_clusters(clusters: Clusters, centres: ArrayLike, reach_m: ArrayLike, *,
                   min_separation_m: float = 10.0, anchored: ArrayLike | None = None,
                   course_rad: ArrayLike | None = None, semi_axes_m: ArrayLike | None = None,
                   ) -> tuple[Clusters, int]:
    """Split clusters that two or more predicted vessels fall into (known positions split
    what the beam geometry could not: vessels closer than the segmentation's resolution).

    Each vessel is a footprint: the box of ``semi_axes_m`` (along, across) turned to
    ``course_rad`` about its centre (a point when not given). A vessel *claims* a
    cluster when some return of the cluster lies within ``reach_m`` of its footprint (its
    position uncertainty). A cluster claimed by two or more vessels at least
    ``min_separation_m`` apart is cut into one piece per vessel, each return going to
    the nearest footprint (inside several: the nearest centre). The pieces keep the
    occlusion shadow of the original cluster's outer ends; the ends at a cut get none.

    Parameters
    ----------
    clusters : Clusters
        One scan's clusters.
    centres : array_like, shape (p, 2)
        Predicted vessel centres ``[north_m, east_m]`` [m] (e.g. the AIS-tied tracks).
    reach_m : array_like, shape (p,)
        How far from its footprint a vessel's returns may lie [m], >= 0.
    min_separation_m : float
        Centres closer than this [m] are one claim (duplicates of one vessel).
    anchored : array_like of bool, shape (p,), optional
        When given, a cluster is split only if one of its claims is anchored (a position
        with independent evidence, e.g. an AIS report: two tracks from LiDAR alone may be
        duplicates of one hull).
    course_rad : array_like, shape (p,), optional
        Hull axis of each vessel from north, clockwise [rad].
    semi_axes_m : array_like, shape (p, 2), optional
        Half-length and half-beam of each vessel [m] (with ``course_rad``).

    Returns
    -------
    Clusters
        The clusters, split ones replaced by their pieces (in place of the original).
    int
        How many clusters were split.
    """
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    reach = np.broadcast_to(np.asarray(reach_m, dtype=np.float64), (c.shape[0],))
    anc = None if anchored is None else np.broadcast_to(np.asarray(anchored, dtype=bool), (c.shape[0],))
    p_ = c.shape[0]
    if course_rad is None or semi_axes_m is None:
        hdg, semi = np.zeros(p_), np.zeros((p_, 2))
    else:
        hdg = np.broadcast_to(np.asarray(course_rad, dtype=np.float64), (p_,))
        semi = np.broadcast_to(np.asarray(semi_axes_m, dtype=np.float64), (p_, 2))

    def box_distance(pts: NDArray[np.float64], js: NDArray[np.int64]) -> NDArray[np.float64]:
        """(m, len(js)) distances [m] of the points to the vessels' footprints."""
        dn = pts[:, None, 0] - c[None, js, 0]
        de = pts[:, None, 1] - c[None, js, 1]
        ch, sh = np.cos(hdg[js])[None, :], np.sin(hdg[js])[None, :]
        s_ = np.maximum(np.abs(dn * ch + de * sh) - semi[None, js, 0], 0.0)
        t_ = np.maximum(np.abs(-dn * sh + de * ch) - semi[None, js, 1], 0.0)
        return np.hypot(s_, t_)

    k = len(clusters)
    if k == 0 or c.shape[0] < 2:
        return clusters, 0
    # cheap pre-selection on bounding circles: (k, p)
    cen = clusters.centroids
    owner = np.repeat(np.arange(k), clusters.sizes)
    rad = np.zeros(k)
    np.maximum.at(rad, owner, np.hypot(*(clusters.points - cen[owner]).T))
    dc = np.hypot(cen[:, None, 0] - c[None, :, 0], cen[:, None, 1] - c[None, :, 1])
    cand = dc <= rad[:, None] + reach[None, :] + np.hypot(semi[:, 0], semi[:, 1])[None, :]
    multi = np.flatnonzero(cand.sum(axis=1) >= 2)
    if multi.size == 0:
        return clusters, 0
    pieces: dict[int, list[tuple[NDArray[np.float64], float, float]]] = {}
    for i in multi.tolist():
        pts = clusters[i]
        js = np.flatnonzero(cand[i])
        js = js[(box_distance(pts, js) <= reach[js][None, :]).any(axis=0)]  # claims: a return within reach
        # one claim per place: a centre within min_separation of an earlier one is dropped
        keep: list[int] = []
        for j in js.tolist():
            if all(np.hypot(*(c[j] - c[q])) >= min_separation_m for q in keep):
                keep.append(j)
        if len(keep) < 2 or (anc is not None and not anc[keep].any()):
            continue
        kk = np.array(keep)
        d = np.hypot(pts[:, None, 0] - c[None, kk, 0], pts[:, None, 1] - c[None, kk, 1])
        lab = np.argmin(box_distance(pts, kk) * 1e6 + d, axis=1)  # nearest footprint, then centre
        sh = np.zeros(2) if clusters.end_shadow_m is None else clusters.end_shadow_m[i]
        parts = []
        for q in range(len(keep)):
            sel = np.flatnonzero(lab == q)
            if sel.size == 0:
                continue
            # points are in ray order: the piece holding the first (last) return keeps
            # the cluster's lower (higher) end
            parts.append((pts[sel], float(sh[0]) if sel[0] == 0 else 0.0,
                          float(sh[1]) if sel[-1] == len(pts) - 1 else 0.0))
        if len(parts) >= 2:
            pieces[i] = parts
    if not pieces:
        return clusters, 0
    arrs: list[NDArray[np.float64]] = []
    shadows: list[tuple[float, float]] = []
    old_sh = clusters.end_shadow_m
    for i in range(k):
        if i in pieces:
            for p, s0, s1 in pieces[i]:
                arrs.append(p)
                shadows.append((s0, s1))
        else:
            arrs.append(clusters[i])
            shadows.append((0.0, 0.0) if old_sh is None else (float(old_sh[i, 0]), float(old_sh[i, 1])))
    pts = np.concatenate(arrs)
    off = np.concatenate([[0], np.cumsum([len(a) for a in arrs])]).astype(np.int64)
    out = replace(clusters, points=pts, offsets=off,
                  end_shadow_m=None if old_sh is None else np.array(shadows, dtype=np.float64))
    return out, len(pieces)
