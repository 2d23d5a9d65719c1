from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.control import (
    CircleObstacles,
    CoastSegments,
    MovingObstacles,
    covariance_inflation,
    lidar_circles,
    stage_circles,
)
from asvtwin.errors import StateError


def test_lidar_circle_nearest_point_is_the_return():
    ang = np.array([0.0, np.pi / 2])
    rng_m = np.array([10.0, 5.0])
    c = lidar_circles([1.0, 2.0], ang, rng_m, radius_m=8.0)
    # circle centre 8 m behind the return along the ray: its edge is the return point
    np.testing.assert_allclose(c.centres, [[1.0 + 18.0, 2.0], [1.0, 2.0 + 13.0]], atol=1e-12)
    gap = np.linalg.norm(c.centres - [1.0, 2.0], axis=1) - c.radii
    np.testing.assert_allclose(gap, rng_m)


def test_lidar_keeps_five_nearest_per_sector_within_range():
    ang = np.full(12, 0.1)  # all in sector 0 of 9
    rng_m = np.arange(1.0, 13.0) * 3  # 3 .. 36 m
    c = lidar_circles([0, 0], ang, rng_m, max_range_m=30.0, per_sector=5)
    assert len(c) == 5
    gap = np.linalg.norm(c.centres, axis=1) - c.radii
    np.testing.assert_allclose(np.sort(gap), [3, 6, 9, 12, 15])


def test_covariance_inflation_is_chi_square_radius():
    # 95 % ellipse of a unit isotropic Gaussian: sqrt(chi2_2(0.95)) = sqrt(5.991) = 2.4477
    assert covariance_inflation(np.eye(2), 0.95) == pytest.approx(2.4477, abs=1e-4)
    # largest axis counts: diag(4, 1) m² -> 2 m standard deviation
    assert covariance_inflation(np.diag([4.0, 1.0]), 0.95) == pytest.approx(2 * 2.4477, abs=1e-3)


def test_constant_velocity_prediction_and_inflation():
    mo = MovingObstacles.constant_velocity([[10.0, 0.0]], [[0.0, -0.5]], [2.0], N=4, dt_s=0.5,
                                           covariances=[np.eye(2) * 0.25], process_noise=0.5)
    np.testing.assert_allclose(mo.positions[0, -1], [10.0, -1.0])
    r = mo.effective_radii()[0]
    k = math.sqrt(-2 * math.log(0.05))
    np.testing.assert_allclose(r, 2.0 + k * np.sqrt(0.25 + 0.5 * np.arange(5) * 0.5))
    centres, radii, segs = stage_circles([mo, CircleObstacles([[0, 5]], [1.0])], 4)
    assert centres.shape == (5, 2, 2) and radii.shape == (5, 2) and segs.shape == (0, 4)


def test_coast_segment_distance_hand_computed():
    seg = CoastSegments([[0.0, 0.0, 0.0, 10.0]])  # along east from the origin
    d = seg.distances([[3.0, 5.0], [4.0, -3.0], [0.0, 12.0]])[:, 0]
    np.testing.assert_allclose(d, [3.0, 5.0, 2.0])


@pytest.mark.parametrize("radius", [0.0, -1.0, np.nan])
def test_bad_radius_is_refused(radius):
    with pytest.raises(StateError, match="radii"):
        CircleObstacles([[1.0, 1.0]], [radius])


def test_nan_centre_and_wrong_horizon_are_refused():
    with pytest.raises(StateError, match="finite"):
        CircleObstacles([[np.nan, 1.0]], [1.0])
    mo = MovingObstacles.constant_velocity([[10.0, 0.0]], [[0.0, 1.0]], [1.0], N=3, dt_s=0.5)
    with pytest.raises(StateError, match="N\\+1 = 6"):
        stage_circles(mo, 5)
