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
   run of bearings), which makes it O(m) in a numba union–find. Unordered points use a k-d
   tree (scipy) and connected components.

Non-finite points are dropped and counted; nothing here raises on data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.geo.land import LandMask
from asvtwin.sensors.lidar import LidarScan

__all__ = ["ClusterConfig", "Clusters", "cluster_points", "cluster_scan"]



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
    """

    link_m: float = 3.0
    incidence_rad: float = float(np.deg2rad(10.0))
    range_std_m: float = 0.05
    max_link_m: float = 25.0
    window: int = 4
    min_points: int = 1
    coast_margin_m: float = 2.0

    def __post_init__(self) -> None:
        for name, ok, expected in (
            ("link_m", 0.0 < self.link_m < np.inf, "finite and > 0 m"),
            ("incidence_rad", 0.0 < self.incidence_rad <= 0.5 * np.pi, "in (0, π/2]"),
            ("range_std_m", 0.0 <= self.range_std_m < np.inf, "finite and >= 0 m"),
            ("max_link_m", self.link_m <= self.max_link_m < np.inf, "finite and >= link_m"),
            ("window", int(self.window) >= 1, ">= 1"),
            ("min_points", int(self.min_points) >= 1, ">= 1"),
            ("coast_margin_m", 0.0 <= self.coast_margin_m < np.inf, "finite and >= 0 m"),
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
    """

    points: _F8
    offsets: NDArray[np.int64]
    t_s: float = 0.0
    origin_ned: _F8 = field(default_factory=lambda: np.full(2, np.nan))
    n_coast: int = 0
    n_invalid: int = 0
    n_small: int = 0

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
def _link_ordered(pts, r, ang, link_m, lam, noise, window, max_link):  # type: ignore[no-untyped-def]
    """Union–find labels of angularly ordered points; neighbours within ``window``, cyclic."""
    n = pts.shape[0]
    parent = np.arange(n)
    for i in range(n):
        for w in range(1, min(window, n - 1) + 1):
            j = (i + w) % n
            d2 = (pts[i, 0] - pts[j, 0]) ** 2 + (pts[i, 1] - pts[j, 1]) ** 2
            linked = d2 <= link_m * link_m
            if not linked:
                dphi = abs(ang[j] - ang[i])
                if dphi > np.pi:
                    dphi = 2.0 * np.pi - dphi % (2.0 * np.pi)
                if dphi < 0.5 * lam:  # adaptive breakpoint detector (not across wide gaps)
                    lim = min(min(r[i], r[j]) * np.sin(dphi) / np.sin(lam - dphi) + noise, max_link)
                    linked = d2 <= lim * lim
            if linked:
                ri, rj = _find(parent, i), _find(parent, j)
                if ri != rj:
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
    """The returns with a hit, a finite point and a finite range, compacted: (pts, r, ang, n_invalid)."""
    n = pts.shape[0]
    keep = np.zeros(n, np.bool_)
    k, n_hit = 0, 0
    for i in range(n):
        if hit[i]:
            n_hit += 1
            if np.isfinite(pts[i, 0]) and np.isfinite(pts[i, 1]) and np.isfinite(r[i]):
                keep[i] = True
                k += 1
    p, rr, aa = np.empty((k, 2)), np.empty(k), np.empty(k)
    j = 0
    for i in range(n):
        if keep[i]:
            p[j, 0], p[j, 1], rr[j], aa[j] = pts[i, 0], pts[i, 1], r[i], ang[i]
            j += 1
    return p, rr, aa, n_hit - k


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
    pts, r, ang, n_invalid = _valid_returns(
        np.ascontiguousarray(scan.points_ned, dtype=np.float64), np.ascontiguousarray(scan.ranges_m, dtype=np.float64),
        np.ascontiguousarray(scan.angles_rad, dtype=np.float64), np.ascontiguousarray(scan.hit, dtype=np.bool_))
    n_before = pts.shape[0]
    if land is not None and n_before:
        pts, water = _coast_filter(pts, land, cfg.coast_margin_m)
        pts, r, ang = np.ascontiguousarray(pts), r[water], ang[water]
    labels = _link_ordered(pts, r, ang, cfg.link_m, cfg.incidence_rad,
                           3.0 * cfg.range_std_m, int(cfg.window), cfg.max_link_m)
    p, off, small = _group_kernel(pts, labels, int(cfg.min_points))
    return Clusters(points=p, offsets=off, t_s=float(scan.t_s), origin_ned=np.array(scan.origin_ned, dtype=float),
                    n_coast=n_before - pts.shape[0], n_invalid=int(n_invalid), n_small=int(small))


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
