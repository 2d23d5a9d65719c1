"""Settings of the tracker (see :mod:`asvtwin.tracking.tracker` for their roles)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from asvtwin.errors import ParameterError
from asvtwin.tracking.clustering import ClusterConfig
from asvtwin.tracking.fusion import FUSION_METHODS
from asvtwin.tracking.measurement import AisModel, LidarModel

__all__ = ["TrackerConfig"]


@dataclass(frozen=True)
class TrackerConfig:
    """Tracker settings (see the module docstring for their roles).

    Attributes
    ----------
    q : float
        Acceleration noise spectral density of the CV model [m²/s³].
    fusion : {"product", "gain_weighted", "covariance_intersection"}
        Fusion of LiDAR and AIS.
    gate_probability : float
        χ² gate probability for LiDAR and untied AIS association.
    tied_gate_probability : float
        Looser gate for AIS reports of a tied MMSI.
    confirm_m, confirm_n : int
        M-of-N confirmation (1 <= M <= N <= 30).
    confirm_velocity_std_m_s : float
        ... and, for a track without AIS, only once its largest velocity standard
        deviation is below this [m/s] (inf, the default: M-of-N alone). A confirmed track
        is handed to the safety filter as a moving obstacle; one still carrying the initial
        velocity prior (``init_velocity_std_m_s``) is a clearance circle kilometres wide at
        the end of its horizon, but a bound here (e.g. 1 m/s) keeps a new LiDAR-only
        object from the filter until it settles: in the model-scale crossing the first
        confirmed track came at 3.0 s instead of 0.2 s, and the dense twin scene's
        fallbacks did not drop (63 %), so it is off by default.
    max_coast_s, max_coast_ais_s : float
        Deletion after this long without an update [s] (without / with an MMSI tie).
    max_position_std_m : float
        Deletion when the largest position standard deviation exceeds this [m].
    init_velocity_std_m_s : float
        Velocity standard deviation of a track started from a LiDAR centre [m/s].
    min_separation_m : float
        No new LiDAR track within this distance of an existing track (or within its
        fitted semi-major axis + 10 m, or inside its gate) [m]: fragments of a partly
        occluded hull must not start tracks.
    fusion_window_s : float
        For gain weighting / CI: a per-sensor filter counts as fresh this long [s].
    ais_reseed_after : int
        Consecutive rejected reports of a tied MMSI after which the tie is dropped.
    merge_probability : float
        Two tracks whose positions and velocities are this close in χ² terms ...
    merge_after : int
        ... for this many ticks in a row are merged (duplicates of one vessel) ...
    merge_distance_m : float
        ... if their positions are also within this distance [m] (two vessels abreast
        with wide covariances pass the χ² test but are not one).
    identity_gate_probability : float
        χ² gate of a LiDAR cluster against the AIS-only estimate of an MMSI-tied track:
        outside it the cluster cannot update that track (the AIS identity is evidence).
    identity_margin : float
        An untied AIS report ties its MMSI to a track only if the next-best track's
        squared Mahalanobis distance is larger by at least this [-] (a likelihood ratio
        of e^(margin/2)); ambiguous reports wait for the next one.
    measure_with_dimensions : bool
        Known AIS dimensions (:meth:`Tracker.set_dimensions`) size the LiDAR measurement
        of a tied track (and the footprint of ``split_by_tracks``). False: they only keep
        new tracks off the known hull (its length × beam rectangle along the course plus
        ``min_separation_m / 3``), which they do either way. The twin sets False: with
        the sized measurement the tracks are over-confident (NEES 2.9 / 3.4 in open sea /
        near the coast against bounds of about 2.4 / 2.5, docs/tracking.md).
    chart_error_m : float
        Bound of the chart's error [m]: LiDAR clusters with a return within this of the
        charted shore (or on charted land) do not start tracks (0 disables).
    course_min_speed_m_s : float
        A track this fast lends its course as the hull axis to the LiDAR measurement
        (hull-centre model) [m/s] ...
    course_max_std_rad : float
        ... when the course's standard deviation is below this [rad] ...
    course_min_returns : int
        ... to clusters of at least this many returns (>= 1; default 1: every cluster).
        One or two returns of a far hull show neither its beam nor its length; with the
        axis known, the model's bounds (length up to ρ_max times a beam the ray spacing
        allows) can place the centre of a hull seen end-on too deep, and its track lag.
        3 removed the remaining duplicate tracks of a far end-on hull but raised the
        open-sea NEES of the calibration scenes (docs/tracking.md, "Duplicate tracks of
        one far hull").
    split_by_tracks : bool
        Cut a LiDAR cluster that two confirmed tracks (one tied to a fresh AIS report)
        predict into, one piece per track (vessels closer than the segmentation resolves).
        Off by default: without the vessels' dimensions (AIS message 5) the footprints
        come from fitted ellipses, and a merged cluster's fit swallows the neighbour
        (measured in docs/tracking.md, "Splitting by known positions").
    depth_persistence_s : float or None
        How long the error of a LiDAR centre persists [s] (the unseen depth of a hull, the
        rays' sampling of it: the geometry changes slowly). A scan ``Δt`` after the previous
        one updates the filter with that part of ``R`` scaled by ``max(1, τ / Δt)``: a
        filter fed every scan must not average a persistent error away, and the number of
        scans it persists over grows with the scan rate. 3 s is 3 scans at 1 Hz, where it
        was calibrated (docs/tracking.md); at 10 Hz it is 30. None: use
        ``lidar.depth_persistence`` (scans) whatever the rate.
    cluster, lidar, ais : ClusterConfig, LidarModel, AisModel
        Segmentation and measurement models.
    """

    q: float = 0.01
    fusion: str = "product"
    gate_probability: float = 0.999
    tied_gate_probability: float = 0.999999
    confirm_m: int = 3
    confirm_n: int = 5
    confirm_velocity_std_m_s: float = float("inf")
    max_coast_s: float = 15.0
    max_coast_ais_s: float = 180.0
    max_position_std_m: float = 150.0
    init_velocity_std_m_s: float = 8.0
    min_separation_m: float = 30.0
    fusion_window_s: float = 30.0
    ais_reseed_after: int = 3
    merge_probability: float = 0.99
    merge_after: int = 3
    merge_distance_m: float = 10.0
    identity_gate_probability: float = 0.9999
    identity_margin: float = 6.0
    chart_error_m: float = 10.0
    course_min_speed_m_s: float = 0.5
    course_max_std_rad: float = float(np.deg2rad(20.0))
    course_min_returns: int = 1
    split_by_tracks: bool = False
    measure_with_dimensions: bool = True
    depth_persistence_s: float | None = 3.0
    cluster: ClusterConfig = field(default_factory=ClusterConfig)
    lidar: LidarModel = field(default_factory=lambda: LidarModel(depth_persistence=3.0))
    ais: AisModel = field(default_factory=AisModel)

    def __post_init__(self) -> None:
        if self.fusion not in FUSION_METHODS:
            raise ParameterError(f"TrackerConfig.fusion must be one of {FUSION_METHODS}, actually: {self.fusion!r}")
        if not 1 <= self.confirm_m <= self.confirm_n <= 30:
            raise ParameterError(
                f"TrackerConfig needs 1 <= confirm_m <= confirm_n <= 30, actually: m={self.confirm_m}, n={self.confirm_n}")
        if not self.confirm_velocity_std_m_s > 0.0:
            raise ParameterError(f"TrackerConfig.confirm_velocity_std_m_s must be > 0 (inf: off), "
                                 f"actually: {self.confirm_velocity_std_m_s!r}")
        for name in ("q", "max_coast_s", "max_coast_ais_s", "max_position_std_m", "init_velocity_std_m_s",
                     "min_separation_m", "fusion_window_s", "course_min_speed_m_s", "course_max_std_rad",
                     "identity_margin", "chart_error_m", "merge_distance_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0.0):
                raise ParameterError(f"TrackerConfig.{name} must be finite and >= 0, actually: {v!r}")
        if not 0.0 < self.identity_gate_probability < 1.0:
            raise ParameterError(f"TrackerConfig.identity_gate_probability must be in (0, 1), "
                                 f"actually: {self.identity_gate_probability!r}")
        if not 0.0 < self.merge_probability < 1.0 or self.merge_after < 1:
            raise ParameterError(f"TrackerConfig needs merge_probability in (0, 1) and merge_after >= 1, "
                                 f"actually: {self.merge_probability!r}, {self.merge_after!r}")
        if self.depth_persistence_s is not None and not (np.isfinite(self.depth_persistence_s)
                                                         and self.depth_persistence_s >= 0.0):
            raise ParameterError(f"TrackerConfig.depth_persistence_s must be None or finite and >= 0, "
                                 f"actually: {self.depth_persistence_s!r}")
        if self.course_min_returns < 1:
            raise ParameterError(f"TrackerConfig.course_min_returns must be >= 1, actually: {self.course_min_returns!r}")
        if self.ais_reseed_after < 1:
            raise ParameterError(f"TrackerConfig.ais_reseed_after must be >= 1, actually: {self.ais_reseed_after!r}")
