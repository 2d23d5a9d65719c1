"""Obstacles the safety filter keeps clear of, as plain values.

Four kinds, each a frozen dataclass of arrays in the local NED frame [m]:

- :class:`CircleObstacles` — static circles (buoys, islets, LiDAR returns);
- :func:`lidar_circles` — LiDAR returns turned into circles as in the safety filter of
  Vaaler et al. (2023) (returns within 30 m, radius 8 m at their scale, at most 5 per
  sector of 9);
- :class:`MovingObstacles` — circles moving along predicted centres over the horizon
  (ground truth or the tracker's constant-velocity predictions); the tracker's position
  covariance inflates the radius by κ·√λ_max(Σ_k), κ from the chi-square quantile;
- :class:`CoastSegments` — nearby shore segments ``(n0, e0, n1, e1)``; the filter keeps
  the distance to each *segment* (not its line) ≥ d_safe, a C¹ constraint.

:func:`stage_circles` flattens static and moving circles to per-stage arrays, the form
the OCP's parameters take; :func:`obstacle_labels` names each circle for the filter's
explanation ("track 2", "obstacle 5") from the optional ``ids``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.checks import check_all_finite
from asvtwin.errors import StateError

__all__ = [
    "CircleObstacles",
    "CoastSegments",
    "MovingObstacles",
    "Obstacles",
    "covariance_inflation",
    "lidar_circles",
    "obstacle_labels",
    "stage_circles",
    "stage_spread",
]



def _radii(r: ArrayLike, n: int, what: str) -> _F8:
    radii = np.broadcast_to(np.asarray(r, dtype=float), (n,)).copy()
    check_all_finite(radii, what)
    if n and radii.min() <= 0:
        i = int(np.argmin(radii))
        raise StateError(f"{what}[{i}] must be > 0 m, actually: {radii[i]}")
    return radii


def _ids(ids: Sequence[int | str] | None, n: int, what: str) -> tuple[int | str, ...] | None:
    if ids is None:
        return None
    out = tuple(ids)
    if len(out) != n:
        raise StateError(f"{what} ids must have one entry per obstacle ({n}), actually: "
                         f"{len(out)}")
    return out


@dataclass(frozen=True)
class CircleObstacles:
    """Static circles: ``centres`` (m, 2) [north, east] m and ``radii`` (m,) m > 0;
    ``ids`` optional identities (e.g. a chart object's or a track's number) that the
    filter's explanation names."""

    centres: _F8
    radii: _F8
    ids: tuple[int | str, ...] | None = None

    def __post_init__(self) -> None:
        c = np.asarray(self.centres, dtype=float).reshape(-1, 2)
        check_all_finite(c, "circle centres")
        object.__setattr__(self, "centres", c)
        object.__setattr__(self, "radii", _radii(self.radii, c.shape[0], "circle radii"))
        object.__setattr__(self, "ids", _ids(self.ids, c.shape[0], "circle"))

    def __len__(self) -> int:
        return int(self.centres.shape[0])


def covariance_inflation(cov: ArrayLike, confidence: float = 0.95) -> _F8:
    """κ·√λ_max(Σ) [m] for position covariances ``cov`` (..., 2, 2) [m²].

    κ = √(−2 ln(1 − p)) is the radius of the p-confidence ellipse of a 2-D Gaussian in
    standard deviations (chi-square, 2 degrees of freedom): 2.45 for p = 0.95.
    """
    if not 0.0 < confidence < 1.0:
        raise StateError(f"confidence must be in (0, 1), actually: {confidence}")
    S = np.asarray(cov, dtype=float)
    check_all_finite(S, "obstacle covariance")
    lam = np.linalg.eigvalsh(0.5 * (S + np.swapaxes(S, -1, -2)))[..., -1]
    kappa = math.sqrt(-2.0 * math.log(1.0 - confidence))
    return kappa * np.sqrt(np.maximum(lam, 0.0))


