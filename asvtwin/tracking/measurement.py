"""Measurement models: LiDAR clusters -> hull centres, AIS reports -> position and velocity.

**LiDAR, default** (``LidarModel.centre = "hull_box"``): the centre of the hull from
what the sensor sees of it, :mod:`asvtwin.tracking.hull_model`; every cluster also gets a
Halir–Flusser ellipse fit for the hull's size. With a track's course as the hull axis,
:func:`hull_centres` measures again (the tracker does so after association).

**LiDAR, the paper's fitted centre** (``centre = "ellipse"``): the ellipse fit's centre
is the position measurement. The covariance is built in the line-of-sight frame of the sensor,

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

import itertools
import operator
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.checks import check_positive
from asvtwin.errors import ParameterError, StateError
from asvtwin.tracking.clustering import Clusters
from asvtwin.tracking.ellipse import _C1, EllipseFits, _method_code
from asvtwin.tracking.hull_model import hull_box_kernel, hull_box_pairs_kernel
from asvtwin.tracking.measurement_kernels import (
    ais_model_kernel,
    lidar_model_kernel,
    los_covariance,
)

__all__ = [
    "CENTRE_MODELS",
    "AisMeasurement",
    "AisMeasurementBatch",
    "AisMeasurements",
    "AisModel",
    "LidarMeasurements",
    "LidarModel",
    "ais_measurements",
    "hull_centres",
    "hull_centres_for_pairs",
    "lidar_measurements",
]


#: Centre measurement models of :class:`LidarModel`.
CENTRE_MODELS = ("hull_box", "ellipse")


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

    @classmethod
    def from_report(cls, report: Any, *, epoch_unix_s: float = 0.0) -> AisMeasurement:
        """From a validated AIS report (``asvtwin.sources.ais.AisReport``, read by field
        name): ``t_s = t_unix_s − epoch_unix_s``; "not available" (None) becomes NaN."""

        def num(v: float | None) -> float:
            return float("nan") if v is None else float(v)

        return cls(int(report.mmsi), float(report.t_unix_s) - epoch_unix_s,
                   float(report.north_m), float(report.east_m), num(report.sog_m_s),
                   num(report.cog_rad))


def _positive(cls: str, name: str, value: float, lo_ok: bool = False) -> None:
    check_positive(value, name, allow_zero=lo_ok, where=cls)


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
    centre : {"hull_box", "ellipse"}
        Which centre is the measurement: ``"hull_box"`` (default) models what the LiDAR
        sees of a hull (:mod:`asvtwin.tracking.hull_model`: the near side's offset to the
        centre from the visible extents and the aspect, the unseen depth bounded by the
        hull's proportions); ``"ellipse"`` is the paper's fitted-ellipse centre with the
        line-of-sight inflation above (biased towards the sensor: docs/tracking.md).
    angular_step_rad : float
        The LiDAR's angular step [rad]; 0 estimates it from each cluster (mean spacing).
    length_beam_ratio : tuple of float
        ``(ρ_min, ρ_max)``: range of hull length over beam [-] that bounds the unseen depth.
    tip_gap_rays : float
        Sampling gap at the near corner or bow tip, in ray spacings [-].
    gap_factor : float
        Safety factor on the sampling gap along a grazing face [-].
    bow_taper : float
        Fraction of the length taken by a tapering bow [-].
    taper_angles_rad : tuple of float
        Off-axis angles below / above which the bow's V is fully hidden / fully seen [rad].
    orientation_std_rad : float
        Orientation uncertainty of the rectangle fitted when the heading is unknown [rad].
    heading_floor_rad : float
        Floor of the heading's standard deviation when taken from a track's course
        (heading differs from course by the drift angle) [rad].
    centre_floor_m : float
        Isotropic floor of the centre's standard deviation [m].
    depth_persistence : float
        Scale of the unseen-depth variance, >= 1 [-]: that error repeats from scan to
        scan, so a filter fed every scan must see it as this many scans' worth (1: the
        single-scan covariance).
    max_hidden_m : float
        Most of a hull taken to continue unseen behind an occluder beside a cluster's end
        [m] (the occluder's shadow bounds it first; :attr:`Clusters.end_shadow_m`).
    known_size_tol, known_size_floor_m : float
        A hull's known length and beam (AIS static data: :meth:`Tracker.set_dimensions`)
        are taken to ± ``max(known_size_tol × size, known_size_floor_m)`` (AIS gives whole
        metres, from a reference point that is often approximate) [-], [m].
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
    centre: str = "hull_box"
    angular_step_rad: float = 0.0
    length_beam_ratio: tuple[float, float] = (2.5, 8.0)
    tip_gap_rays: float = 2.5
    gap_factor: float = 1.5
    bow_taper: float = 0.2
    taper_angles_rad: tuple[float, float] = (float(np.deg2rad(17.0)), float(np.deg2rad(45.0)))
    orientation_std_rad: float = float(np.deg2rad(5.0))
    heading_floor_rad: float = float(np.deg2rad(3.0))
    centre_floor_m: float = 0.3
    depth_persistence: float = 1.0
    max_hidden_m: float = 150.0
    known_size_tol: float = 0.1
    known_size_floor_m: float = 1.0

    def __post_init__(self) -> None:
        for name in ("range_std_m", "bearing_std_rad", "coverage_gain", "depth_gain", "end_gain", "min_coverage_rad",
                     "needle_ratio", "needle_depth_gain", "angular_step_rad", "tip_gap_rays", "orientation_std_rad",
                     "heading_floor_rad", "centre_floor_m", "known_size_tol", "known_size_floor_m"):
            _positive("LidarModel", name, getattr(self, name), lo_ok=True)
        _positive("LidarModel", "gap_factor", self.gap_factor)
        if not (np.isfinite(self.depth_persistence) and self.depth_persistence >= 1.0):
            raise ParameterError(f"LidarModel.depth_persistence must be finite and >= 1, "
                                 f"actually: {self.depth_persistence!r}")
        if self.centre not in CENTRE_MODELS:
            raise ParameterError(f"LidarModel.centre must be one of {CENTRE_MODELS}, actually: {self.centre!r}")
        lo, hi = self.length_beam_ratio
        if not (np.isfinite(hi) and 1.0 <= lo <= hi):
            raise ParameterError(f"LidarModel.length_beam_ratio must be (lo, hi) with 1 <= lo <= hi < inf, "
                                 f"actually: {self.length_beam_ratio!r}")
        if not 0.0 <= self.bow_taper < 1.0:
            raise ParameterError(f"LidarModel.bow_taper must be in [0, 1), actually: {self.bow_taper!r}")
        a0, a1 = self.taper_angles_rad
        if not 0.0 <= a0 <= a1 <= 0.5 * np.pi:
            raise ParameterError(f"LidarModel.taper_angles_rad must be (lo, hi) with 0 <= lo <= hi <= π/2, "
                                 f"actually: {self.taper_angles_rad!r}")
        for name in ("fit_floor_m", "default_half_depth_m", "max_semi_axis_m", "max_hidden_m"):
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
        True where the ellipse fit is plausible (with ``centre="ellipse"``: its centre was
        used, else the centroid was).
    extent_m : ndarray, shape (k, 2)
        With ``centre="hull_box"``: visible extents ``[along, across]`` the hull axis [m]
        (NaN otherwise).
    R_update : ndarray, shape (k, 2, 2), or None
        The covariance for a filter update: ``R`` with the unseen-depth part scaled by
        ``LidarModel.depth_persistence`` (None: ``R`` itself). ``R`` (one scan) is for
        gates and association.
    sight : ndarray, shape (k, 8), or None
        With ``centre="hull_box"``: each cluster's line of sight from the sensor
        (centroid, ranges, direction, extreme bearings; internal, reused when the tracker
        measures a cluster again with a track's course).
    """

    z: _F8
    R: _F8
    fits: EllipseFits
    used_fit: NDArray[np.bool_]
    extent_m: _F8 | None = None
    R_update: _F8 | None = None
    sight: _F8 | None = None

    def __len__(self) -> int:
        return int(self.z.shape[0])


