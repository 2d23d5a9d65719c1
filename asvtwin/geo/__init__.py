"""Geography of the twin: WGS84 <-> local NED frames, land polygons and scenes.

Everything inside the twin is in the local NED tangent plane of the scene origin
(x north, y east, metres); latitude/longitude appear only at the edges.

Examples
--------
>>> from asvtwin.geo import default_scene
>>> scene = default_scene()
>>> bool(scene.land.contains([[0.0, 0.0]])[0])  # the origin is on water
False
"""

from __future__ import annotations

from asvtwin.geo.frames import WGS84_A_M, WGS84_F, LocalFrame
from asvtwin.geo.land import LandMask
from asvtwin.geo.scene import SCENE_FORMAT, GeoBounds, Scene, default_scene, load_scene, parse_scene

__all__ = [
    "SCENE_FORMAT",
    "WGS84_A_M",
    "WGS84_F",
    "GeoBounds",
    "LandMask",
    "LocalFrame",
    "Scene",
    "default_scene",
    "load_scene",
    "parse_scene",
]
