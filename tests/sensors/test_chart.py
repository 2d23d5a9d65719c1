"""The imperfect chart: bounded, seeded errors of a coast (checked with shapely)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Point, Polygon

from asvtwin.errors import ParameterError
from asvtwin.geo import LandMask
from asvtwin.sensors import perturb_chart


def _world() -> LandMask:
    e = np.linspace(-2000.0, 2000.0, 201)
    n = 300.0 + 15.0 * np.sin(e / 40.0)
    coast = Polygon(np.vstack([np.column_stack([n, e]), [[2000.0, 2000.0], [2000.0, -2000.0]]]))
    islet = Point(100.0, 400.0).buffer(15.0)  # ~700 m²: a skerry
    pier = Polygon([(280.0, -100.0), (280.0, -96.0), (240.0, -96.0), (240.0, -100.0)])  # 160 m²
    return LandMask([coast, islet, pier])


def test_chart_error_is_bounded_by_its_settings() -> None:
    world = _world()
    chart = perturb_chart(world, np.random.default_rng(3), offset_m=5.0, warp_m=2.0, simplify_m=3.0,
                          drop_probability=0.0)
    big_w = max(world.polygons.geoms, key=lambda p: p.area)
    big_c = max(chart.polygons.geoms, key=lambda p: p.area)
    h = shapely.hausdorff_distance(big_w.exterior, big_c.exterior)
    assert 3.0 < h <= 5.0 + 2.0 + 3.0 + 1e-6  # moved, but within the error bound
    assert len(chart.polygons.geoms) == 3


def test_small_features_are_dropped_and_the_run_is_seeded() -> None:
    world = _world()
    a = perturb_chart(world, np.random.default_rng(7))
    b = perturb_chart(world, np.random.default_rng(7))
    assert len(a.polygons.geoms) == 1  # the islet and the pier are missing from the chart
    assert a.polygons.equals_exact(b.polygons, 0.0)
    c = perturb_chart(world, np.random.default_rng(8))
    assert not a.polygons.equals_exact(c.polygons, 1e-6)


def test_zero_error_returns_the_same_coast() -> None:
    world = _world()
    chart = perturb_chart(world, np.random.default_rng(0), offset_m=0.0, warp_m=0.0, simplify_m=0.0,
                          drop_probability=0.0)
    assert shapely.hausdorff_distance(world.polygons, chart.polygons) < 1e-9


@pytest.mark.parametrize("bad", [{"offset_m": -1.0}, {"warp_m": float("nan")}, {"warp_wavelength_m": 0.0},
                                 {"drop_probability": 1.5}, {"simplify_m": float("inf")}])
def test_bad_settings_are_refused_with_the_field_named(bad: dict[str, float]) -> None:
    with pytest.raises(ParameterError, match=next(iter(bad))):
        perturb_chart(_world(), np.random.default_rng(0), **bad)  # type: ignore[arg-type]
