"""Benchmark of asvtwin.geo on the bundled Trondheim Fjord scene; prints one JSON object.

Times are medians in microseconds (time.perf_counter), after a warm-up that also excludes
numba's compilation. Ray scans start at random water points of the scene (seeded).

    python benchmarks/geo.py [--repeats 2000]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import shapely

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from asvtwin.geo import default_scene
from asvtwin.geo.land import LandMask

__all__ = ["cast_rays_numpy", "main", "water_points"]


def _median_us(fn: Callable[[int], object], repeats: int) -> float:
    """Median wall time [us] of ``fn(k)`` over ``repeats`` calls, after 20 warm-up calls."""
    for k in range(20):
        fn(k)
    times = []
    for k in range(repeats):
        t0 = time.perf_counter()
        fn(k)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e6


def cast_rays_numpy(
    land: LandMask, origin: np.ndarray, angles_rad: np.ndarray, rmax: float
) -> np.ndarray:
    """Vectorised-numpy variant of ``LandMask.cast_rays``, kept here for comparison only.

    Same prefilter (``segments_within``), then all (ray, segment) pairs at once:
    ``t = cross(a - o, e) / cross(d, e)``, ``u = cross(a - o, d) / cross(d, e)``.
    """
    s = land.segments_within(origin, rmax)
    if s.shape[0] == 0:
        return np.full(angles_rad.shape, np.inf)
    an, ae = s[:, 0] - origin[0], s[:, 1] - origin[1]
    en, ee = s[:, 2] - s[:, 0], s[:, 3] - s[:, 1]
    dn, de = np.cos(angles_rad)[:, None], np.sin(angles_rad)[:, None]
    den = dn * ee - de * en
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (an * ee - ae * en) / den
        u = (an * de - ae * dn) / den
    hit = (den != 0.0) & (t >= 0.0) & (t <= rmax) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf).min(axis=1)


def water_points(
    land: LandMask, bounds_ned: tuple[float, float, float, float], n: int, rng: np.random.Generator
) -> np.ndarray:
    """``n`` random water points [m] in the scene box, drawn with ``rng``."""
    n0, n1, e0, e1 = bounds_ned
    out = np.empty((0, 2))
    while len(out) < n:
        p = np.column_stack([rng.uniform(n0, n1, 4 * n), rng.uniform(e0, e1, 4 * n)])
        out = np.vstack([out, p[~land.contains(p)]])
    return out[:n]


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the JSON result."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    scene = default_scene()
    load_s = time.perf_counter() - t0
    land = scene.land
    origins = water_points(land, scene.bounds_ned, args.repeats, rng)
    # scans near the coast are the expensive ones: also time origins within 150 m of land
    far = water_points(land, scene.bounds_ned, 20 * args.repeats, rng)
    coastal = far[land.distance_to_shore(far) < 150.0][: args.repeats]
    a360 = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    a3600 = np.linspace(0.0, 2 * np.pi, 3600, endpoint=False)
    pts = rng.uniform(
        [scene.bounds_ned[0], scene.bounds_ned[2]],
        [scene.bounds_ned[1], scene.bounds_ned[3]],
        size=(10_000, 2),
    )
    # both variants must agree before they are timed
    for k in range(50):
        ref = land.cast_rays(coastal[k], a360, 150.0)
        alt = cast_rays_numpy(land, coastal[k], a360, 150.0)
        if not np.allclose(ref, alt, atol=1e-9, rtol=0.0):
            raise SystemExit(f"numpy and numba ray casts disagree at {coastal[k]}")
    r = args.repeats
    o, c = origins, coastal
    result = {
        "scene": scene.name,
        "coast_segments": int(land.segments.shape[0]),
        "grid_cell_m": land.cell_size_m,
        "default_scene_load_s": round(load_s, 3),
        "cast_rays_360_us": _median_us(lambda k: land.cast_rays(o[k % len(o)], a360, 150.0), r),
        "cast_rays_3600_us": _median_us(
            lambda k: land.cast_rays(o[k % len(o)], a3600, 150.0), r // 4
        ),
        "cast_rays_360_coastal_us": _median_us(
            lambda k: land.cast_rays(c[k % len(c)], a360, 150.0), r
        ),
        "cast_rays_3600_coastal_us": _median_us(
            lambda k: land.cast_rays(c[k % len(c)], a3600, 150.0), r // 4
        ),
        # a new angle array every scan (no reuse of sin/cos)
        "cast_rays_360_coastal_new_angles_us": _median_us(
            lambda k: land.cast_rays(c[k % len(c)], a360 + 1e-3 * (k % 97), 150.0), r
        ),
        "cast_rays_360_numpy_us": _median_us(
            lambda k: cast_rays_numpy(land, o[k % len(o)], a360, 150.0), r
        ),
        "cast_rays_360_coastal_numpy_us": _median_us(
            lambda k: cast_rays_numpy(land, c[k % len(c)], a360, 150.0), r
        ),
        "cast_rays_3600_coastal_numpy_us": _median_us(
            lambda k: cast_rays_numpy(land, c[k % len(c)], a3600, 150.0), r // 4
        ),
        "cast_rays_many_100x360_us": _median_us(
            lambda k: land.cast_rays_many(c[:100], a360, 150.0), max(r // 20, 20)
        ),
        "contains_10k_points_us": _median_us(lambda k: land.contains(pts), 50),
        "contains_10k_points_shapely_us": _median_us(
            lambda k: shapely.contains_xy(land.polygons, pts[:, 0], pts[:, 1]), 20
        ),
        "distance_10k_points_us": _median_us(lambda k: land.distance_to_shore(pts), 50),
        "distance_10k_points_shapely_us": _median_us(
            lambda k: shapely.distance(land.polygons, shapely.points(pts)),
            5,
        ),
        "segments_within_150m_us": _median_us(
            lambda k: land.segments_within(c[k % len(c)], 150.0), r
        ),
        "terrain_10k_points_us": _median_us(lambda k: land.terrain_height_m(pts), 20),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    print(json.dumps({k: round(v, 1) if isinstance(v, float) else v for k, v in result.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
