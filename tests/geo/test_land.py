"""LandMask: hand-computed cases on a synthetic island, shapely as oracle on the fjord."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from asvtwin.errors import ParameterError, StateError
from asvtwin.geo import LandMask, default_scene

# A 1 km x 1 km island, north 1000..2000 m, east -500..500 m, with a 200 m square lagoon.
ISLAND = Polygon(
    [(1000, -500), (2000, -500), (2000, 500), (1000, 500)],
    holes=[[(1400, -100), (1600, -100), (1600, 100), (1400, 100)]],
)


@pytest.fixture(scope="module")
def island() -> LandMask:
    return LandMask(ISLAND, cell_size_m=130.0)


@pytest.fixture(scope="module")
def fjord() -> LandMask:
    return default_scene().land


def _water_points(land: LandMask, n: int, seed: int) -> np.ndarray:
    b = default_scene().bounds_ned
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(b[0], b[1], 4 * n), rng.uniform(b[2], b[3], 4 * n)])
    inside = shapely.contains_xy(default_scene().boundary_ned, p[:, 0], p[:, 1])
    p = p[inside & ~land.contains(p)]
    return p[:n]


def test_island_hand_computed(island: LandMask) -> None:
    pts = np.array([[0.0, 0.0], [1500.0, 300.0], [1500.0, 0.0], [2100.0, 600.0], [990.0, 0.0]])
    np.testing.assert_array_equal(island.contains(pts), [False, True, False, False, False])
    # (0,0): 1000 m south of the shore; (1500,300): 200 m from both the east shore and lagoon;
    # lagoon centre: 100 m; NE corner: sqrt(100^2 + 100^2); 10 m south of the south shore
    np.testing.assert_allclose(
        island.distance_to_shore(pts), [1000.0, 200.0, 100.0, np.hypot(100, 100), 10.0]
    )
    np.testing.assert_allclose(island.signed_distance(pts)[:2], [1000.0, -200.0])
    np.testing.assert_allclose(
        island.nearest_shore_point(pts[[0, 3, 4]]), [[1000, 0], [2000, 500], [1000, 0]]
    )
    assert island.segments.shape == (8, 4)


def test_island_rays_hand_computed(island: LandMask) -> None:
    north, east, south, west = 0.0, np.pi / 2, np.pi, 3 * np.pi / 2
    r = island.cast_rays([0.0, 0.0], [north, east, south, west, np.arctan2(500, 1000)], 5000.0)
    np.testing.assert_allclose(r[[0, 4]], [1000.0, np.hypot(1000, 500)])
    assert np.isinf(r[1:4]).all()  # no land east, south or west
    # a short range stops short of the shore: no hit, not max_range
    assert np.isinf(island.cast_rays([0.0, 0.0], [north], 999.0)).all()
    # from the lagoon centre every ray hits the lagoon shore at 100..141 m
    a = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    r = island.cast_rays([1500.0, 0.0], a, 150.0)
    np.testing.assert_allclose(r, 100.0 / np.maximum(np.abs(np.cos(a)), np.abs(np.sin(a))))
    # east of the island, looking west (angle measured clockwise from north)
    assert island.cast_rays([1500.0, 800.0], [west], 500.0)[0] == pytest.approx(300.0)


def test_clip_edges_are_not_coast() -> None:
    box = Polygon([(0, -1000), (3000, -1000), (3000, 1000), (0, 1000)])
    land = Polygon([(1000, 0), (3000, 0), (3000, 1000), (1000, 1000)]).intersection(box)
    mask = LandMask(land, clip_boundary=box)
    assert mask.segments.shape[0] == 2  # the west and south shores; east and north are cuts
    assert mask.contains([[2000.0, 900.0]])[0]
    # inland, next to the cut: the distance is to the real shore (100 m), not to the cut
    assert mask.distance_to_shore([[2950.0, 100.0]])[0] == pytest.approx(100.0)
    assert mask.terrain_height_m([[2950.0, 900.0]])[0] > mask.terrain_height_m([[2950.0, 300.0]])[0]


@settings(max_examples=50, deadline=None)
@given(
    n=st.floats(-3000, 5000),
    e=st.floats(-3000, 3000),
    angle=st.floats(0, 2 * np.pi),
)
def test_island_rays_match_shapely(island: LandMask, n: float, e: float, angle: float) -> None:
    r = island.cast_rays([n, e], [angle], 4000.0)[0]
    ray = shapely.LineString([(n, e), (n + 4000 * np.cos(angle), e + 4000 * np.sin(angle))])
    hit = ray.intersection(ISLAND.boundary)
    expected = np.inf if hit.is_empty else shapely.distance(shapely.Point(n, e), hit)
    assert r == pytest.approx(expected, abs=1e-6)


def test_contains_matches_shapely_on_the_fjord(fjord: LandMask) -> None:
    b = default_scene().bounds_ned
    rng = np.random.default_rng(3)
    pts = np.column_stack(
        [rng.uniform(b[0] - 2e3, b[1] + 2e3, 50_000), rng.uniform(b[2] - 2e3, b[3] + 2e3, 50_000)]
    )
    got = fjord.contains(pts)
    np.testing.assert_array_equal(got, shapely.contains_xy(fjord.polygons, pts[:, 0], pts[:, 1]))
    assert 0.3 < got.mean() < 0.7  # the box is roughly half land


def test_distance_and_nearest_match_shapely(fjord: LandMask) -> None:
    scene = default_scene()
    rng = np.random.default_rng(4)
    b = scene.bounds_ned
    pts = np.column_stack([rng.uniform(b[0], b[1], 5000), rng.uniform(b[2], b[3], 5000)])
    pts = pts[shapely.contains_xy(scene.boundary_ned, pts[:, 0], pts[:, 1])]
    water = ~fjord.contains(pts)
    d = fjord.distance_to_shore(pts)
    # on water: distance to land; everywhere: distance to the coast line segments
    np.testing.assert_allclose(
        d[water], shapely.distance(fjord.polygons, shapely.points(pts[water])), atol=1e-6
    )
    coast = shapely.multilinestrings(shapely.linestrings(fjord.segments.reshape(-1, 2, 2)))
    np.testing.assert_allclose(d, shapely.distance(coast, shapely.points(pts)), atol=1e-6)
    near = fjord.nearest_shore_point(pts)
    np.testing.assert_allclose(np.hypot(*(near - pts).T), d, atol=1e-6)
    assert np.all(shapely.distance(coast, shapely.points(near)) < 1e-6)
    sd = fjord.signed_distance(pts)
    np.testing.assert_array_equal(sd < 0, ~water & (d > 0))
    # points far off the grid use the ring search fallback
    far = np.array([[b[1] + 20e3, 0.0], [0.0, b[2] - 30e3]])
    np.testing.assert_allclose(
        fjord.distance_to_shore(far), shapely.distance(coast, shapely.points(far))
    )


def test_fjord_rays_match_shapely(fjord: LandMask) -> None:
    origins = _water_points(fjord, 1500, seed=5)
    coastal = origins[fjord.distance_to_shore(origins) < 150.0][:40]
    assert len(coastal) >= 20
    rng = np.random.default_rng(6)
    angles = rng.uniform(0, 2 * np.pi, 90)
    boundary = fjord.polygons.boundary
    hits = 0
    for o in coastal:
        r = fjord.cast_rays(o, angles, 150.0)
        ends = o + 150.0 * np.column_stack([np.cos(angles), np.sin(angles)])
        rays = shapely.linestrings(np.stack([np.broadcast_to(o, ends.shape), ends], axis=1))
        inter = shapely.intersection(rays, boundary)
        expected = np.where(
            shapely.is_empty(inter), np.inf, shapely.distance(shapely.Point(o), inter)
        )
        np.testing.assert_allclose(r, expected, atol=1e-6)
        hits += int(np.isfinite(r).sum())
    assert hits > 200  # the check did exercise hits, not only misses


def test_cast_rays_many_equals_single_scans(fjord: LandMask) -> None:
    origins = _water_points(fjord, 30, seed=8)
    a = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    many = fjord.cast_rays_many(origins, a, 3000.0)
    assert many.shape == (30, 720)
    for k in (0, 7, 29):
        np.testing.assert_array_equal(many[k], fjord.cast_rays(origins[k], a, 3000.0))
    assert np.isfinite(many).any() and (many[np.isfinite(many)] <= 3000.0).all()


def test_segments_within_matches_brute_force(fjord: LandMask) -> None:
    for k, p in enumerate(_water_points(fjord, 30, seed=9)):
        radius = [50.0, 300.0, 2000.0][k % 3]
        got = fjord.segments_within(p, radius)
        lines = shapely.linestrings(fjord.segments.reshape(-1, 2, 2))
        want = fjord.segments[shapely.distance(lines, shapely.Point(p)) <= radius]
        np.testing.assert_array_equal(got, want)


def test_terrain_is_zero_on_water_and_rises_inland(fjord: LandMask) -> None:
    scene = default_scene()
    pts = np.column_stack(
        scene.frame.to_ned([63.50, 63.583, 63.60, 63.65], [10.20, 10.62, 10.00, 10.45])
    )
    h = fjord.terrain_height_m(pts)
    sd = fjord.signed_distance(pts)
    assert h[0] == 0.0 and sd[0] > 0
    np.testing.assert_allclose(h[1:], 400.0 * np.tanh(-sd[1:] / 1500.0))
    assert np.all((h >= 0) & (h < 400.0))


def test_bad_inputs_are_refused(island: LandMask) -> None:
    with pytest.raises(StateError, match=r"shape \(n, 2\)"):
        island.contains(np.zeros(3))
    with pytest.raises(StateError, match=r"origin must have shape \(2,\)"):
        island.cast_rays([0.0, 0.0, 0.0], [0.0], 10.0)
    with pytest.raises(ParameterError, match="max_range_m must be positive"):
        island.cast_rays([0.0, 0.0], [0.0], -1.0)
    with pytest.raises(ParameterError, match="at least one"):
        LandMask([])
    with pytest.raises(ParameterError, match="invalid land polygon"):
        LandMask(Polygon([(0, 0), (1, 1), (1, 0), (0, 1)]))
    assert island.segments.flags.writeable is False
