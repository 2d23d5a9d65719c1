"""The LiDAR's compiled scan (range cull, fused returns) against the plain NumPy scan it
replaced: the same ranges, hits, points and hit ids to the bit, near and far targets and
the coast mixed, noise and dropout on."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box

from asvtwin.geo import LandMask
from asvtwin.sensors import HIT_COAST, HIT_NONE, Lidar, LidarConfig, hull_polygons
from asvtwin.sensors.hull import hull_segments, target_poses
from asvtwin.sensors.lidar import _cast_hulls


def _reference_scan(lidar: Lidar, own, ts, L, B, land, rng):  # type: ignore[no-untyped-def]
    """The scan as it was written before the cull and the fused kernel (NumPy)."""
    cfg = lidar.config
    o = own[:2].copy()
    nominal = own[2] + lidar._rel
    m = nominal.size
    true_a = nominal + cfg.angle_std_rad * rng.standard_normal(m)
    noise = cfg.range_std_m * rng.standard_normal(m)
    dropped = rng.random(m) < cfg.dropout_prob
    cosa, sina = np.cos(true_a), np.sin(true_a)
    rng_t = np.full(m, np.inf)
    who = np.full(m, HIT_NONE, np.int64)
    if ts.size:
        polys = hull_polygons(ts, L, B, shape=cfg.hull_shape)
        pose = target_poses(ts)
        radii = 0.5 * np.hypot(L, B) + 1e-6
        rng_t, who = _cast_hulls(o[0], o[1], cosa, sina, cfg.max_range_m, hull_segments(polys),
                                 np.ascontiguousarray(pose[:, :2]), radii)
    if land is not None:
        coast = land.cast_rays(o, true_a, cfg.max_range_m)
        nearer = coast < rng_t
        rng_t = np.where(nearer, coast, rng_t)
        who = np.where(nearer, HIT_COAST, who)
    hit = np.isfinite(rng_t) & (rng_t >= cfg.min_range_m) & ~dropped
    ranges = np.where(hit, np.maximum(rng_t + noise, 0.0), np.inf)
    who = np.where(hit, who, HIT_NONE)
    c, s = np.cos(nominal), np.sin(nominal)
    with np.errstate(invalid="ignore"):
        pts = np.where(hit[:, None], o + ranges[:, None] * np.column_stack([c, s]), np.nan)
    return ranges, hit, pts, who


@pytest.mark.parametrize("shape", ["pointed", "ellipse"])
@pytest.mark.parametrize("with_land", [False, True])
def test_scan_equals_the_numpy_reference_bit_for_bit(shape: str, with_land: bool) -> None:
    rng = np.random.default_rng(11)
    land = LandMask([box(250.0, -800.0, 900.0, -300.0)]) if with_land else None
    lidar = Lidar(LidarConfig(n_rays=720, max_range_m=400.0, range_std_m=0.3,
                              angle_std_rad=0.002, dropout_prob=0.1, hull_shape=shape))
    n_hits = n_coast = 0
    for k in range(12):
        n = 40
        ts = np.column_stack([rng.uniform(-1500, 1500, (n, 2)), rng.uniform(-np.pi, np.pi, n),
                              rng.uniform(0, 5, n), np.zeros(n), np.zeros(n)])
        ts[: 5 + k, :2] = rng.uniform(-350, 350, (5 + k, 2))  # some surely in range
        L = rng.uniform(10.0, 150.0, n)
        B = L / 5.0
        own = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-np.pi, np.pi),
                        2.0, 0.0, 0.0])
        seed = int(rng.integers(1 << 30))
        scan = lidar.scan(own, ts, L, B, land, np.random.default_rng(seed))
        ranges, hit, pts, who = _reference_scan(lidar, own, ts, L, B, land,
                                                np.random.default_rng(seed))
        np.testing.assert_array_equal(scan.ranges_m, ranges)
        np.testing.assert_array_equal(scan.hit, hit)
        np.testing.assert_array_equal(scan.points_ned, pts)
        np.testing.assert_array_equal(scan.hit_id, who)
        n_hits += int((who >= 0).sum())
        n_coast += int((who == HIT_COAST).sum())
    assert n_hits > 100  # the targets were really seen, not only culled
    assert (n_coast > 0) == with_land


def test_targets_out_of_range_change_nothing() -> None:
    lidar = Lidar(LidarConfig(n_rays=360, max_range_m=300.0))
    near = np.array([[120.0, 10.0, 0.3, 0.0, 0.0, 0.0]])
    far = np.array([[0.0, 302.0 + 25.5, 0.0, 0.0, 0.0, 0.0]])  # circle just beyond range
    a = lidar.scan(np.zeros(6), near, [40.0], [8.0], None, np.random.default_rng(3))
    b = lidar.scan(np.zeros(6), np.vstack([far, near]), [50.0, 40.0], [10.0, 8.0], None,
                   np.random.default_rng(3))
    np.testing.assert_array_equal(a.ranges_m, b.ranges_m)
    np.testing.assert_array_equal(a.hit_id[a.hit], 0)
    np.testing.assert_array_equal(b.hit_id[b.hit], 1)  # the original index, not the culled one