@dataclass(frozen=True)
class MovingObstacles:
    """Circles moving along predicted centres.

    Attributes
    ----------
    positions : ndarray, shape (m, N+1, 2)
        Predicted centres at the filter's stage times t, t + Δt, ..., t + NΔt [m].
    radii : ndarray, shape (m,)
        Hull radius plus clearance [m], > 0.
    covariances : ndarray, shape (m, N+1, 2, 2), optional
        Position covariances of the prediction [m²]; inflate the radius per stage.
    confidence : float
        Probability mass the inflated circle covers (see :func:`covariance_inflation`).
    ids : tuple of int or str, optional
        Identities (track numbers, MMSI) the filter's explanation names.
    """

    positions: _F8
    radii: _F8
    covariances: _F8 | None = None
    confidence: float = 0.95
    ids: tuple[int | str, ...] | None = None

    def __post_init__(self) -> None:
        pos = np.asarray(self.positions, dtype=float)
        if pos.ndim == 2:
            pos = pos[None]
        if pos.ndim != 3 or pos.shape[2] != 2:
            raise StateError("moving obstacle positions must have shape (m, N+1, 2), "
                             f"actually: {np.shape(self.positions)}")
        check_all_finite(pos, "moving obstacle positions")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "radii", _radii(self.radii, pos.shape[0],
                                                 "moving obstacle radii"))
        if self.covariances is not None:
            cov = np.asarray(self.covariances, dtype=float)
            if cov.shape != pos.shape[:2] + (2, 2):
                raise StateError(f"moving obstacle covariances must have shape "
                                 f"{pos.shape[:2] + (2, 2)}, actually: {cov.shape}")
            object.__setattr__(self, "covariances", cov)
        object.__setattr__(self, "ids", _ids(self.ids, pos.shape[0], "moving obstacle"))

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @classmethod
    def constant_velocity(cls, positions: ArrayLike, velocities: ArrayLike, radii: ArrayLike,
                          *, N: int, dt_s: float, covariances: ArrayLike | None = None,
                          process_noise: float = 0.0,
                          ids: Sequence[int | str] | None = None) -> MovingObstacles:
        """Predict m obstacles at constant velocity over N stages of ``dt_s``.

        ``positions`` and ``velocities`` are (m, 2) [m, m/s]; ``covariances`` (m, 2, 2)
        [m²] of the current position grows by ``process_noise`` [m²/s] per second.
        """
        p0 = np.asarray(positions, dtype=float).reshape(-1, 2)
        v = np.asarray(velocities, dtype=float).reshape(-1, 2)
        t = np.arange(N + 1) * dt_s
        pos = p0[:, None, :] + t[None, :, None] * v[:, None, :]
        cov = None
        if covariances is not None:
            c0 = np.asarray(covariances, dtype=float).reshape(-1, 2, 2)
            cov = c0[:, None] + process_noise * t[None, :, None, None] * np.eye(2)
        return cls(positions=pos, radii=np.asarray(radii, dtype=float), covariances=cov,
                   ids=None if ids is None else tuple(ids))

    def effective_radii(self) -> _F8:
        """Radii inflated by the covariance, shape (m, N+1) [m]."""
        r = np.repeat(self.radii[:, None], self.positions.shape[1], axis=1)
        if self.covariances is not None:
            r = r + covariance_inflation(self.covariances, self.confidence)
        return r


