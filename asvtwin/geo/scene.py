"""Scenes: a named piece of coast with its local frame, bounds, land and licence.

A scene is one file, a GeoJSON ``FeatureCollection`` (RFC 7946, so GIS tools open it) with a
foreign member ``"scene"`` holding the header::

    {
      "type": "FeatureCollection",
      "scene": {
        "format": "asvtwin-scene/1",
        "name": "Trondheim Fjord",
        "origin": {"lat_deg": 63.446, "lon_deg": 10.39},
        "bounds": {"lat_min_deg": 63.4, "lat_max_deg": 63.7,
                   "lon_min_deg": 9.8, "lon_max_deg": 10.8},
        "attribution": "© OpenStreetMap contributors",
        "licence": "Open Database License (ODbL) v1.0 ...",
        "source": "roaring-landmask 0.11.0 ..."            (optional)
      },
      "features": [
        {"type": "Feature", "properties": {"kind": "land"},
         "geometry": {"type": "MultiPolygon", "coordinates": [...]}}
      ]
    }

Coordinates are ``(lon, lat)`` WGS84 degrees. Land is clipped to ``bounds``; the origin
anchors the NED frame and must be on water inside the bounds. Every violation raises
:class:`~asvtwin.errors.SceneError` naming the file, the field and the allowed values.
"""

from __future__ import annotations

import functools
import json
import math
import numbers
import os
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon, shape

from asvtwin.errors import SceneError
from asvtwin.geo.frames import LocalFrame
from asvtwin.geo.land import LandMask

__all__ = ["SCENE_FORMAT", "GeoBounds", "Scene", "default_scene", "load_scene", "parse_scene"]

#: Value of ``scene.format`` understood by this version.
SCENE_FORMAT = "asvtwin-scene/1"
_DEFAULT_SCENE_FILE = "trondheim_fjord.geojson"
_DENSIFY_DEG = 0.005


@dataclass(frozen=True)
class GeoBounds:
    """A latitude/longitude box [deg]."""

    lat_min_deg: float
    lat_max_deg: float
    lon_min_deg: float
    lon_max_deg: float

    def polygon(self) -> Polygon:
        """The box as a shapely polygon in ``(lon, lat)`` [deg]."""
        return shapely.box(self.lon_min_deg, self.lat_min_deg, self.lon_max_deg, self.lat_max_deg)

    def contains(self, lat_deg: float, lon_deg: float) -> bool:
        """Whether a position [deg] lies in the box (edges included)."""
        return bool(
            self.lat_min_deg <= lat_deg <= self.lat_max_deg
            and self.lon_min_deg <= lon_deg <= self.lon_max_deg
        )


@dataclass(frozen=True, eq=False)
class Scene:
    """A loaded scene: frame, bounds, land and the terms of use of its data.

    Attributes
    ----------
    name : str
        Human-readable name.
    frame : LocalFrame
        The local NED frame anchored at the scene origin.
    bounds : GeoBounds
        The scene box [deg].
    bounds_ned : tuple of float
        ``(north_min, north_max, east_min, east_max)`` [m]: the NED bounding box of the
        scene box (its edges are slightly curved in NED).
    boundary_ned : shapely Polygon
        The scene box in NED [m] (``x`` north, ``y`` east), edges densified every 0.005 deg.
    land : LandMask
        Land in NED with the coast queries.
    land_lonlat : shapely MultiPolygon
        The same land in ``(lon, lat)`` [deg], for the viewer.
    attribution, licence : str
        Attribution to display and the licence of the land data.
    source : str
        Where the land data came from (may be empty).
    path : str
        The file the scene was read from.
    """

    name: str
    frame: LocalFrame
    bounds: GeoBounds
    bounds_ned: tuple[float, float, float, float]
    boundary_ned: Polygon
    land: LandMask
    land_lonlat: MultiPolygon
    attribution: str
    licence: str
    source: str
    path: str


def _fail(label: str, field: str, expected: str, actual: object) -> SceneError:
    return SceneError(f"{label}: field {field!r} must be {expected}, actually: {actual!r}")


