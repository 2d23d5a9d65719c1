"""A synthetic 2-D LiDAR on the own ship: rays against target hulls and the coast.

One scan is ``m`` rays from the own ship's position, at bearings relative to its heading
(a full circle or a sector centred on the bow). Each ray is a half-line
:math:`o + t\\,(\\cos a, \\sin a)` in ``(north, east)``, ``a`` from north clockwise; its
return is the nearest of

- the target hull edges (:func:`asvtwin.sensors.hull.hull_polygons`), all rays against all
  targets in one numba kernel, each target first culled by its bounding circle, and
- the coast, through :meth:`asvtwin.geo.LandMask.cast_rays` (a grid of coast segments).

Noise model (all draws from the ``Generator`` passed in, the same number of draws for every
scan so a seed gives the same sequence whatever the scene): the beam leaves at the nominal
bearing plus a Gaussian angle error but is reported at the nominal bearing; the range gets
Gaussian noise; each return drops out with a fixed probability. The scan also records which
target (or the coast) each ray really hit: ground truth for tests, never for the tracker.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.geo.land import LandMask
from asvtwin.sensors.hull import HULL_SHAPES, _check_dims, _polygons, hull_segments, target_poses

__all__ = ["HIT_COAST", "HIT_NONE", "Lidar", "LidarConfig", "LidarScan"]


#: ``LidarScan.hit_id`` of a ray that returned nothing.
HIT_NONE = -1
#: ``LidarScan.hit_id`` of a ray that hit the coast.
HIT_COAST = -2


@njit(cache=True)
def _cast_hulls(on, oe, cosa, sina, rmax, segs, centres, radii):  # type: ignore[no-untyped-def]
    """First hit of each ray on the hull edges: (range [m] or inf, target index or -1)."""
    m = cosa.shape[0]
    best = np.full(m, np.inf)
    who = np.full(m, -1, np.int64)
    for r in range(m):
        dn, de = cosa[r], sina[r]
        for k in range(segs.shape[0]):
            wn, we = centres[k, 0] - on, centres[k, 1] - oe
            tc = wn * dn + we * de  # distance along the ray to the centre's foot
            rho = radii[k]
            if tc + rho < 0.0 or tc - rho > min(best[r], rmax):
                continue
            if wn * wn + we * we - tc * tc > rho * rho:
                continue  # the ray misses the bounding circle
            for s in range(segs.shape[1]):
                an, ae = segs[k, s, 0] - on, segs[k, s, 1] - oe
                en, ee = segs[k, s, 2] - segs[k, s, 0], segs[k, s, 3] - segs[k, s, 1]
                den = dn * ee - de * en
                if den == 0.0:
                    continue
                t = (an * ee - ae * en) / den
                u = (an * de - ae * dn) / den
                if 0.0 <= t <= rmax and 0.0 <= u <= 1.0 and t < best[r]:
                    best[r] = t
                    who[r] = k
    return best, who


@njit(cache=True)
def _finish_scan(on, oe, c, s, rng_t, who, coast, noise, dropped, min_range):  # type: ignore[no-untyped-def]
    """The returns of one scan from the hulls' first hits ``rng_t``/``who``, the coast's
    ranges ``coast`` (empty: no coast) and the draws: (ranges, hit, points, hit_id).

    The same operations, element by element, as the NumPy expressions they replace
    (nearer coast wins; a return is finite, at least ``min_range`` and not dropped; its
    range is ``max(r + noise, 0)``; its point ``o + range * (cos, sin)`` of the nominal
    bearing), so the numbers are the same to the bit."""
    m = rng_t.shape[0]
    ranges = np.empty(m)
    hit = np.empty(m, np.bool_)
    pts = np.empty((m, 2))
    out = np.empty(m, np.int64)
    with_coast = coast.shape[0] == m
    for i in range(m):
        r = rng_t[i]
        k = who[i]
        if with_coast and coast[i] < r:
            r = coast[i]
            k = HIT_COAST
        h = np.isfinite(r) and r >= min_range and not dropped[i]
        hit[i] = h
        if h:
            v = r + noise[i]
            v = max(v, 0.0)
            ranges[i] = v
            out[i] = k
            pts[i, 0] = on + v * c[i]
            pts[i, 1] = oe + v * s[i]
        else:
            ranges[i] = np.inf
            out[i] = HIT_NONE
            pts[i, 0] = np.nan
            pts[i, 1] = np.nan
    return ranges, hit, pts, out


_NO_COAST = np.empty(0)

#: Slack [m] of the range cull: a target whose bounding circle lies wholly beyond the
#: maximum range plus this cannot return a ray, so its hull is not built at all.
_CULL_SLACK_M = 1.0


@dataclass(frozen=True)
class LidarConfig:
    """Configuration of the synthetic LiDAR.

    Attributes
    ----------
    n_rays : int
        Rays per scan, 1 to 3600 (180 to 3600 over 360° are typical).
    fov_rad : float
        Field of view [rad], in (0, 2π]; centred on the bow; 2π is a full circle.
    max_range_m : float
        Maximum range [m], > 0.
    min_range_m : float
        Returns closer than this are discarded (own superstructure) [m], >= 0.
    range_std_m : float
        Standard deviation of the Gaussian range noise [m], >= 0.
    angle_std_rad : float
        Standard deviation of the beam's bearing error [rad], >= 0.
    dropout_prob : float
        Probability that a return is lost, in [0, 1).
    hull_shape : {"pointed", "ellipse"}
        Target hull outline, see :mod:`asvtwin.sensors.hull`.
    """

    n_rays: int = 360
    fov_rad: float = 2.0 * np.pi
    max_range_m: float = 500.0
    min_range_m: float = 0.5
    range_std_m: float = 0.05
    angle_std_rad: float = 0.001
    dropout_prob: float = 0.0
    hull_shape: str = "pointed"

    def __post_init__(self) -> None:
        checks = [
            ("n_rays", self.n_rays, 1 <= int(self.n_rays) <= 3600 and int(self.n_rays) == self.n_rays, "an integer in [1, 3600]"),
            ("fov_rad", self.fov_rad, 0.0 < self.fov_rad <= 2.0 * np.pi + 1e-12, "in (0, 2π]"),
            ("max_range_m", self.max_range_m, 0.0 < self.max_range_m < np.inf, "finite and > 0"),
            ("min_range_m", self.min_range_m, 0.0 <= self.min_range_m < self.max_range_m, "in [0, max_range_m)"),
            ("range_std_m", self.range_std_m, 0.0 <= self.range_std_m < np.inf, "finite and >= 0"),
            ("angle_std_rad", self.angle_std_rad, 0.0 <= self.angle_std_rad < 0.5, "in [0, 0.5)"),
            ("dropout_prob", self.dropout_prob, 0.0 <= self.dropout_prob < 1.0, "in [0, 1)"),
            ("hull_shape", self.hull_shape, self.hull_shape in HULL_SHAPES, f"one of {HULL_SHAPES}"),
        ]
        for name, value, ok, expected in checks:
            if not ok:
                raise ParameterError(f"LidarConfig.{name} must be {expected}, actually: {value!r}")

    def relative_bearings(self) -> _F8:
        """Nominal ray bearings relative to the bow [rad], clockwise positive, shape (n_rays,)."""
        n = int(self.n_rays)
        if self.fov_rad >= 2.0 * np.pi - 1e-12:
            return -np.pi + 2.0 * np.pi * np.arange(n) / n
        if n == 1:
            return np.zeros(1)
        return np.linspace(-0.5 * self.fov_rad, 0.5 * self.fov_rad, n)


def _frozen(a: NDArray) -> NDArray:  # type: ignore[type-arg]
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class LidarScan:
    """One LiDAR scan as plain arrays (read-only).

    Attributes
    ----------
    t_s : float
        Scan time [s] since the scene start.
    origin_ned : ndarray, shape (2,)
        Sensor position ``[north_m, east_m]`` [m].
    heading_rad : float
        Own-ship heading at the scan [rad].
    angles_rad : ndarray, shape (m,)
        Reported bearing of each ray in NED [rad] (from north, clockwise).
    ranges_m : ndarray, shape (m,)
        Measured range [m]; ``inf`` where the ray returned nothing.
    hit : ndarray of bool, shape (m,)
        Whether the ray returned.
    points_ned : ndarray, shape (m, 2)
        Return points ``[north_m, east_m]`` [m]; NaN where nothing returned.
    hit_id : ndarray of int64, shape (m,)
        Ground truth: index of the target hit, :data:`HIT_COAST` or :data:`HIT_NONE`.
    max_range_m : float
        The sensor's maximum range [m].
    """

    t_s: float
    origin_ned: _F8
    heading_rad: float
    angles_rad: _F8
    ranges_m: _F8
    hit: NDArray[np.bool_]
    points_ned: _F8
    hit_id: NDArray[np.int64]
    max_range_m: float

    @property
    def points(self) -> _F8:
        """The returned points only, shape (k, 2) [m]."""
        return self.points_ned[self.hit]


class Lidar:
    """The synthetic LiDAR: casts one scan per call.

    Parameters
    ----------
    config : LidarConfig, optional
        Sensor configuration (defaults: 360 rays, 500 m, 5 cm range noise).

    Examples
    --------
    >>> import numpy as np
    >>> lidar = Lidar(LidarConfig(n_rays=360, range_std_m=0.0, angle_std_rad=0.0))
    >>> scan = lidar.scan(np.zeros(6), np.array([[100.0, 0, 0, 0, 0, 0]]), 20.0, 5.0,
    ...                   None, np.random.default_rng(0))
    >>> round(float(scan.ranges_m[180]), 3)  # the ray dead ahead hits the stern at 90 m
    90.0
    """

    def __init__(self, config: LidarConfig | None = None) -> None:
        self.config = config or LidarConfig()
        self._rel = self.config.relative_bearings()

    def scan(
        self,
        own_state: ArrayLike,
        target_states: ArrayLike,
        length_m: ArrayLike,
        beam_m: ArrayLike,
        land: LandMask | None,
        rng: np.random.Generator,
        *,
        t_s: float = 0.0,
    ) -> LidarScan:
        """Cast one scan.

        Parameters
        ----------
        own_state : array_like, shape (6,)
            Own-ship state ``[x, y, psi, u, v, r]``; the sensor sits at ``(x, y)`` [m] and
            its bearings are relative to ``psi`` [rad].
        target_states : array_like, shape (n, 6) or (n, 4)
            Target states (see :func:`asvtwin.sensors.hull.target_poses`); n may be 0.
        length_m, beam_m : array_like, shape (n,)
            Target dimensions [m].
        land : LandMask or None
            The scene's coast; ``None`` for open sea.
        rng : numpy.random.Generator
            Source of the noise and dropout draws.
        t_s : float, default 0.0
            Scan time [s], recorded in the scan.

        Returns
        -------
        LidarScan
        """
        cfg = self.config
        own = np.asarray(own_state, dtype=np.float64).reshape(-1)
        if own.shape != (6,) or not np.isfinite(own).all():
            raise StateError(f"own_state must be a finite (6,) [x, y, psi, u, v, r], actually: {own!r}")
        o = own[:2].copy()
        nominal = own[2] + self._rel
        m = nominal.size
        # same draws every scan: bearing error, range noise, dropout
        true_a = nominal + cfg.angle_std_rad * rng.standard_normal(m)
        noise = cfg.range_std_m * rng.standard_normal(m)
        dropped = rng.random(m) < cfg.dropout_prob
        cosa, sina = np.cos(true_a), np.sin(true_a)

        rng_t = np.full(m, np.inf)
        who = np.full(m, HIT_NONE, np.int64)
        ts = np.asarray(target_states, dtype=np.float64)
        if ts.size:
            pose = target_poses(ts)
            L, B = _check_dims(length_m, beam_m, pose.shape[0])
            radii = 0.5 * np.hypot(L, B) + 1e-6
            # only the targets whose bounding circle reaches into range (the kernel would
            # skip the others ray by ray; their hulls need not be built): same returns
            near = np.flatnonzero(np.hypot(pose[:, 0] - o[0], pose[:, 1] - o[1]) - radii
                                  <= cfg.max_range_m + _CULL_SLACK_M)
            if near.size:
                pn = pose[near]
                segs = hull_segments(_polygons(pn, L[near], B[near], shape=cfg.hull_shape,
                                               bow_fraction=0.2, n_vertices=24))
                rng_t, w = _cast_hulls(o[0], o[1], cosa, sina, cfg.max_range_m, segs,
                                       np.ascontiguousarray(pn[:, :2]), radii[near])
                who = np.where(w >= 0, near[np.maximum(w, 0)], HIT_NONE)
        coast = land.cast_rays(o, true_a, cfg.max_range_m) if land is not None else _NO_COAST
        ranges, hit, pts, who = _finish_scan(
            o[0], o[1], np.cos(nominal), np.sin(nominal), rng_t, who,
            np.ascontiguousarray(coast, dtype=np.float64), noise, dropped,
            float(cfg.min_range_m))
        return LidarScan(
            t_s=float(t_s),
            origin_ned=_frozen(o),
            heading_rad=float(own[2]),
            angles_rad=_frozen(nominal),
            ranges_m=_frozen(ranges),
            hit=_frozen(hit),
            points_ned=_frozen(pts),
            hit_id=_frozen(who),
            max_range_m=float(cfg.max_range_m),
        )
