"""Synthetic sensors of the own ship: a 2-D LiDAR cast against target hulls and the coast."""

from __future__ import annotations

from asvtwin.sensors.chart import perturb_chart
from asvtwin.sensors.hull import HULL_SHAPES, hull_polygons, hull_segments, target_poses
from asvtwin.sensors.lidar import HIT_COAST, HIT_NONE, Lidar, LidarConfig, LidarScan

__all__ = [
    "HIT_COAST",
    "HIT_NONE",
    "HULL_SHAPES",
    "Lidar",
    "LidarConfig",
    "LidarScan",
    "hull_polygons",
    "hull_segments",
    "perturb_chart",
    "target_poses",
]