def _get(obj: dict[str, Any], key: str, label: str, prefix: str) -> Any:
    if key not in obj:
        raise SceneError(f"{label}: missing field {prefix + key!r}")
    return obj[key]


def _text(obj: dict[str, Any], key: str, label: str, prefix: str, *, required: bool = True) -> str:
    if not required and key not in obj:
        return ""
    value = _get(obj, key, label, prefix)
    if not isinstance(value, str) or not value.strip():
        raise _fail(label, prefix + key, "a non-empty string", value)
    return value


def _number(obj: dict[str, Any], key: str, label: str, prefix: str, lo: float, hi: float) -> float:
    value = _get(obj, key, label, prefix)
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or not lo <= value <= hi:
        raise _fail(label, prefix + key, f"a number in [{lo:g}, {hi:g}]", value)
    return float(value)


def _object(obj: dict[str, Any], key: str, label: str, prefix: str) -> dict[str, Any]:
    value = _get(obj, key, label, prefix)
    if not isinstance(value, dict):
        raise _fail(label, prefix + key, "a JSON object", type(value).__name__)
    return value


def _land(doc: dict[str, Any], label: str) -> list[Polygon]:
    features = _get(doc, "features", label, "")
    if not isinstance(features, list) or not features:
        raise _fail(label, "features", "a non-empty list of land features", features)
    parts: list[Polygon] = []
    for k, feat in enumerate(features):
        where = f"features[{k}]"
        if not isinstance(feat, dict) or feat.get("type") != "Feature":
            found = feat.get("type") if isinstance(feat, dict) else type(feat).__name__
            raise _fail(label, f"{where}.type", "'Feature'", found)
        props = feat.get("properties") or {}
        if not isinstance(props, dict) or props.get("kind", "land") != "land":
            raise _fail(
                label,
                f"{where}.properties.kind",
                "'land'",
                props.get("kind") if isinstance(props, dict) else props,
            )
        geo = _object(feat, "geometry", label, f"{where}.")
        if geo.get("type") not in ("Polygon", "MultiPolygon"):
            raise _fail(
                label, f"{where}.geometry.type", "'Polygon' or 'MultiPolygon'", geo.get("type")
            )
        try:
            geom = shape(geo)
        except Exception as exc:  # shapely raises several types for bad coordinates
            raise SceneError(
                f"{label}: field '{where}.geometry.coordinates' is malformed: {exc}"
            ) from exc
        if geom.is_empty:
            raise _fail(label, f"{where}.geometry", "a non-empty polygon", "empty")
        xy = shapely.get_coordinates(geom)
        if not (
            np.isfinite(xy).all()
            and (np.abs(xy[:, 0]) <= 180).all()
            and (np.abs(xy[:, 1]) <= 90).all()
        ):
            raise _fail(
                label,
                f"{where}.geometry.coordinates",
                "(lon, lat) within [-180, 180] x [-90, 90]",
                "out of range",
            )
        if not geom.is_valid:
            raise _fail(
                label, f"{where}.geometry", "a valid polygon", shapely.is_valid_reason(geom)
            )
        parts.extend(p for p in shapely.get_parts(geom) if not p.is_empty)
    return parts