def _hull_prm(mdl: LidarModel, clusters: Clusters | None = None) -> _F8:
    step = np.nan if clusters is None else float(clusters.ray_step_rad)
    return np.array([mdl.range_std_m, mdl.bearing_std_rad, mdl.angular_step_rad, mdl.length_beam_ratio[0],
                     mdl.length_beam_ratio[1], mdl.tip_gap_rays, mdl.orientation_std_rad, mdl.centre_floor_m,
                     mdl.gap_factor, mdl.bow_taper, mdl.taper_angles_rad[0], mdl.taper_angles_rad[1],
                     mdl.depth_persistence, mdl.max_hidden_m, step if np.isfinite(step) and step > 0.0 else 0.0,
                     mdl.known_size_tol, mdl.known_size_floor_m,
                     np.inf if clusters is None else float(clusters.max_range_m)])


def _end_shadows(clusters: Clusters) -> _F8:
    """The clusters' occlusion shadows (zeros when the segmenter did not record them)."""
    if clusters.end_shadow_m is None:
        return np.zeros((len(clusters), 2))
    return np.ascontiguousarray(clusters.end_shadow_m, dtype=np.float64).reshape(len(clusters), 2)


def hull_centres(clusters: Clusters, heading_rad: ArrayLike, heading_std_rad: ArrayLike,
                 model: LidarModel | None = None, *, only_known: bool = False,
                 size_m: ArrayLike | None = None) -> tuple[_F8, _F8, _F8]:
    """Hull-centre measurements of clusters whose hull axis is known (or NaN: unknown).

    Parameters
    ----------
    clusters : Clusters
        Clusters of one scan with the sensor position ``origin_ned``.
    heading_rad, heading_std_rad : array_like, shape (k,)
        Hull axis of each cluster from north, clockwise [rad] (NaN: unknown) and its
        standard deviation [rad].
    model : LidarModel, optional
    only_known : bool
        Skip clusters without a heading (their rows are NaN).
    size_m : array_like, shape (k, 2), optional
        Known length and beam of each hull [m] (AIS static data; NaN rows: unknown). With
        a heading they replace the length/beam-ratio bounds of the unseen depth.

    Returns
    -------
    z : ndarray, shape (k, 2)
        Centres ``[north_m, east_m]`` [m].
    R : ndarray, shape (k, 2, 2)
        Covariances [m²].
    extent : ndarray, shape (k, 2)
        Visible extents along and across the hull axis [m].
    """
    mdl = model or LidarModel()
    k = len(clusters)
    h = np.array(np.broadcast_to(np.asarray(heading_rad, np.float64), (k,)))  # a writeable copy: one kernel type
    hs = np.maximum(np.broadcast_to(np.asarray(heading_std_rad, np.float64), (k,)), mdl.heading_floor_rad)
    origin = np.asarray(clusters.origin_ned, dtype=np.float64).reshape(2)
    if not np.isfinite(origin).all():
        raise StateError("hull-centre measurements need the sensor position (Clusters.origin_ned), actually: NaN")
    points = np.ascontiguousarray(clusters.points, dtype=np.float64).reshape(-1, 2)
    offsets = np.ascontiguousarray(clusters.offsets, dtype=np.int64)
    sizes = np.full((k, 2), np.nan) if size_m is None else \
        np.array(np.broadcast_to(np.asarray(size_m, np.float64), (k, 2)))
    z, R, ext, _, _ = hull_box_kernel(points, offsets, origin, h, hs, _end_shadows(clusters), _hull_prm(mdl, clusters),
                                   only_known, sizes)
    return z, R, ext


