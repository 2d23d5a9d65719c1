"""Regenerate a scene file's land polygons from the PyPI package ``roaring-landmask``.

``roaring-landmask`` (>= 0.11, ``pip install 'asvtwin[data]'``) ships the whole world's land
as WKB: ``Shapes.wkb(LandmaskProvider.Osm)`` is derived from OpenStreetMap (ODbL),
``LandmaskProvider.Gshhg`` is GSHHG (LGPL-3.0). This script cuts a lat/lon box out of it
with shapely, optionally simplifies it in metres, and writes an asvtwin scene file (see
``asvtwin/geo/scene.py``) plus an ``ATTRIBUTION.md`` beside it.

Default: the bundled Trondheim Fjord scene::

    python tools/extract_coastline.py                    # -> asvtwin/geo/data/
    python tools/extract_coastline.py --box 63.3 63.5 10.2 10.6 --origin 63.45 10.39 \\
        --name "Trondheim harbour" --out /tmp/harbour.geojson

The whole-world WKB is ~150 MB; reading it takes a few seconds and ~1 GB of memory.
"""

from __future__ import annotations

import argparse
import json
import sys
from importlib import metadata
from pathlib import Path

import shapely
from shapely.geometry import MultiPolygon, Polygon

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from asvtwin.geo.frames import LocalFrame
from asvtwin.geo.scene import SCENE_FORMAT, load_scene

__all__ = ["extract_land", "main"]

_LICENCES = {
    "osm": (
        "© OpenStreetMap contributors",
        (
            "Open Database License (ODbL) v1.0, https://opendatacommons.org/licenses/odbl/1-0/ . "
            "This extract is a Derivative Database of OpenStreetMap data and stays under the ODbL."
        ),
    ),
    "gshhg": (
        "GSHHG, Wessel and Smith (1996), https://www.soest.hawaii.edu/pwessel/gshhg/",
        "GNU Lesser General Public License v3.0 (LGPL-3.0)",
    ),
}


def extract_land(
    lat_min: float, lat_max: float, lon_min: float, lon_max: float, *, provider: str = "osm"
) -> MultiPolygon:
    """Land of the box from roaring-landmask, clipped with shapely, in ``(lon, lat)`` [deg].

    Parameters
    ----------
    lat_min, lat_max, lon_min, lon_max : float
        The box [deg].
    provider : {"osm", "gshhg"}
        Which of the package's land masks to read.

    Returns
    -------
    MultiPolygon
        The clipped land (possibly empty).
    """
    try:
        import roaring_landmask as rl
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise SystemExit("roaring-landmask is missing: pip install 'asvtwin[data]'") from exc
    which = {"osm": rl.LandmaskProvider.Osm, "gshhg": rl.LandmaskProvider.Gshhg}[provider]
    world = shapely.get_parts(shapely.from_wkb(rl.Shapes.wkb(which)))
    box = shapely.box(lon_min, lat_min, lon_max, lat_max)
    near = world[shapely.STRtree(world).query(box, predicate="intersects")]
    land = shapely.union_all(shapely.intersection(near, box))
    return MultiPolygon(
        [p for p in shapely.get_parts(land) if isinstance(p, Polygon) and p.area > 0]
    )


def _simplify(land: MultiPolygon, frame: LocalFrame, tolerance_m: float) -> MultiPolygon:
    """Topology-preserving Douglas-Peucker in the local frame [m], back to lon/lat."""
    ned = shapely.transform(land, frame.points_to_ned)
    simple = shapely.simplify(ned, tolerance_m, preserve_topology=True)
    back = shapely.transform(simple, frame.points_to_lonlat)
    return MultiPolygon(
        [p for p in shapely.get_parts(back) if isinstance(p, Polygon) and p.area > 0]
    )


def _rounded(land: MultiPolygon, decimals: int) -> MultiPolygon:
    """Round coordinates (6 decimals ~ 0.1 m) and repair any polygon this breaks."""
    out = shapely.set_precision(land, 10.0**-decimals)
    if not out.is_valid:  # pragma: no cover - set_precision keeps validity in practice
        out = shapely.make_valid(out)
    return MultiPolygon([p for p in shapely.get_parts(out) if isinstance(p, Polygon)])