def parse_scene(doc: object, *, label: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from a decoded scene document.

    Parameters
    ----------
    doc : object
        The JSON document (see the module docstring for the format).
    label : str
        Name of the file, used in error messages.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        If any field is missing, of the wrong type or out of range, a polygon is invalid or
        the origin is outside the bounds or on land.
    """
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        found = doc.get("type") if isinstance(doc, dict) else type(doc).__name__
        raise _fail(label, "type", "'FeatureCollection'", found)
    head = _object(doc, "scene", label, "")
    fmt = _get(head, "format", label, "scene.")
    if fmt != SCENE_FORMAT:
        raise _fail(label, "scene.format", repr(SCENE_FORMAT), fmt)
    name = _text(head, "name", label, "scene.")
    origin = _object(head, "origin", label, "scene.")
    lat0 = _number(origin, "lat_deg", label, "scene.origin.", -90.0, 90.0)
    lon0 = _number(origin, "lon_deg", label, "scene.origin.", -180.0, 180.0)
    if abs(lat0) == 90.0:
        raise _fail(label, "scene.origin.lat_deg", "a number in (-90, 90) (no poles)", lat0)
    box = _object(head, "bounds", label, "scene.")
    p = "scene.bounds."
    b = GeoBounds(
        _number(box, "lat_min_deg", label, p, -90.0, 90.0),
        _number(box, "lat_max_deg", label, p, -90.0, 90.0),
        _number(box, "lon_min_deg", label, p, -180.0, 180.0),
        _number(box, "lon_max_deg", label, p, -180.0, 180.0),
    )
    if not b.lat_min_deg < b.lat_max_deg:
        raise _fail(
            label, p + "lat_max_deg", f"greater than lat_min_deg = {b.lat_min_deg}", b.lat_max_deg
        )
    if not b.lon_min_deg < b.lon_max_deg:
        raise _fail(
            label, p + "lon_max_deg", f"greater than lon_min_deg = {b.lon_min_deg}", b.lon_max_deg
        )
    if not b.contains(lat0, lon0):
        raise _fail(
            label, "scene.origin", f"inside scene.bounds {b}", {"lat_deg": lat0, "lon_deg": lon0}
        )
    attribution = _text(head, "attribution", label, "scene.")
    licence = _text(head, "licence", label, "scene.")
    source = _text(head, "source", label, "scene.", required=False)

    land_ll = shapely.intersection(shapely.union_all(_land(doc, label)), b.polygon())
    polys = [q for q in shapely.get_parts(land_ll) if isinstance(q, Polygon) and not q.is_empty]
    if not polys:
        raise _fail(
            label, "features", "land polygons overlapping scene.bounds", "no land inside the bounds"
        )
    land_lonlat = MultiPolygon(polys)
    frame = LocalFrame(lat0, lon0)
    # Straight lon/lat edges are curves in NED (a parallel bends by ~15 m over 20 km):
    # densify every 0.005 deg (~250-560 m) before projecting; the chords then stay within
    # ~1 cm of the lon/lat geometry.
    step = _DENSIFY_DEG
    to_ned = frame.points_to_ned
    boundary = shapely.transform(shapely.segmentize(b.polygon(), step), to_ned)
    n0, e0, n1, e1 = boundary.bounds
    land_ned = shapely.transform(shapely.segmentize(land_lonlat, step), to_ned)
    land_ned = shapely.make_valid(land_ned)
    land = LandMask(land_ned, clip_boundary=boundary)
    if land.contains(np.zeros((1, 2)))[0]:
        raise _fail(
            label,
            "scene.origin",
            "on water (the frame origin cannot be on land)",
            {"lat_deg": lat0, "lon_deg": lon0},
        )
    return Scene(
        name=name,
        frame=frame,
        bounds=b,
        bounds_ned=(n0, n1, e0, e1),
        boundary_ned=boundary,
        land=land,
        land_lonlat=land_lonlat,
        attribution=attribution,
        licence=licence,
        source=source,
        path=label,
    )


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Load a scene file.

    Parameters
    ----------
    path : str or path-like
        A scene file (GeoJSON FeatureCollection with a ``scene`` header).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        If the file cannot be read, is not JSON or is not a valid scene; the message names
        the file and the offending field.
    """
    label = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise SceneError(f"{label}: cannot read scene file: {exc.strerror or exc}") from exc
    return _parse_text(text, label)


def _parse_text(text: str, label: str) -> Scene:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneError(
            f"{label}: not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}"
        ) from exc
    return parse_scene(doc, label=label)


@functools.cache
def default_scene() -> Scene:
    """The bundled Trondheim Fjord scene (63.4–63.7 N, 9.8–10.8 E), loaded once and cached.

    Returns
    -------
    Scene
        Land from OpenStreetMap (© OpenStreetMap contributors, ODbL) via roaring-landmask;
        origin in Trondheim harbour, 63.446 N 10.390 E.
    """
    res = resources.files("asvtwin.geo").joinpath("data", _DEFAULT_SCENE_FILE)
    return _parse_text(res.read_text(encoding="utf-8"), f"asvtwin/geo/data/{_DEFAULT_SCENE_FILE}")