def hull_centres_for_pairs(clusters: Clusters, cols: NDArray[np.int64], heading_rad: _F8, heading_std_rad: _F8,
                           model: LidarModel | None = None) -> tuple[_F8, _F8, _F8]:
    """Hull-centre measurements of cluster ``cols[p]`` with hull axis ``heading_rad[p]``, one
    per (track, cluster) pair: a cluster in the gate of two tracks is measured once with
    each one's course (its centre depends on the hull axis assumed).

    Returns
    -------
    z : ndarray, shape (p, 2)
    R_update : ndarray, shape (p, 2, 2)
        Covariance with the unseen depth scaled by ``depth_persistence`` (for the filter).
    R : ndarray, shape (p, 2, 2)
        Single-scan covariance (for gates).
    """
    mdl = model or LidarModel()
    cols = np.ascontiguousarray(cols, np.int64)
    points = np.ascontiguousarray(clusters.points, dtype=np.float64).reshape(-1, 2)
    offsets = np.ascontiguousarray(clusters.offsets, dtype=np.int64)
    origin = np.asarray(clusters.origin_ned, dtype=np.float64).reshape(2)
    h = np.array(heading_rad, np.float64).reshape(cols.size)
    hs = np.maximum(np.asarray(heading_std_rad, np.float64).reshape(cols.size), mdl.heading_floor_rad)
    z, Ru, _, R = hull_box_pairs_kernel(points, offsets, origin, cols, h, hs, _end_shadows(clusters), _hull_prm(mdl, clusters))
    return z, Ru, R