def write_scene(
    out: Path,
    land: MultiPolygon,
    *,
    name: str,
    origin: tuple[float, float],
    box: tuple[float, float, float, float],
    provider: str,
    simplify_m: float,
) -> None:
    """Write the scene file ``out`` and ``ATTRIBUTION.md`` beside it.

    Parameters
    ----------
    out : Path
        The scene file to write.
    land : MultiPolygon
        Land in ``(lon, lat)`` [deg], already clipped to ``box``.
    name : str
        Scene name.
    origin : tuple of float
        ``(lat, lon)`` of the NED origin [deg].
    box : tuple of float
        ``(lat_min, lat_max, lon_min, lon_max)`` [deg].
    provider : {"osm", "gshhg"}
        Source of the land, selects attribution and licence.
    simplify_m : float
        Simplification tolerance that was applied [m] (0: none), recorded in ``source``.
    """
    try:
        version = metadata.version("roaring-landmask")
    except metadata.PackageNotFoundError:
        version = "(version unknown)"
    attribution, licence = _LICENCES[provider]
    method = f"clipped to the box with shapely {shapely.__version__}"
    if simplify_m > 0:
        method += f", simplified (Douglas-Peucker, topology preserved) at {simplify_m:g} m"
    source = (
        f"roaring-landmask {version} (PyPI), Shapes.wkb(LandmaskProvider.{provider.capitalize()}), "
        f"{method}, coordinates rounded to 1e-6 deg; made by tools/extract_coastline.py"
    )
    lat_min, lat_max, lon_min, lon_max = box
    geometry = json.loads(shapely.to_geojson(land))
    doc = {
        "type": "FeatureCollection",
        "scene": {
            "format": SCENE_FORMAT,
            "name": name,
            "origin": {"lat_deg": origin[0], "lon_deg": origin[1]},
            "bounds": {
                "lat_min_deg": lat_min,
                "lat_max_deg": lat_max,
                "lon_min_deg": lon_min,
                "lon_max_deg": lon_max,
            },
            "attribution": attribution,
            "licence": licence,
            "source": source,
        },
        "features": [{"type": "Feature", "properties": {"kind": "land"}, "geometry": geometry}],
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(doc, ensure_ascii=False, separators=(",", ":")) + "\n", encoding="utf-8"
    )
    (out.parent / "ATTRIBUTION.md").write_text(
        f"# Attribution and licence of `{out.name}`\n\n"
        f"Land polygons: **{attribution}**.\n\n"
        f"Licence: {licence}\n\n"
        f"Source: {source}.\n\n"
        "Box: lat {0}–{1} N, lon {2}–{3} E. Neither source is quay-accurate: expect tens of "
        "metres of error along the coast.\n".format(lat_min, lat_max, lon_min, lon_max),
        encoding="utf-8",
    )


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--box",
        nargs=4,
        type=float,
        metavar=("LAT_MIN", "LAT_MAX", "LON_MIN", "LON_MAX"),
        default=(63.4, 63.7, 9.8, 10.8),
        help="box [deg] (default: Trondheim Fjord)",
    )
    ap.add_argument(
        "--origin",
        nargs=2,
        type=float,
        metavar=("LAT", "LON"),
        default=(63.446, 10.390),
        help="NED origin [deg], must be on water (default: Trondheim harbour)",
    )
    ap.add_argument("--name", default="Trondheim Fjord")
    ap.add_argument("--provider", choices=sorted(_LICENCES), default="osm")
    ap.add_argument(
        "--simplify-m",
        type=float,
        default=0.0,
        help="Douglas-Peucker tolerance [m]; 0 keeps every vertex (default)",
    )
    ap.add_argument(
        "--out", type=Path, default=ROOT / "asvtwin" / "geo" / "data" / "trondheim_fjord.geojson"
    )
    args = ap.parse_args(argv)
    lat_min, lat_max, lon_min, lon_max = args.box
    land = extract_land(lat_min, lat_max, lon_min, lon_max, provider=args.provider)
    n_raw = shapely.get_num_coordinates(land)
    if args.simplify_m > 0:
        land = _simplify(land, LocalFrame(*args.origin), args.simplify_m)
    land = _rounded(land, 6)
    write_scene(
        args.out,
        land,
        name=args.name,
        origin=tuple(args.origin),
        box=tuple(args.box),
        provider=args.provider,
        simplify_m=args.simplify_m,
    )
    scene = load_scene(args.out)  # validates the result (origin on water, polygons valid...)
    print(
        json.dumps(
            {
                "out": str(args.out),
                "polygons": len(land.geoms),
                "vertices_raw": int(n_raw),
                "vertices": int(shapely.get_num_coordinates(land)),
                "coast_segments": int(scene.land.segments.shape[0]),
                "bytes": args.out.stat().st_size,
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
