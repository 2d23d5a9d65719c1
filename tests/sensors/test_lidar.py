"""Synthetic LiDAR: exact ranges on known geometry, coast hits, noise, determinism, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box

from asvtwin.errors import ParameterError, StateError
from asvtwin.geo import LandMask
from asvtwin.sensors import HIT_COAST, HIT_NONE, Lidar, LidarConfig, hull_polygons, target_poses

EXACT = LidarConfig(n_rays=360, range_std_m=0.0, angle_std_rad=0.0, max_range_m=500.0)


def _state(n: float, e: float, psi: float = 0.0) -> np.ndarray:
    return np.array([[n, e, psi, 0.0, 0.0, 0.0]])


def test_ray_dead_ahead_hits_the_stern_of_a_target_ahead() -> None:
    scan = Lidar(EXACT).scan(np.zeros(6), _state(100.0, 0.0), 20.0, 5.0, None, np.random.default_rng(0))
    ahead = int(np.argmin(np.abs(scan.angles_rad)))
    assert scan.ranges_m[ahead] == pytest.approx(90.0, abs=1e-9)
    assert scan.hit_id[ahead] == 0
    np.testing.assert_allclose(scan.points_ned[ahead], [90.0, 0.0], atol=1e-9)
    # a 5 m beam at 90 m subtends 2*atan(2.5/90) = 3.18 deg: the 1-degree rays at -1, 0, 1 deg
    assert scan.hit.sum() == 3


def test_beam_on_target_is_hit_on_its_side_and_bearings_follow_own_heading() -> None:
    # target 200 m east, heading north (beam-on): near side at 200 - 2.5 m
    own = np.array([0.0, 0.0, np.pi / 2, 0.0, 0.0, 0.0])  # own ship heading east
    scan = Lidar(EXACT).scan(own, _state(0.0, 200.0, 0.0), 30.0, 5.0, None, np.random.default_rng(0))
    ahead = int(np.argmin(np.abs(scan.angles_rad - np.pi / 2)))
    assert scan.ranges_m[ahead] == pytest.approx(197.5, abs=1e-9)
    side = scan.points_ned[scan.hit]
    side = side[(side[:, 0] > -15.0) & (side[:, 0] < 9.0)]  # the parallel part: stern to shoulder
    assert len(side) == 7
    np.testing.assert_allclose(side[:, 1], 197.5, atol=1e-9)


def test_kinematic_states_use_course_as_heading() -> None:
    pose = target_poses(np.array([[0.0, 0.0, 0.0, 2.0], [1.0, 1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(pose[:, 2], [np.pi / 2, 0.0])
    poly = hull_polygons(np.array([[0.0, 0.0, 0.0, 2.0]]), 20.0, 4.0)
    # bow tip 10 m east of the centre
    np.testing.assert_allclose(poly[0, 2], [0.0, 10.0], atol=1e-12)


def test_coast_is_hit_and_nearer_target_occludes_it() -> None:
    land = LandMask(box(300.0, -1000.0, 1000.0, 1000.0))  # land north of 300 m
    rng = np.random.default_rng(0)
    scan = Lidar(EXACT).scan(np.zeros(6), _state(100.0, 0.0), 20.0, 5.0, land, rng)
    coast = scan.hit_id == HIT_COAST
    assert coast.sum() > 50
    # coast returns at range 300 / cos(bearing)
    np.testing.assert_allclose(scan.ranges_m[coast], 300.0 / np.cos(scan.angles_rad[coast]), rtol=1e-9)
    ahead = int(np.argmin(np.abs(scan.angles_rad)))
    assert scan.hit_id[ahead] == 0 and scan.ranges_m[ahead] == pytest.approx(90.0)


def test_no_return_beyond_max_range_and_empty_scene() -> None:
    scan = Lidar(EXACT).scan(np.zeros(6), np.empty((0, 6)), [], [], None, np.random.default_rng(0))
    assert not scan.hit.any()
    assert np.isinf(scan.ranges_m).all() and np.isnan(scan.points_ned).all()
    assert (scan.hit_id == HIT_NONE).all()
    far = Lidar(EXACT).scan(np.zeros(6), _state(800.0, 0.0), 20.0, 5.0, None, np.random.default_rng(0))
    assert not far.hit.any()


def test_noise_statistics_and_dropout() -> None:
    cfg = LidarConfig(n_rays=3600, range_std_m=0.2, angle_std_rad=0.0, dropout_prob=0.3, max_range_m=500.0)
    land = LandMask(box(-1000.0, -1000.0, 1000.0, 1000.0).difference(box(-200, -200, 200, 200)))
    rng = np.random.default_rng(3)
    scans = [Lidar(cfg).scan(np.zeros(6), np.empty((0, 6)), [], [], land, rng) for _ in range(5)]
    hit = np.concatenate([s.hit for s in scans])
    assert hit.mean() == pytest.approx(0.7, abs=0.02)  # 18 000 rays: binomial sd 0.0034
    true_r = np.concatenate([200.0 / np.maximum(np.abs(np.cos(s.angles_rad)), np.abs(np.sin(s.angles_rad))) for s in scans])
    err = np.concatenate([s.ranges_m for s in scans])[hit] - true_r[hit]
    assert abs(err.mean()) < 0.01 and err.std() == pytest.approx(0.2, rel=0.05)


def test_same_seed_same_scan_and_sector_config() -> None:
    cfg = LidarConfig(n_rays=181, fov_rad=np.pi, range_std_m=0.1)
    a = Lidar(cfg).scan(np.zeros(6), _state(100.0, 20.0), 20.0, 5.0, None, np.random.default_rng(7))
    b = Lidar(cfg).scan(np.zeros(6), _state(100.0, 20.0), 20.0, 5.0, None, np.random.default_rng(7))
    np.testing.assert_array_equal(a.ranges_m, b.ranges_m)
    assert a.angles_rad[0] == pytest.approx(-np.pi / 2) and a.angles_rad[-1] == pytest.approx(np.pi / 2)
    assert not a.ranges_m.flags.writeable


@pytest.mark.parametrize("kwargs", [{"n_rays": 0}, {"n_rays": 5000}, {"fov_rad": 0.0}, {"max_range_m": -1.0},
                                    {"dropout_prob": 1.0}, {"range_std_m": -0.1}, {"hull_shape": "box"}])
def test_bad_config_names_the_field(kwargs: dict) -> None:
    with pytest.raises(ParameterError, match=next(iter(kwargs))):
        LidarConfig(**kwargs)


def test_bad_states_and_dimensions_raise() -> None:
    lidar, rng = Lidar(EXACT), np.random.default_rng(0)
    with pytest.raises(StateError, match="own_state"):
        lidar.scan(np.array([0.0, np.nan, 0, 0, 0, 0]), _state(1, 1), 1.0, 1.0, None, rng)
    with pytest.raises(StateError, match="target states"):
        lidar.scan(np.zeros(6), np.zeros((2, 5)), 1.0, 1.0, None, rng)
    with pytest.raises(ParameterError, match="beam_m"):
        lidar.scan(np.zeros(6), _state(100, 0), 10.0, -1.0, None, rng)