@dataclass(frozen=True)
class CoastSegments:
    """Shore segments ``segments`` (k, 4) = ``[n0, e0, n1, e1]`` [m], e.g. from
    ``LandMask.segments_within(position, radius_m)``."""

    segments: _F8

    def __post_init__(self) -> None:
        s = np.asarray(self.segments, dtype=float).reshape(-1, 4)
        check_all_finite(s, "coast segments")
        object.__setattr__(self, "segments", s)

    def __len__(self) -> int:
        return int(self.segments.shape[0])

    def distances(self, points: ArrayLike) -> _F8:
        """Distance from each point (n, 2) to each segment, shape (n, k) [m]."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        a, b = self.segments[:, 0:2], self.segments[:, 2:4]
        e = b - a
        L2 = np.maximum(np.einsum("kj,kj->k", e, e), 1e-12)
        t = np.clip(np.einsum("nkj,kj->nk", p[:, None, :] - a[None], e) / L2, 0.0, 1.0)
        q = a[None] + t[..., None] * e[None]
        return np.linalg.norm(p[:, None, :] - q, axis=2)


#: What :meth:`SafetyFilter.filter` accepts as ``obstacles``.
Obstacles = CircleObstacles | MovingObstacles | CoastSegments | Sequence[
    CircleObstacles | MovingObstacles | CoastSegments]


def lidar_circles(origin: ArrayLike, angles_rad: ArrayLike, ranges_m: ArrayLike, *,
                  max_range_m: float = 30.0, radius_m: float = 8.0, n_sectors: int = 9,
                  per_sector: int = 5) -> CircleObstacles:
    """LiDAR returns as circles whose nearest point is the return (Vaaler et al. 2023).

    Returns beyond ``max_range_m`` are dropped; in each of ``n_sectors`` equal angular
    sectors the ``per_sector`` closest returns are kept. Each circle of ``radius_m`` is
    centred ``radius_m`` behind its return along the ray, so it never contains the origin.
    Angles are NED (from north, clockwise): direction ``(cos a, sin a)``.
    """
    o = np.asarray(origin, dtype=float).reshape(2)
    a = np.asarray(angles_rad, dtype=float).ravel()
    r = np.asarray(ranges_m, dtype=float).ravel()
    if a.shape != r.shape:
        raise StateError(f"angles_rad and ranges_m must have the same length, actually: "
                         f"{a.size} and {r.size}")
    if radius_m <= 0:
        raise StateError(f"radius_m must be > 0, actually: {radius_m}")
    keep = np.isfinite(r) & np.isfinite(a) & (r < max_range_m) & (r > 0)
    a, r = a[keep], r[keep]
    sector = np.floor(np.mod(a, 2 * np.pi) / (2 * np.pi) * n_sectors).astype(int)
    chosen: list[int] = []
    for s in range(n_sectors):
        idx = np.flatnonzero(sector == s)
        chosen.extend(idx[np.argsort(r[idx])[:per_sector]].tolist())
    a, r = a[chosen], r[chosen]
    d = np.stack([np.cos(a), np.sin(a)], axis=1)
    centres = o + (r + radius_m)[:, None] * d
    return CircleObstacles(centres=centres, radii=np.full(len(r), radius_m))


def _as_list(obstacles: Obstacles | None) -> list[CircleObstacles | MovingObstacles |
                                                 CoastSegments]:
    if obstacles is None:
        return []
    if isinstance(obstacles, (CircleObstacles, MovingObstacles, CoastSegments)):
        return [obstacles]
    if isinstance(obstacles, Iterable):
        out = list(obstacles)
        for o in out:
            if not isinstance(o, (CircleObstacles, MovingObstacles, CoastSegments)):
                raise StateError(f"obstacles must be CircleObstacles, MovingObstacles or "
                                 f"CoastSegments, actually: {type(o).__name__}")
        return out
    raise StateError(f"obstacles of type {type(obstacles).__name__} are not understood")


def stage_circles(obstacles: Obstacles | None, N: int) -> tuple[_F8, _F8, _F8]:
    """All circles per stage and all coast segments.

    Returns ``centres`` (N+1, m, 2) [m], ``radii`` (N+1, m) [m] and ``segments`` (k, 4).
    Moving obstacles must have N+1 predicted positions.
    """
    items = _as_list(obstacles)
    circles = [o for o in items if not isinstance(o, CoastSegments)]
    for o in circles:
        if isinstance(o, MovingObstacles) and o.positions.shape[1] != N + 1:
            raise StateError(f"moving obstacles need N+1 = {N + 1} predicted positions, "
                             f"actually: {o.positions.shape[1]}")
    m = sum(len(o) for o in circles)
    centres = np.empty((N + 1, m, 2))
    radii = np.empty((N + 1, m))
    j = 0
    for o in circles:  # filled in place: no per-kind temporaries
        n = len(o)
        if isinstance(o, CircleObstacles):
            centres[:, j: j + n] = o.centres
            radii[:, j: j + n] = o.radii
        else:
            centres[:, j: j + n] = np.swapaxes(o.positions, 0, 1)
            radii[:, j: j + n] = (o.effective_radii().T if o.covariances is not None
                                  else o.radii)
        j += n
    segs = [o.segments for o in items if isinstance(o, CoastSegments)]
    segments = np.concatenate(segs, axis=0) if segs else np.zeros((0, 4))
    return centres, radii, segments


def stage_spread(obstacles: Obstacles | None, radii: _F8) -> _F8:
    """The part of each circle's radius that is prediction uncertainty, per stage: the
    ``radii`` (N+1, m) of :func:`stage_circles` for the same ``obstacles`` less each
    circle's own radius [m] (the covariance inflation of a moving obstacle; 0 for static
    circles and for moving ones without covariance).

    ``radii − spread`` is the circle around the predicted *mean* position (hull plus
    clearance): where a plan comes within d_safe of it, it runs at where the vessel is
    expected to be, not only into the uncertainty of its prediction.
    """
    own = np.empty(radii.shape[1])
    j = 0
    for o in _as_list(obstacles):
        if not isinstance(o, CoastSegments):
            own[j: j + len(o)] = o.radii
            j += len(o)
    if j != radii.shape[1]:
        raise StateError(f"radii must have one column per circle ({j}), actually: "
                         f"{radii.shape[1]}")
    return radii - own


def obstacle_labels(obstacles: Obstacles | None) -> tuple[list[str], NDArray[np.bool_]]:
    """A name per circle, in :func:`stage_circles`' order, and whether it moves.

    Moving obstacles with integer ids are "track <id>", other ids are used as given;
    without ids: "vessel <k>" (moving) or "obstacle <k>" (static), k counting within
    the kind from 0.
    """
    names: list[str] = []
    moving: list[bool] = []
    n_static = n_moving = 0
    for o in _as_list(obstacles):
        if isinstance(o, CoastSegments):
            continue
        is_moving = isinstance(o, MovingObstacles)
        for i in range(len(o)):
            if o.ids is not None:
                ident = o.ids[i]
                names.append(f"track {ident}" if is_moving and isinstance(ident, int)
                             else (f"obstacle {ident}" if isinstance(ident, int)
                                   else str(ident)))
            elif is_moving:
                names.append(f"vessel {n_moving + i}")
            else:
                names.append(f"obstacle {n_static + i}")
        if is_moving:
            n_moving += len(o)
        else:
            n_static += len(o)
        moving.extend([is_moving] * len(o))
    return names, np.asarray(moving, dtype=bool)
