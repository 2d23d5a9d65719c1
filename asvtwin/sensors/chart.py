"""An imperfect chart: the coast the tracker believes in, perturbed from the one the LiDAR sees.

A tracker removes coast returns with a chart. Evaluated against the very polygons the
LiDAR is simulated against, coast removal is perfect and near-coast tracking looks like
open sea. Real charts are not: OpenStreetMap coastlines are typically off by 5–20 m
(Haklay 2010, "How good is volunteered geographical information? A comparative study of
OpenStreetMap and Ordnance Survey datasets"), electronic charts are generalised for their
scale, and small islands, rocks and piers are missing or out of date. :func:`perturb_chart`
builds such a chart from the sensor's world, with every error seeded and bounded:

1. **simplification** — Douglas–Peucker with tolerance ``simplify_m`` (generalisation);
2. **missing features** — polygons smaller than ``drop_area_m2`` are dropped (small
   islands, skerries, piers), each with probability ``drop_probability``;
3. **offset** — the whole chart is shifted by a vector of length ``offset_m`` in a random
   direction (datum and digitising error), plus a smooth local warp of amplitude
   ``warp_m`` (a sine field over ``warp_wavelength_m``), so the error varies along the coast.

The chart error bound is ``offset_m + warp_m + simplify_m``; the issue's evaluation uses
up to 10 m. Only the tracker gets the perturbed chart; the LiDAR keeps the true coast.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon

from asvtwin.errors import ParameterError
from asvtwin.geo.land import LandMask

__all__ = ["perturb_chart"]


def perturb_chart(
    land: LandMask,
    rng: np.random.Generator,
    *,
    offset_m: float = 5.0,
    warp_m: float = 2.0,
    warp_wavelength_m: float = 400.0,
    simplify_m: float = 3.0,
    drop_area_m2: float = 2000.0,
    drop_probability: float = 1.0,
) -> LandMask:
    """A chart of ``land`` with bounded, seeded errors (see the module docstring).

    Parameters
    ----------
    land : LandMask
        The world's coast (what the LiDAR sees).
    rng : numpy.random.Generator
        Source of the offset direction, warp phases and dropped features.
    offset_m : float
        Length of the rigid shift [m], >= 0.
    warp_m : float
        Amplitude of the smooth local displacement [m], >= 0.
    warp_wavelength_m : float
        Wavelength of the local displacement [m], > 0.
    simplify_m : float
        Douglas–Peucker tolerance [m], >= 0.
    drop_area_m2 : float
        Polygons smaller than this may be dropped [m²], >= 0.
    drop_probability : float
        Probability that each such polygon is missing, in [0, 1].

    Returns
    -------
    LandMask
        The chart. If every polygon would be dropped, the largest is kept.

    Raises
    ------
    ParameterError
        For a negative or non-finite setting.
    """
    for name, v in (("offset_m", offset_m), ("warp_m", warp_m), ("simplify_m", simplify_m),
                    ("drop_area_m2", drop_area_m2)):
        if not (np.isfinite(v) and v >= 0.0):
            raise ParameterError(f"perturb_chart: {name} must be finite and >= 0, actually: {v!r}")
    if not (np.isfinite(warp_wavelength_m) and warp_wavelength_m > 0.0):
        raise ParameterError(f"perturb_chart: warp_wavelength_m must be finite and > 0, actually: {warp_wavelength_m!r}")
    if not 0.0 <= drop_probability <= 1.0:
        raise ParameterError(f"perturb_chart: drop_probability must be in [0, 1], actually: {drop_probability!r}")
    parts = list(land.polygons.geoms)
    keep = [p for p in parts if not (p.area < drop_area_m2 and rng.random() < drop_probability)]
    if not keep:
        keep = [max(parts, key=lambda p: p.area)]
    ang = rng.uniform(0.0, 2.0 * np.pi)
    dn, de = offset_m * np.cos(ang), offset_m * np.sin(ang)
    ph = rng.uniform(0.0, 2.0 * np.pi, 4)
    k = 2.0 * np.pi / warp_wavelength_m

    def move(xy: np.ndarray) -> np.ndarray:
        n, e = xy[:, 0], xy[:, 1]
        wn = warp_m * np.sin(k * e + ph[0]) * np.cos(k * n + ph[1])
        we = warp_m * np.sin(k * n + ph[2]) * np.cos(k * e + ph[3])
        return np.column_stack([n + dn + wn, e + de + we])

    out: list[Polygon] = []
    for p in keep:
        q = p.simplify(simplify_m, preserve_topology=True) if simplify_m > 0.0 else p
        q = shapely.transform(q, move)
        if not q.is_valid:
            q = q.buffer(0)
        out.extend(g for g in shapely.get_parts(q) if isinstance(g, Polygon) and not g.is_empty)
    return LandMask(out, cell_size_m=land.cell_size_m)
