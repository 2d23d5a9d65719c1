"""Predictive target tracking: clusters, ellipse fits, batched CV Kalman filters, AIS–LiDAR fusion.

The components follow Stone Soup's vocabulary (predictor :func:`cv_predict`, updater
:func:`kalman_update` / :func:`fuse_product`, associator :func:`gnn_assign`, initiator and
deleter inside :class:`Tracker`), light and batched over targets: arrays in, frozen plain
values out.
"""

from __future__ import annotations

from asvtwin.tracking.association import FORBIDDEN, gate_threshold, gated_costs, gnn_assign
from asvtwin.tracking.clustering import (
    ClusterConfig,
    Clusters,
    cluster_points,
    cluster_scan,
    split_clusters,
)
from asvtwin.tracking.config import TrackerConfig
from asvtwin.tracking.ellipse import (
    FIT_COLLINEAR,
    FIT_NO_ELLIPSE,
    FIT_OK,
    FIT_STATUS,
    FIT_TOO_FEW_POINTS,
    EllipseFit,
    EllipseFits,
    fit_ellipse,
    fit_ellipses,
)
from asvtwin.tracking.fusion import (
    FUSION_METHODS,
    fuse_covariance_intersection,
    fuse_gain_weighted,
    fuse_product,
)
from asvtwin.tracking.kalman import (
    H_FULL,
    H_POSITION,
    KalmanUpdate,
    cv_predict,
    cv_process_noise,
    cv_transition,
    kalman_update,
)
from asvtwin.tracking.measurement import (
    AisMeasurement,
    AisMeasurementBatch,
    AisMeasurements,
    AisModel,
    LidarMeasurements,
    LidarModel,
    ais_measurements,
    hull_centres,
    lidar_measurements,
)
from asvtwin.tracking.metrics import (
    GospaResult,
    assign_tracks,
    effective_sample_size,
    false_tracks,
    gospa,
    nees,
    nees_bounds,
    rmse,
    track_breaks,
)
from asvtwin.tracking.prediction import (
    COVARIANCE_INFLATION,
    SafetyPrediction,
    TrackPrediction,
    predict_tracks,
    predictions_for_safety,
    uncertainty_polygon,
)
from asvtwin.tracking.snapshot import TRACK_STATUS, TrackSnapshot
from asvtwin.tracking.tracker import Tracker, VesselDimensions

__all__ = [
    "COVARIANCE_INFLATION",
    "FIT_COLLINEAR",
    "FIT_NO_ELLIPSE",
    # ellipse fits
    "FIT_OK",
    "FIT_STATUS",
    "FIT_TOO_FEW_POINTS",
    # association
    "FORBIDDEN",
    # fusion
    "FUSION_METHODS",
    "H_FULL",
    # Kalman filter
    "H_POSITION",
    # tracker
    "TRACK_STATUS",
    # measurements
    "AisMeasurement",
    "AisMeasurementBatch",
    "AisMeasurements",
    "AisModel",
    # clustering
    "ClusterConfig",
    "Clusters",
    "EllipseFit",
    "EllipseFits",
    "GospaResult",
    "KalmanUpdate",
    "LidarMeasurements",
    "LidarModel",
    "SafetyPrediction",
    # prediction
    "TrackPrediction",
    "TrackSnapshot",
    "Tracker",
    "TrackerConfig",
    "VesselDimensions",
    "ais_measurements",
    "assign_tracks",
    "cluster_points",
    "cluster_scan",
    "cv_predict",
    "cv_process_noise",
    "cv_transition",
    "effective_sample_size",
    "false_tracks",
    "fit_ellipse",
    "fit_ellipses",
    "fuse_covariance_intersection",
    "fuse_gain_weighted",
    "fuse_product",
    "gate_threshold",
    "gated_costs",
    "gnn_assign",
    "gospa",
    "hull_centres",
    "kalman_update",
    "lidar_measurements",
    "nees",
    "nees_bounds",
    "predict_tracks",
    "predictions_for_safety",
    # metrics
    "rmse",
    "split_clusters",
    "track_breaks",
    "uncertainty_polygon",
]
