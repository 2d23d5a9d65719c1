"""Measurement models: LiDAR clusters -> fitted centres, AIS reports -> position and velocity.

**LiDAR.** Each cluster gets a Halir–Flusser ellipse fit; its centre is the position
measurement. The covariance is built in the line-of-sight frame of the sensor,

.. math::

    R = U \\operatorname{diag}(\\sigma_{los}^2, \\sigma_{cross}^2) U^T, \\quad
    \\sigma_{los}^2 = \\sigma_r^2 + \\sigma_{fit}^2 + (g_d\\, b)^2
                      + \\big(k\\, a\\, (1 - c/\\pi)_+\\big)^2, \\quad
    \\sigma_{cross}^2 = (r \\sigma_\\theta)^2 + \\sigma_{fit}^2 + (g_e\\, a)^2,

with ``a, b`` the fitted semi-axes, ``c`` the arc coverage and ``U`` the rotation to the
bearing. A hull seen from one point shows at most its near half, so the fitted centre is
uncertain along the line of sight by about the unseen depth (for a pointed-bow hull the fit
sits on average 0.6 half-beams toward the sensor, measured in docs/tracking.md), and across
it by the uncertain ends; low coverage (a corner, a flank) inflates the line of sight
further instead of trusting the fit blindly. A cluster whose fit fails (< 5 points,
collinear, no ellipse) or is implausible (coverage below ``min_coverage_rad``, a needle
``b < needle_ratio a``, a semi-axis beyond twice the cluster's half-width or beyond
``max_semi_axis_m``, a centre far from the points) falls back to its centroid, with a few
visible half-widths as the line-of-sight spread (a hull seen end-on is ~4 times deeper
than wide).

**AIS.** A report ``(mmsi, t_s, north_m, east_m, sog_m_s, cog_rad)`` becomes
:math:`z = [n, e, \\mathrm{sog}\\cos\\mathrm{cog}, \\mathrm{sog}\\sin\\mathrm{cog}]` with the
velocity covariance :math:`J \\operatorname{diag}(\\sigma_{sog}^2, \\sigma_{cog}^2) J^T`
(:math:`J` the Jacobian of the polar-to-Cartesian map), propagated to the tick time with its
own velocity. A report without SOG/COG carries no velocity information (a huge velocity
variance). Reports with a non-finite or out-of-range field or older than ``max_age_s`` are
rejected and counted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from asvtwin.errors import ParameterError
from asvtwin.tracking.clustering import Clusters
from asvtwin.tracking.ellipse import EllipseFits, fit_ellipses

__all__ = [
    "AisMeasurement",
    "AisMeasurements",
    "AisModel",
    "LidarMeasurements",
    "LidarModel",
    "ais_measurements",
    "lidar_measurements",
]

_F8 = NDArray[np.float64]
_NO_VELOCITY_VAR = 1.0e6  # [m²/s²]: "no velocity information"


@dataclass(frozen=True)
class AisMeasurement:
    """One AIS position report in the local frame (what the AIS source hands the tracker).

    Attributes
    ----------
    mmsi : int
        Maritime Mobile Service Identity.
    t_s : float
        Time of the report [s] since the scene start.
    north_m, east_m : float
        Position in the local NED frame [m].
    sog_m_s : float
        Speed over ground [m/s] (NaN when not available).
    cog_rad : float
        Course over ground from north, clockwise [rad] (NaN when not available).
    """

    mmsi: int
    t_s: float
    north_m: float
    east_m: float
    sog_m_s: float = float("nan")
    cog_rad: float = float("nan")


def _positive(cls: str, name: str, value: float, lo_ok: bool = False) -> None:
    ok = (value >= 0.0 if lo_ok else value > 0.0) and np.isfinite(value)
    if not ok:
        raise ParameterError(f"{cls}.{name} must be finite and {'>=' if lo_ok else '>'} 0, actually: {value!r}")


@dataclass(frozen=True)
class LidarModel:
    """Noise of the LiDAR centre measurement.

    Attributes
    ----------
    range_std_m : float
        Range noise of one return [m].
    bearing_std_rad : float
        Bearing noise of one return [rad].
    fit_floor_m : float
        Floor of the fit's own spread [m] (hull shape is not an ellipse).
    coverage_gain : float
        ``k`` of the line-of-sight inflation for low arc coverage [-].
    depth_gain : float
        ``g_d``: line-of-sight spread per metre of fitted semi-minor axis [-].
    end_gain : float
        ``g_e``: cross-range spread per metre of fitted semi-major axis [-].
    min_coverage_rad : float
        Fits covering less arc than this are not used [rad].
    needle_ratio : float
        A fit with ``b < needle_ratio * a`` is a straight face (a stern seen end-on, a
        flank) whose depth is unknown: the centroid is used instead [-].
    needle_depth_gain : float
        For the centroid: line-of-sight spread = ``max(needle_depth_gain * h,
        default_half_depth_m)`` with ``h`` the visible half-width of the cluster [-].
    default_half_depth_m : float
        Unseen half depth of a hull assumed when a fit is unusable [m].
    max_semi_axis_m : float
        Fits with a larger semi-major axis are implausible for a vessel [m].
    method : {"halir_flusser", "mlr"}
        The ellipse fit.
    """

    range_std_m: float = 0.05
    bearing_std_rad: float = 0.002
    fit_floor_m: float = 1.0
    coverage_gain: float = 0.5
    depth_gain: float = 4.0
    end_gain: float = 0.15
    min_coverage_rad: float = 2.0
    needle_ratio: float = 0.15
    needle_depth_gain: float = 8.0
    default_half_depth_m: float = 8.0
    max_semi_axis_m: float = 200.0
    method: str = "halir_flusser"

    def __post_init__(self) -> None:
        for name in ("range_std_m", "bearing_std_rad", "coverage_gain", "depth_gain", "end_gain", "min_coverage_rad",
                     "needle_ratio", "needle_depth_gain"):
            _positive("LidarModel", name, getattr(self, name), lo_ok=True)
        for name in ("fit_floor_m", "default_half_depth_m", "max_semi_axis_m"):
            _positive("LidarModel", name, getattr(self, name))


@dataclass(frozen=True)
class LidarMeasurements:
    """Position measurements from one scan's clusters.

    Attributes
    ----------
    z : ndarray, shape (k, 2)
        Measured centres ``[north_m, east_m]`` [m].
    R : ndarray, shape (k, 2, 2)
        Covariances [m²].
    fits : EllipseFits
        The ellipse fits of the clusters.
    used_fit : ndarray of bool, shape (k,)
        True where the fit's centre was used, False where the centroid was.
    """

    z: _F8
    R: _F8
    fits: EllipseFits
    used_fit: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.z.shape[0])


def _los_cov(z: _F8, origin: _F8, var_los: _F8, var_cross: _F8) -> _F8:
    d = z - origin
    rng = np.hypot(d[:, 0], d[:, 1])
    u = np.where(rng[:, None] > 1e-9, d / np.maximum(rng, 1e-9)[:, None], np.array([1.0, 0.0]))
    c, s = u[:, 0], u[:, 1]
    R = np.empty((z.shape[0], 2, 2))
    R[:, 0, 0] = c * c * var_los + s * s * var_cross
    R[:, 1, 1] = s * s * var_los + c * c * var_cross
    R[:, 0, 1] = R[:, 1, 0] = c * s * (var_los - var_cross)
    return R


def lidar_measurements(clusters: Clusters, model: LidarModel | None = None) -> LidarMeasurements:
    """Fit every cluster and turn it into a position measurement with its covariance.

    Parameters
    ----------
    clusters : Clusters
        Clusters of one scan (``origin_ned`` is the sensor position; when NaN the
        covariance is isotropic).
    model : LidarModel, optional
        Noise settings.

    Returns
    -------
    LidarMeasurements
    """
    mdl = model or LidarModel()
    fits = fit_ellipses(clusters.points, clusters.offsets, method=mdl.method)
    cen = clusters.centroids
    a, b = fits.semi_axes[:, 0], fits.semi_axes[:, 1]
    if len(cen):
        dev = clusters.points - np.repeat(cen, clusters.sizes, axis=0)
        d2 = (dev**2).sum(axis=1)
        ext = np.sqrt(np.add.reduceat(d2, clusters.offsets[:-1]) / clusters.sizes)  # rms spread
        half = np.sqrt(np.maximum.reduceat(d2, clusters.offsets[:-1]))  # visible half-width
    else:
        ext = half = np.empty(0)
    with np.errstate(invalid="ignore"):
        use = (fits.ok & (a <= mdl.max_semi_axis_m) & (fits.arc_coverage_rad >= mdl.min_coverage_rad)
               & (a <= 2.0 * half + mdl.fit_floor_m) & (b >= mdl.needle_ratio * a)
               & (np.hypot(*(fits.centre - cen).T) <= a + mdl.fit_floor_m))
    z = np.where(use[:, None], fits.centre, cen)
    origin = np.asarray(clusters.origin_ned, float)
    if not np.isfinite(origin).all():
        origin = z.mean(axis=0) - np.array([1.0e4, 0.0]) if len(z) else np.zeros(2)
    r = np.hypot(*(z - origin).T)
    cov = np.nan_to_num(fits.arc_coverage_rad, nan=0.0)
    resid = np.nan_to_num(fits.residual_m, nan=0.0)
    var_fit = mdl.fit_floor_m**2 + resid**2
    a0, b0 = np.nan_to_num(a), np.nan_to_num(b)
    # fitted centre: the unseen depth (~ the semi-minor axis), more for low coverage
    los_fit = (mdl.range_std_m**2 + var_fit + (mdl.depth_gain * b0) ** 2
               + (mdl.coverage_gain * a0 * np.clip(1.0 - cov / np.pi, 0.0, 1.0)) ** 2)
    # centroid (no usable fit, or a straight face): depth up to a few visible half-widths
    los_cen = (mdl.range_std_m**2 + mdl.fit_floor_m**2
               + np.maximum(mdl.needle_depth_gain * half, mdl.default_half_depth_m) ** 2)
    var_los = np.where(use, los_fit, los_cen)
    var_cross = (r * mdl.bearing_std_rad) ** 2 + np.where(use, var_fit + (mdl.end_gain * a0) ** 2, mdl.fit_floor_m**2 + ext**2)
    R = _los_cov(z, origin, var_los, var_cross)
    return LidarMeasurements(z=z, R=R, fits=fits, used_fit=use)


@dataclass(frozen=True)
class AisModel:
    """Noise and freshness of AIS reports.

    Attributes
    ----------
    position_std_m : float
        GNSS position noise per axis [m].
    sog_std_m_s : float
        Speed-over-ground noise [m/s].
    cog_std_rad : float
        Course-over-ground noise [rad].
    accel_q : float
        Acceleration spectral density used to age a report to the tick time [m²/s³].
    max_age_s : float
        Reports older than this at the tick are dropped [s].
    max_future_s : float
        Reports stamped later than the tick by more than this are dropped [s].
    """

    position_std_m: float = 5.0
    sog_std_m_s: float = 0.1
    cog_std_rad: float = float(np.deg2rad(2.0))
    accel_q: float = 0.05
    max_age_s: float = 30.0
    max_future_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("position_std_m", "sog_std_m_s", "cog_std_rad", "max_age_s"):
            _positive("AisModel", name, getattr(self, name))
        for name in ("accel_q", "max_future_s"):
            _positive("AisModel", name, getattr(self, name), lo_ok=True)


@dataclass(frozen=True)
class AisMeasurements:
    """AIS reports of one tick as arrays (one row per accepted report, latest per MMSI).

    Attributes
    ----------
    mmsi : ndarray of int64, shape (k,)
    z : ndarray, shape (k, 4)
        ``[north_m, east_m, v_north_m_s, v_east_m_s]`` at the tick time.
    R : ndarray, shape (k, 4, 4)
        Covariances.
    n_rejected : int
        Reports dropped as malformed (non-finite position or time, negative SOG).
    n_stale : int
        Reports dropped as too old or from the future.
    """

    mmsi: NDArray[np.int64]
    z: _F8
    R: _F8
    n_rejected: int = 0
    n_stale: int = 0

    def __len__(self) -> int:
        return int(self.mmsi.shape[0])


def ais_measurements(reports: Sequence[AisMeasurement], t_s: float, model: AisModel | None = None) -> AisMeasurements:
    """Convert AIS reports to measurements at the tick time ``t_s``.

    Parameters
    ----------
    reports : sequence of AisMeasurement
        Reports received since the last tick (any order; several per MMSI allowed: the
        latest valid one is used).
    t_s : float
        Tick time [s].
    model : AisModel, optional
        Noise settings.

    Returns
    -------
    AisMeasurements
    """
    mdl = model or AisModel()
    if not reports:
        return AisMeasurements(np.empty(0, np.int64), np.empty((0, 4)), np.empty((0, 4, 4)))
    arr = np.array([(r.mmsi, r.t_s, r.north_m, r.east_m, r.sog_m_s, r.cog_rad) for r in reports], dtype=np.float64)
    mmsi = arr[:, 0].astype(np.int64)  # MMSIs are 9 digits: exact in float64
    tr, n, e, sog, cog = arr[:, 1:].T
    good = np.isfinite(tr) & np.isfinite(n) & np.isfinite(e) & (mmsi > 0) & ~(sog < 0.0)
    age = t_s - tr
    fresh = (age <= mdl.max_age_s) & (age >= -mdl.max_future_s)
    n_rej = int((~good).sum())
    n_stale = int((good & ~fresh).sum())
    keep = np.flatnonzero(good & fresh)
    # latest report per MMSI
    order = keep[np.lexsort((tr[keep], mmsi[keep]))]
    last = np.r_[mmsi[order][1:] != mmsi[order][:-1], True] if order.size else np.zeros(0, bool)
    idx = order[last]
    k = idx.size
    has_v = np.isfinite(sog[idx]) & np.isfinite(cog[idx])
    s, c = np.where(has_v, sog[idx], 0.0), np.where(has_v, cog[idx], 0.0)
    vn, ve = s * np.cos(c), s * np.sin(c)
    # J = d(vn, ve)/d(sog, cog)
    J = np.empty((k, 2, 2))
    J[:, 0, 0], J[:, 0, 1] = np.cos(c), -s * np.sin(c)
    J[:, 1, 0], J[:, 1, 1] = np.sin(c), s * np.cos(c)
    Rv = J @ np.diag([mdl.sog_std_m_s**2, mdl.cog_std_rad**2]) @ J.transpose(0, 2, 1)
    Rv += (mdl.sog_std_m_s**2 * 1e-2) * np.eye(2)  # keep it regular at SOG = 0
    Rv[~has_v] = _NO_VELOCITY_VAR * np.eye(2)
    dt = age[idx]
    z = np.column_stack([n[idx] + vn * dt, e[idx] + ve * dt, vn, ve])
    R = np.zeros((k, 4, 4))
    # aging by dt: position picks up the velocity uncertainty and the acceleration noise
    vel_var = np.where(has_v, 1.0, 0.0)[:, None, None] * Rv * (dt**2)[:, None, None]
    R[:, :2, :2] = mdl.position_std_m**2 * np.eye(2) + vel_var + (mdl.accel_q * np.abs(dt) ** 3 / 3.0)[:, None, None] * np.eye(2)
    R[:, 2:, 2:] = Rv + (mdl.accel_q * np.abs(dt))[:, None, None] * np.eye(2)
    cross = np.where(has_v, 1.0, 0.0)[:, None, None] * Rv * dt[:, None, None]
    R[:, :2, 2:] = cross
    R[:, 2:, :2] = cross.transpose(0, 2, 1)
    return AisMeasurements(mmsi=mmsi[idx], z=z, R=R, n_rejected=n_rej, n_stale=n_stale)