def lidar_measurements(clusters: Clusters, model: LidarModel | None = None) -> LidarMeasurements:
    """Fit every cluster and turn it into a position measurement with its covariance.

    Parameters
    ----------
    clusters : Clusters
        Clusters of one scan (``origin_ned`` is the sensor position; when NaN the
        covariance is isotropic and the ``"ellipse"`` centre is used).
    model : LidarModel, optional
        Noise settings. With ``centre="hull_box"`` the hull axis is unknown here (the
        tracker re-measures associated clusters with their track's course,
        :func:`hull_centres`).

    Returns
    -------
    LidarMeasurements
    """
    mdl = model or LidarModel()
    code = _method_code(mdl.method)
    points = np.ascontiguousarray(clusters.points, dtype=np.float64).reshape(-1, 2)
    offsets = np.ascontiguousarray(clusters.offsets, dtype=np.int64)
    origin = np.asarray(clusters.origin_ned, dtype=np.float64).reshape(2)
    prm = np.array([mdl.max_semi_axis_m, mdl.min_coverage_rad, mdl.fit_floor_m, mdl.needle_ratio,
                    mdl.range_std_m**2, mdl.fit_floor_m**2, mdl.depth_gain, mdl.coverage_gain,
                    mdl.needle_depth_gain, mdl.default_half_depth_m, mdl.end_gain, mdl.bearing_std_rad])
    # one numba pass: fits, centroids/spreads, plausibility, line-of-sight variances (and R)
    out, z, use, var_los, cross0, R = lidar_model_kernel(points, offsets, code, _C1, origin, prm)
    if not np.isfinite(origin).all():  # no sensor position: a far-away one, i.e. ~isotropic
        origin = z.mean(axis=0) - np.array([1.0e4, 0.0]) if len(z) else np.zeros(2)
        R = los_covariance(z, origin, var_los, cross0, mdl.bearing_std_rad)
        return LidarMeasurements(z=z, R=R, fits=EllipseFits.from_array(out), used_fit=use)
    ext = np.full((len(z), 2), np.nan)
    if mdl.centre == "hull_box" and len(z):
        k = len(z)
        z, Rf, ext, R, sight = hull_box_kernel(points, offsets, origin, np.full(k, np.nan), np.zeros(k),
                                               _end_shadows(clusters), _hull_prm(mdl, clusters), False,
                                               np.full((k, 2), np.nan))
        return LidarMeasurements(z=z, R=R, fits=EllipseFits.from_array(out), used_fit=use, extent_m=ext,
                                 R_update=Rf, sight=sight)
    return LidarMeasurements(z=z, R=R, fits=EllipseFits.from_array(out), used_fit=use, extent_m=ext)


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


_AIS_FIELDS = ("mmsi", "t_s", "north_m", "east_m", "sog_m_s", "cog_rad")
_AIS_GET = operator.attrgetter(*_AIS_FIELDS)


