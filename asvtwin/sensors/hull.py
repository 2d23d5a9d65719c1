"""Target hulls as to-scale polygons in the local NED frame.

A target is a pose ``(north, east, heading)`` and its dimensions ``(length, beam)``. Its
hull, seen from above, is either

- ``"pointed"``: a rectangle with a pointed bow (the stern is square; the last
  ``bow_fraction`` of the length tapers to a point on the centre line), or
- ``"ellipse"``: an ellipse with semi-axes ``length / 2`` and ``beam / 2``,

rotated by the heading (from north, clockwise towards east) and translated to the
position. The polygons come out as arrays, one row of vertices per target, so the LiDAR
can cast every ray against every hull edge in one kernel.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError

__all__ = ["HULL_SHAPES", "hull_polygons", "hull_segments", "target_poses"]


#: Hull shapes understood by :func:`hull_polygons`.
HULL_SHAPES = ("pointed", "ellipse")


def target_poses(states: ArrayLike) -> _F8:
    """Poses ``[north_m, east_m, heading_rad]`` of targets from their states.

    Parameters
    ----------
    states : array_like, shape (n, 6) or (n, 4)
        Either full vessel states ``[x, y, psi, u, v, r]`` (NED position [m], heading
        [rad], body velocities) or kinematic states ``[x, y, x_dot, y_dot]`` (NED position
        [m] and velocity [m/s]); for the latter the heading is the course over ground
        ``atan2(y_dot, x_dot)`` (0, north, for a target at rest).

    Returns
    -------
    ndarray, shape (n, 3)
        ``[north_m, east_m, heading_rad]``.

    Raises
    ------
    StateError
        If the shape is not (n, 6) or (n, 4) or a value is not finite.
    """
    s = np.asarray(states, dtype=np.float64)
    if s.ndim == 1 and s.size in (4, 6):
        s = s[None, :]
    if s.ndim != 2 or s.shape[1] not in (4, 6):
        raise StateError(
            f"target states must have shape (n, 6) [x, y, psi, u, v, r] or (n, 4) "
            f"[x, y, x_dot, y_dot], actually: {s.shape}"
        )
    if not np.isfinite(s).all():
        bad = int(np.flatnonzero(~np.isfinite(s).all(axis=1))[0])
        raise StateError(f"target states must be finite, actually: row {bad} = {s[bad].tolist()}")
    if s.shape[1] == 6:
        return np.ascontiguousarray(s[:, :3])
    speed = np.hypot(s[:, 2], s[:, 3])
    psi = np.where(speed > 1e-9, np.arctan2(s[:, 3], s[:, 2]), 0.0)
    return np.column_stack([s[:, 0], s[:, 1], psi])


def _check_dims(length_m: ArrayLike, beam_m: ArrayLike, n: int) -> tuple[_F8, _F8]:
    L = np.broadcast_to(np.asarray(length_m, dtype=np.float64), (n,)).copy()
    B = np.broadcast_to(np.asarray(beam_m, dtype=np.float64), (n,)).copy()
    for name, v in (("length_m", L), ("beam_m", B)):
        bad = ~(np.isfinite(v) & (v > 0.0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ParameterError(f"{name} must be finite and > 0 m, actually: {name}[{i}] = {v[i]!r}")
    return L, B


def hull_polygons(
    states: ArrayLike,
    length_m: ArrayLike,
    beam_m: ArrayLike,
    *,
    shape: str = "pointed",
    bow_fraction: float = 0.2,
    n_vertices: int = 24,
) -> _F8:
    """Closed hull outlines of ``n`` targets in NED.

    Parameters
    ----------
    states : array_like, shape (n, 6) or (n, 4)
        Target states, see :func:`target_poses`.
    length_m, beam_m : array_like, shape (n,) or scalar
        Length over all and beam [m], > 0.
    shape : {"pointed", "ellipse"}
        Hull shape, see the module docstring.
    bow_fraction : float, default 0.2
        For ``"pointed"``: fraction of the length taken by the tapering bow, in (0, 1).
    n_vertices : int, default 24
        For ``"ellipse"``: number of polygon vertices, >= 8.

    Returns
    -------
    ndarray, shape (n, k + 1, 2)
        Vertices ``[north_m, east_m]``, the first repeated at the end (k = 5 for
        ``"pointed"``, ``n_vertices`` for ``"ellipse"``).
    """
    pose = target_poses(states)
    n = pose.shape[0]
    L, B = _check_dims(length_m, beam_m, n)
    return _polygons(pose, L, B, shape=shape, bow_fraction=bow_fraction, n_vertices=n_vertices)


def _polygons(pose: _F8, L: _F8, B: _F8, *, shape: str, bow_fraction: float,
              n_vertices: int) -> _F8:
    """:func:`hull_polygons` of checked poses (n, 3) and dimensions (n,)."""
    if shape == "pointed":
        if not 0.0 < bow_fraction < 1.0:
            raise ParameterError(f"bow_fraction must be in (0, 1), actually: {bow_fraction!r}")
        # body frame: x forward, y starboard; stern corners, shoulders, bow tip
        xs = np.array([-0.5, 0.5 - bow_fraction, 0.5, 0.5 - bow_fraction, -0.5, -0.5])
        ys = np.array([-0.5, -0.5, 0.0, 0.5, 0.5, -0.5])
        bx = L[:, None] * xs[None, :]
        by = B[:, None] * ys[None, :]
    elif shape == "ellipse":
        if int(n_vertices) < 8:
            raise ParameterError(f"n_vertices must be >= 8, actually: {n_vertices!r}")
        t = np.linspace(0.0, 2.0 * np.pi, int(n_vertices) + 1)
        t[-1] = 0.0
        bx = 0.5 * L[:, None] * np.cos(t)[None, :]
        by = 0.5 * B[:, None] * np.sin(t)[None, :]
    else:
        raise ParameterError(f"hull shape must be one of {HULL_SHAPES}, actually: {shape!r}")
    c, s = np.cos(pose[:, 2])[:, None], np.sin(pose[:, 2])[:, None]
    # eta_dot = R(psi) nu: body (forward, starboard) -> NED (north, east)
    north = pose[:, 0:1] + c * bx - s * by
    east = pose[:, 1:2] + s * bx + c * by
    return np.stack([north, east], axis=-1)


def hull_segments(polygons: ArrayLike) -> _F8:
    """Edges of closed outlines as segments.

    Parameters
    ----------
    polygons : array_like, shape (n, k + 1, 2)
        Closed outlines from :func:`hull_polygons`.

    Returns
    -------
    ndarray, shape (n, k, 4)
        ``[n0, e0, n1, e1]`` [m] per edge.
    """
    p = np.asarray(polygons, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 2 or p.shape[1] < 3:
        raise StateError(f"polygons must have shape (n, k + 1, 2) with k >= 2, actually: {p.shape}")
    return np.ascontiguousarray(np.concatenate([p[:, :-1, :], p[:, 1:, :]], axis=2))
