"""Scenes: the bundled Trondheim Fjord, and every kind of malformed scene file refused."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from asvtwin.errors import SceneError
from asvtwin.geo import SCENE_FORMAT, Scene, default_scene, load_scene

# Known points of the fjord (lat, lon, on land?), places as named on OpenStreetMap.
KNOWN = [
    ("Tautra", 63.583, 10.62, True),
    ("mid-fjord", 63.50, 10.20, False),
    ("Rissa", 63.60, 10.00, True),
    ("Munkholmen", 63.4514, 10.3836, True),  # a 200 m islet: land in the OSM extract
]


@pytest.mark.parametrize(("name", "lat", "lon", "land"), KNOWN)
def test_known_points_of_the_fjord(name: str, lat: float, lon: float, land: bool) -> None:
    scene = default_scene()
    p = np.column_stack(scene.frame.to_ned(lat, lon))
    assert bool(scene.land.contains(p)[0]) is land, name


def test_default_scene_header_and_geometry() -> None:
    scene = default_scene()
    assert isinstance(scene, Scene)
    assert default_scene() is scene  # cached
    assert scene.name == "Trondheim Fjord"
    assert (scene.frame.lat0_deg, scene.frame.lon0_deg) == (63.446, 10.39)
    assert (scene.bounds.lat_min_deg, scene.bounds.lat_max_deg) == (63.4, 63.7)
    assert (scene.bounds.lon_min_deg, scene.bounds.lon_max_deg) == (9.8, 10.8)
    assert "OpenStreetMap contributors" in scene.attribution
    assert "ODbL" in scene.licence
    assert "roaring-landmask" in scene.source
    # origin: water in the harbour, a few hundred metres from the quays
    assert not scene.land.contains(np.zeros((1, 2)))[0]
    assert 200.0 < scene.land.distance_to_shore(np.zeros((1, 2)))[0] < 1000.0
    # the box: 0.3 deg of latitude ~ 33.5 km, 1 deg of longitude at 63.5 N ~ 49.9 km
    n0, n1, e0, e1 = scene.bounds_ned
    assert n1 - n0 == pytest.approx(33_575, abs=150)
    assert e1 - e0 == pytest.approx(49_977, abs=150)
    assert n0 < 0 < n1 and e0 < 0 < e1
    # land covers roughly half of the box; 40 polygons from the OSM extract
    area_ratio = scene.land.polygons.area / scene.boundary_ned.area
    assert 0.4 < area_ratio < 0.6
    assert len(scene.land_lonlat.geoms) == 40
    # 1,165 ring edges, long ones densified every 0.005 deg, less the 6 edges cut by the box
    assert 1400 < scene.land.segments.shape[0] < 1800


def test_bundled_files_are_small_and_attributed() -> None:
    data = Path(__file__).resolve().parents[2] / "asvtwin" / "geo" / "data"
    assert (data / "trondheim_fjord.geojson").stat().st_size < 1_000_000
    note = (data / "ATTRIBUTION.md").read_text(encoding="utf-8")
    assert "© OpenStreetMap contributors" in note and "ODbL" in note


# ----------------------------------------------------------------------- malformed files
def _valid_doc() -> dict[str, Any]:
    """A 0.1 x 0.1 deg scene with one square island, origin on water."""
    island = [[[10.02, 63.52], [10.06, 63.52], [10.06, 63.56], [10.02, 63.56], [10.02, 63.52]]]
    return {
        "type": "FeatureCollection",
        "scene": {
            "format": SCENE_FORMAT,
            "name": "test",
            "origin": {"lat_deg": 63.51, "lon_deg": 10.01},
            "bounds": {
                "lat_min_deg": 63.5,
                "lat_max_deg": 63.6,
                "lon_min_deg": 10.0,
                "lon_max_deg": 10.1,
            },
            "attribution": "nobody",
            "licence": "CC0",
        },
        "features": [
            {
                "type": "Feature",
                "properties": {"kind": "land"},
                "geometry": {"type": "Polygon", "coordinates": island},
            }
        ],
    }


def _write(tmp_path: Path, doc: object, name: str = "bad.geojson") -> Path:
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc), encoding="utf-8")
    return path


def test_valid_minimal_scene_loads(tmp_path: Path) -> None:
    scene = load_scene(_write(tmp_path, _valid_doc(), "ok.geojson"))
    # the island is 0.04 deg x 0.04 deg: ~1.98 km east-west, ~4.46 km north-south
    assert scene.land.polygons.area == pytest.approx(1983 * 4459, rel=0.01)
    assert scene.source == "" and scene.path.endswith("ok.geojson")


def _set(path: str, value: Any) -> Any:
    def edit(doc: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = doc
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        if value is _DELETE:
            del node[last]
        else:
            node[int(last) if last.isdigit() else last] = value

    return edit


_DELETE = object()
BOWTIE = {
    "type": "Polygon",
    "coordinates": [
        [[10.02, 63.52], [10.06, 63.56], [10.06, 63.52], [10.02, 63.56], [10.02, 63.52]]
    ],
}

CASES = [
    ("missing scene", _set("scene", _DELETE), "missing field 'scene'"),
    ("missing name", _set("scene.name", _DELETE), "missing field 'scene.name'"),
    ("name not a string", _set("scene.name", 12), "'scene.name' must be a non-empty string"),
    ("wrong format", _set("scene.format", "v0"), "'scene.format' must be 'asvtwin-scene/1'"),
    (
        "origin lat too big",
        _set("scene.origin.lat_deg", 95.0),
        r"'scene.origin.lat_deg' must be a number in \[-90, 90\], actually: 95.0",
    ),
    (
        "origin lon a string",
        _set("scene.origin.lon_deg", "10"),
        r"'scene.origin.lon_deg' must be a number in \[-180, 180\]",
    ),
    (
        "origin lon too big",
        _set("scene.origin.lon_deg", 200),
        r"'scene.origin.lon_deg' must be a number in \[-180, 180\], actually: 200",
    ),
    ("origin missing", _set("scene.origin", _DELETE), "missing field 'scene.origin'"),
    (
        "origin outside bounds",
        _set("scene.origin.lat_deg", 63.7),
        "'scene.origin' must be inside scene.bounds",
    ),
    (
        "origin on land",
        _set("scene.origin", {"lat_deg": 63.54, "lon_deg": 10.04}),
        "'scene.origin' must be on water",
    ),
    (
        "bounds inverted",
        _set("scene.bounds.lat_max_deg", 63.4),
        "'scene.bounds.lat_max_deg' must be greater than lat_min_deg",
    ),
    (
        "bounds lat out of range",
        _set("scene.bounds.lat_min_deg", -100),
        r"'scene.bounds.lat_min_deg' must be a number in \[-90, 90\]",
    ),
    ("licence missing", _set("scene.licence", _DELETE), "missing field 'scene.licence'"),
    (
        "attribution empty",
        _set("scene.attribution", " "),
        "'scene.attribution' must be a non-empty string",
    ),
    ("no features", _set("features", []), "'features' must be a non-empty list"),
    ("not a feature", _set("features.0.type", "Thing"), "'features\\[0\\].type' must be 'Feature'"),
    (
        "other kind",
        _set("features.0.properties", {"kind": "buoy"}),
        "'features\\[0\\].properties.kind' must be 'land'",
    ),
    (
        "point geometry",
        _set("features.0.geometry", {"type": "Point", "coordinates": [10, 63]}),
        "'features\\[0\\].geometry.type' must be 'Polygon' or 'MultiPolygon'",
    ),
    (
        "self-intersecting",
        _set("features.0.geometry", BOWTIE),
        "'features\\[0\\].geometry' must be a valid polygon, actually: 'Self-intersection",
    ),
    (
        "empty polygon",
        _set("features.0.geometry", {"type": "Polygon", "coordinates": []}),
        "'features\\[0\\].geometry' must be a non-empty polygon",
    ),
    (
        "garbage coordinates",
        _set("features.0.geometry.coordinates", [[1, 2]]),
        "'features\\[0\\].geometry.coordinates' is malformed",
    ),
    (
        "latitude beyond 90",
        _set("features.0.geometry.coordinates.0.1", [10.06, 95.0]),
        "within \\[-180, 180\\] x \\[-90, 90\\]",
    ),
    (
        "land outside bounds",
        _set(
            "scene.bounds",
            {"lat_min_deg": 63.5, "lat_max_deg": 63.51, "lon_min_deg": 10.0, "lon_max_deg": 10.01},
        ),
        "no land inside the bounds",
    ),
    ("not a collection", _set("type", "Feature"), "'type' must be 'FeatureCollection'"),
]


@pytest.mark.parametrize(("case", "edit", "message"), CASES, ids=[c[0] for c in CASES])
def test_malformed_scene_is_refused(tmp_path: Path, case: str, edit: Any, message: str) -> None:
    doc = copy.deepcopy(_valid_doc())
    edit(doc)
    path = _write(tmp_path, doc)
    with pytest.raises(SceneError, match=message) as info:
        load_scene(path)
    assert str(path) in str(info.value)  # the message names the file
    assert isinstance(info.value, ValueError)


def test_unreadable_and_non_json_files(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match="missing.geojson: cannot read scene file"):
        load_scene(tmp_path / "missing.geojson")
    with pytest.raises(SceneError, match=r"bad.geojson: not valid JSON at line 2, column 1"):
        load_scene(_write(tmp_path, '{"type":\n}'))
    with pytest.raises(SceneError, match="'type' must be 'FeatureCollection', actually: 'list'"):
        load_scene(_write(tmp_path, "[1, 2]"))


def test_public_surface() -> None:
    import asvtwin.geo

    assert sorted(asvtwin.geo.__all__) == sorted(
        ["SCENE_FORMAT", "WGS84_A_M", "WGS84_F", "GeoBounds", "LandMask", "LocalFrame"]
        + ["Scene", "default_scene", "load_scene", "parse_scene"]
    )
    assert all(hasattr(asvtwin.geo, name) for name in asvtwin.geo.__all__)
