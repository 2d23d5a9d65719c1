"""Segmentation (coast removal, separation of vessels) and the LiDAR/AIS measurement models."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import (
    AisMeasurement,
    AisModel,
    ais_measurements,
    cluster_points,
    cluster_scan,
    lidar_measurements,
)

from .scenes import jagged_coast


def test_scan_splits_into_one_cluster_per_vessel_and_drops_the_coast() -> None:
    land = jagged_coast()
    own = np.array([-300.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    targets = np.array([[-150.0, -60.0, 0.0, 2.0], [-160.0, 60.0, 0.0, -2.0], [-450.0, 0.0, 1.0, 0.0]])
    scan = Lidar(LidarConfig(n_rays=1440)).scan(own, targets, [30.0, 30.0, 20.0], [8.0, 8.0, 5.0], land,
                                                 np.random.default_rng(0))
    cl = cluster_scan(scan, land)
    assert len(cl) == 3
    assert cl.n_coast == int((scan.hit_id == -2).sum()) > 100
    assert np.all(cl.sizes >= 5)
    m = lidar_measurements(cl)
    for z in m.z:  # each measured centre within a hull length of a true centre
        assert np.min(np.hypot(*(targets[:, :2] - z).T)) < 20.0
    assert np.all(np.linalg.eigvalsh(m.R) > 0)


def test_unordered_points_and_fallbacks() -> None:
    rng = np.random.default_rng(1)
    blob_a = rng.normal([0.0, 0.0], 1.0, (20, 2))
    blob_b = rng.normal([100.0, 0.0], 1.0, (3, 2))
    pts = np.vstack([blob_a, blob_b, [[np.nan, 1.0]]])
    cl = cluster_points(pts, link_m=5.0)
    assert sorted(cl.sizes.tolist()) == [3, 20] and cl.n_invalid == 1
    m = lidar_measurements(cl)
    small = int(np.argmin(cl.sizes))
    assert not m.used_fit[small]  # < 5 points: the centroid, with a wide covariance
    np.testing.assert_allclose(m.z[small], blob_b.mean(axis=0))
    assert np.sqrt(np.linalg.eigvalsh(m.R[small]).max()) >= 8.0


def test_ais_velocity_ageing_and_latest_report_per_mmsi() -> None:
    reports = [AisMeasurement(257000001, 8.0, 100.0, 0.0, 5.0, np.pi / 2),
               AisMeasurement(257000001, 9.0, 101.0, 5.0, 5.0, np.pi / 2),   # newer: this one is used
               AisMeasurement(257000002, 10.0, 0.0, 0.0)]                    # no SOG/COG
    am = ais_measurements(reports, 10.0, AisModel(position_std_m=4.0, sog_std_m_s=0.1, cog_std_rad=0.01, accel_q=0.0))
    assert am.mmsi.tolist() == [257000001, 257000002]
    np.testing.assert_allclose(am.z[0], [101.0, 10.0, 0.0, 5.0], atol=1e-12)  # aged 1 s along east
    # velocity covariance: along-track sog², cross-track (sog * cog_std)²
    np.testing.assert_allclose(am.R[0, 2, 2], (5.0 * 0.01) ** 2 + 1e-4, rtol=1e-6)
    assert am.R[0, 3, 3] == pytest.approx(0.1**2 + 1e-4, rel=1e-6)
    assert am.R[0, 0, 0] > 16.0  # ageing adds uncertainty
    assert am.R[1, 2, 2] >= 1e5  # unknown velocity carries no information