@dataclass(frozen=True, eq=False)
class AisMeasurementBatch:
    """Many AIS reports in the local frame as columns (the array form of :class:`AisMeasurement`).

    The tracker takes either a sequence of :class:`AisMeasurement` or one batch; the
    batch skips the conversion of report objects (~0.2 µs per report). Every array
    has shape (k,); NaN marks "not available" in ``sog_m_s`` and ``cog_rad``.

    Attributes
    ----------
    mmsi : ndarray of int64
        Maritime Mobile Service Identities.
    t_s : ndarray
        Report times [s] since the scene start.
    north_m, east_m : ndarray
        Positions in the local NED frame [m].
    sog_m_s : ndarray
        Speed over ground [m/s].
    cog_rad : ndarray
        Course over ground from north, clockwise [rad].
    """

    mmsi: NDArray[np.int64]
    t_s: _F8
    north_m: _F8
    east_m: _F8
    sog_m_s: _F8
    cog_rad: _F8

    def __post_init__(self) -> None:
        k = None
        for name in _AIS_FIELDS:
            v = np.ascontiguousarray(getattr(self, name), dtype=np.int64 if name == "mmsi" else np.float64)
            if v.ndim != 1 or (k is not None and v.shape[0] != k):
                raise StateError(f"AisMeasurementBatch.{name} must have shape ({k if k is not None else 'k'},), "
                                 f"actually: {v.shape}")
            k = v.shape[0]
            object.__setattr__(self, name, v)

    def __len__(self) -> int:
        return int(self.mmsi.shape[0])

    @classmethod
    def from_list(cls, reports: Sequence[AisMeasurement]) -> AisMeasurementBatch:
        """Columns of a sequence of :class:`AisMeasurement` (any object with those fields)."""
        k = len(reports)
        arr = np.fromiter(itertools.chain.from_iterable(map(_AIS_GET, reports)), np.float64, 6 * k).reshape(k, 6)
        with np.errstate(invalid="ignore"):
            mmsi = arr[:, 0].astype(np.int64)  # MMSIs are 9 digits: exact in float64; NaN -> invalid (< 0)
        return cls(mmsi, arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5])

    @classmethod
    def from_batch(cls, batch: Any, *, epoch_unix_s: float = 0.0) -> AisMeasurementBatch:
        """From the AIS pipeline's columnar ``ReportBatch`` (read duck-typed, no copy of objects).

        Parameters
        ----------
        batch : asvtwin.sources.ais.ReportBatch or alike
            Needs the columns ``mmsi``, ``t_unix_s``, ``north_m``, ``east_m``, ``sog_m_s``
            and ``cog_rad`` (NaN = not available), as
            :meth:`AisMeasurement.from_report` reads them row by row.
        epoch_unix_s : float
            UNIX time of the simulation's t = 0 [s]: ``t_s = t_unix_s - epoch_unix_s``.
        """
        try:
            cols = [getattr(batch, name) for name in ("mmsi", "t_unix_s", "north_m", "east_m", "sog_m_s", "cog_rad")]
        except AttributeError as exc:
            raise StateError(f"AIS batch needs the columns mmsi, t_unix_s, north_m, east_m, sog_m_s, cog_rad, "
                             f"actually: {type(batch).__name__} ({exc})") from None
        t = np.asarray(cols[1], dtype=np.float64) - float(epoch_unix_s)
        return cls(cols[0], t, cols[2], cols[3], cols[4], cols[5])


def ais_measurements(reports: Sequence[AisMeasurement] | AisMeasurementBatch, t_s: float,
                     model: AisModel | None = None) -> AisMeasurements:
    """Convert AIS reports to measurements at the tick time ``t_s``.

    Parameters
    ----------
    reports : sequence of AisMeasurement, or AisMeasurementBatch
        Reports received since the last tick (any order; several per MMSI allowed: the
        latest valid one is used).
    t_s : float
        Tick time [s].
    model : AisModel, optional
        Noise settings.

    Returns
    -------
    AisMeasurements
        Rows sorted by MMSI.
    """
    mdl = model or AisModel()
    if len(reports) == 0:
        return AisMeasurements(np.empty(0, np.int64), np.empty((0, 4)), np.empty((0, 4, 4)))
    b = reports if isinstance(reports, AisMeasurementBatch) else AisMeasurementBatch.from_list(reports)
    prm = np.array([mdl.max_age_s, mdl.max_future_s, mdl.position_std_m**2, mdl.sog_std_m_s**2,
                    mdl.cog_std_rad**2, mdl.accel_q])
    mmsi, z, R, n_rej, n_stale = ais_model_kernel(b.mmsi, b.t_s, b.north_m, b.east_m, b.sog_m_s, b.cog_rad,
                                                  float(t_s), prm)
    return AisMeasurements(mmsi=mmsi, z=z, R=R, n_rejected=int(n_rej), n_stale=int(n_stale))
