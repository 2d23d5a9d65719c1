"""WGS84 <-> local NED: agreement with pymap3d, round trips, a meridian-arc check."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from asvtwin.errors import ParameterError
from asvtwin.geo.frames import WGS84_A_M, WGS84_F, LocalFrame

pymap3d = pytest.importorskip("pymap3d")

LAT0, LON0 = 63.446, 10.390  # Trondheim harbour, origin of the default scene
FRAME = LocalFrame(LAT0, LON0)


def _scene_grid(n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(42)
    return rng.uniform(-40e3, 40e3, n), rng.uniform(-40e3, 40e3, n)


def test_to_ned_matches_pymap3d_within_1mm_over_the_scene() -> None:
    north, east = _scene_grid()
    lat, lon = FRAME.to_wgs84(north, east)
    n_ref, e_ref, d_ref = pymap3d.geodetic2ned(lat, lon, 0.0, LAT0, LON0, 0.0)
    n, e = FRAME.to_ned(lat, lon)
    assert np.max(np.abs(n - n_ref)) < 1e-3
    assert np.max(np.abs(e - e_ref)) < 1e-3
    # and the inverse lands on the ellipsoid at the asked plane position: pymap3d agrees
    assert np.max(np.abs(n_ref - north)) < 1e-3
    assert np.max(np.abs(e_ref - east)) < 1e-3
    # the dropped down component is the Earth's curvature: ~ r^2 / (2 R) = 250 m at 56 km
    assert 200.0 < d_ref.max() < 260.0


def test_pymap3d_inverse_agrees_with_to_wgs84() -> None:
    north, east = _scene_grid(500)
    lat, lon = FRAME.to_wgs84(north, east)
    # pymap3d needs the down component: take it from its own forward transform
    _, _, down = pymap3d.geodetic2ned(lat, lon, 0.0, LAT0, LON0, 0.0)
    lat_ref, lon_ref, h_ref = pymap3d.ned2geodetic(north, east, down, LAT0, LON0, 0.0)
    assert np.max(np.abs(h_ref)) < 1e-3
    # 1e-8 deg of latitude is ~1.1 mm
    assert np.max(np.abs(lat - lat_ref)) < 1e-8
    assert np.max(np.abs(lon - lon_ref)) < 2e-8


def test_round_trip_below_1mm_both_ways() -> None:
    north, east = _scene_grid()
    n2, e2 = FRAME.to_ned(*FRAME.to_wgs84(north, east))
    assert np.max(np.hypot(n2 - north, e2 - east)) < 1e-6
    rng = np.random.default_rng(7)
    lat = rng.uniform(63.4, 63.7, 1000)
    lon = rng.uniform(9.8, 10.8, 1000)
    lat2, lon2 = FRAME.to_wgs84(*FRAME.to_ned(lat, lon))
    assert np.max(np.abs(lat2 - lat)) * 111e3 < 1e-6
    assert np.max(np.abs(lon2 - lon)) * 50e3 < 1e-6


def test_origin_maps_to_zero_and_axes_point_north_and_east() -> None:
    n, e = FRAME.to_ned(LAT0, LON0)
    assert abs(float(n)) < 1e-9 and abs(float(e)) < 1e-9
    n, e = FRAME.to_ned(LAT0 + 0.01, LON0)
    assert n > 1000.0 and abs(float(e)) < 1e-6
    n, e = FRAME.to_ned(LAT0, LON0 + 0.01)
    assert e > 400.0 and abs(float(n)) < 1.0  # tiny northing: the parallel curves away


def test_northing_equals_meridian_arc() -> None:
    """0.05 deg north of the origin: the tangent-plane northing is the meridian arc length
    minus the chord shortening s^3 / (6 M^2) (~0.9 mm at 5.6 km)."""
    e2 = WGS84_F * (2 - WGS84_F)

    def meridian_radius(phi: float) -> float:
        return WGS84_A_M * (1 - e2) / (1 - e2 * math.sin(phi) ** 2) ** 1.5

    phi0 = math.radians(LAT0)
    arc, _ = quad(meridian_radius, phi0, phi0 + math.radians(0.05))
    n, _ = FRAME.to_ned(LAT0 + 0.05, LON0)
    assert 5570.0 < arc < 5577.0  # ~111.47 km per degree of latitude at 63.4 N
    shortening = arc**3 / (6 * meridian_radius(phi0) ** 2)
    assert abs(float(n) - (arc - shortening)) < 5e-4


def test_vectorised_shapes_broadcast() -> None:
    lat = np.full((3, 4), LAT0 + 0.02)
    n, e = FRAME.to_ned(lat, LON0)
    assert n.shape == (3, 4) and e.shape == (3, 4)
    lat2, lon2 = FRAME.to_wgs84(n, e)
    assert lat2.shape == lon2.shape == (3, 4)
    np.testing.assert_allclose(lon2, LON0, atol=1e-11)
    np.testing.assert_allclose(lat2, LAT0 + 0.02, atol=1e-11)
    pts = FRAME.points_to_ned([[LON0, LAT0], [LON0, LAT0 + 0.02]])
    assert pts.shape == (2, 2)
    np.testing.assert_allclose(FRAME.points_to_lonlat(pts), [[LON0, LAT0], [LON0, LAT0 + 0.02]])


@settings(max_examples=60, deadline=None)
@given(
    lat0=st.floats(-80, 80),
    lon0=st.floats(-180, 180),
    north=st.floats(-60e3, 60e3),
    east=st.floats(-60e3, 60e3),
)
def test_round_trip_anywhere(lat0: float, lon0: float, north: float, east: float) -> None:
    frame = LocalFrame(lat0, lon0)
    n2, e2 = frame.to_ned(*frame.to_wgs84(north, east))
    assert abs(float(n2) - north) < 1e-6
    assert abs(float(e2) - east) < 1e-6


@pytest.mark.parametrize(
    ("lat0", "lon0", "field"),
    [
        (90.0, 0.0, "lat0_deg"),
        (-91.0, 0.0, "lat0_deg"),
        (math.nan, 0.0, "lat0_deg"),
        (10.0, 180.5, "lon0_deg"),
        (10.0, "10", "lon0_deg"),
        (True, 10.0, "lat0_deg"),
    ],
)
def test_invalid_origin_is_refused(lat0: object, lon0: object, field: str) -> None:
    with pytest.raises(ParameterError, match=field):
        LocalFrame(lat0, lon0)  # type: ignore[arg-type]


def test_frame_is_frozen_and_hashable() -> None:
    assert LocalFrame(63.0, 10.0) == LocalFrame(63.0, 10.0)
    assert len({LocalFrame(63.0, 10.0), LocalFrame(63.0, 10.0)}) == 1
    with pytest.raises(AttributeError):
        FRAME.lat0_deg = 1.0  # type: ignore[misc]
