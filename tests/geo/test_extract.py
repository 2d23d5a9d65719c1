"""The bundled coastline against the project's reference extracts, and the extraction tool."""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiPolygon

from asvtwin.geo import default_scene, load_scene

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = ROOT / "asvtwin" / "geo" / "data" / "trondheim_fjord.geojson"

needs_world_mask = (
    pytest.mark.slow,
    pytest.mark.skipif(
        os.environ.get("ASVTWIN_FULL", "") in ("", "0"),
        reason="reads the whole-world land mask of roaring-landmask (~10 s CPU, ~1 GB); "
               "set ASVTWIN_FULL=1",
    ),
)


def _tool():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(
        "extract_coastline", ROOT / "tools" / "extract_coastline.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _source_land(provider: str):  # type: ignore[no-untyped-def]
    """The fjord's land straight from the original source: the world land mask of the PyPI
    package roaring-landmask (OpenStreetMap-derived, or GSHHG, Wessel and Smith 1996),
    clipped to the scene's box; independent of the bundled file."""
    rl = pytest.importorskip(
        "roaring_landmask", reason="needs the 'data' extra: pip install 'asvtwin[data]'")
    which = getattr(rl.LandmaskProvider, provider)
    world = shapely.get_parts(shapely.from_wkb(rl.Shapes.wkb(which)))
    box = shapely.box(9.8, 63.4, 10.8, 63.7)
    tree = shapely.STRtree(world)
    near = world[tree.query(box, predicate="intersects")]
    return shapely.union_all(shapely.intersection(near, box))


def test_known_points_of_the_bundled_extract() -> None:
    # places as named on OpenStreetMap: Tautra and Rissa are land, mid-fjord is water
    scene = default_scene()
    for lon, lat, land in [(10.62, 63.583, True), (10.20, 63.50, False),
                           (10.00, 63.60, True)]:
        p = np.column_stack(scene.frame.to_ned(lat, lon))
        assert bool(scene.land.contains(p)[0]) is land


@needs_world_mask[0]
@needs_world_mask[1]
def test_bundled_extract_matches_its_source() -> None:
    ref = _source_land("Osm")
    ours = default_scene().land_lonlat
    # same source and box: the areas agree to rounding (1e-6 deg ~ 0.1 m)
    assert ours.area == pytest.approx(ref.area, rel=1e-4)
    assert ours.symmetric_difference(ref).area / ref.area < 1e-3
    assert shapely.hausdorff_distance(ours.boundary, ref.boundary) < 1e-4  # < ~10 m
    # random points: disagreement only within a metre of the coast
    scene = default_scene()
    rng = np.random.default_rng(11)
    lat = rng.uniform(63.4, 63.7, 20_000)
    lon = rng.uniform(9.8, 10.8, 20_000)
    inside = scene.land.contains(np.column_stack(scene.frame.to_ned(lat, lon)))
    differ = inside != shapely.contains_xy(ref, lon, lat)
    assert differ.sum() <= 5
    if differ.any():
        assert shapely.distance(ref.boundary, shapely.points(lon[differ], lat[differ])).max() < 1e-4


@needs_world_mask[0]
@needs_world_mask[1]
def test_osm_and_gshhg_sources_agree_to_tens_of_metres() -> None:
    osm, gshhg = _source_land("Osm"), _source_land("Gshhg")
    # Munkholmen (a 200 m islet off Trondheim) is in the OpenStreetMap land, not in GSHHG
    assert osm.contains(shapely.Point(10.3836, 63.4514))
    assert not gshhg.contains(shapely.Point(10.3836, 63.4514))
    # the two independent sources agree on ~95 % of the land area
    assert osm.symmetric_difference(gshhg).area / osm.area < 0.1


def test_write_scene_round_trip(tmp_path: Path) -> None:
    tool = _tool()
    land = MultiPolygon([shapely.box(10.02, 63.52, 10.06, 63.56)])
    out = tmp_path / "tiny.geojson"
    tool.write_scene(
        out,
        land,
        name="tiny",
        origin=(63.51, 10.01),
        box=(63.5, 63.6, 10.0, 10.1),
        provider="osm",
        simplify_m=0.0,
    )
    scene = load_scene(out)
    assert scene.name == "tiny" and scene.attribution == "© OpenStreetMap contributors"
    assert "ODbL" in scene.licence and "roaring-landmask" in scene.source
    assert scene.land_lonlat.equals(land)
    note = (tmp_path / "ATTRIBUTION.md").read_text(encoding="utf-8")
    assert "tiny.geojson" in note and "© OpenStreetMap contributors" in note


@pytest.mark.slow
@pytest.mark.skipif(
    os.environ.get("ASVTWIN_FULL", "") in ("", "0"),
    reason="reads the whole-world land mask (~10 s, ~1 GB); set ASVTWIN_FULL=1",
)
def test_tool_reproduces_the_bundled_file(tmp_path: Path) -> None:
    pytest.importorskip(
        "roaring_landmask", reason="needs the 'data' extra: pip install 'asvtwin[data]'"
    )
    tool = _tool()
    out = tmp_path / "trondheim_fjord.geojson"
    assert tool.main(["--out", str(out)]) == 0
    assert (
        json.loads(out.read_text(encoding="utf-8"))["features"]
        == json.loads(BUNDLED.read_text(encoding="utf-8"))["features"]
    )
