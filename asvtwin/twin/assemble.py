"""Turning the components' outputs into the parts of a :class:`~asvtwin.twin.snapshot.Snapshot`.

Pure functions from plain values to frozen snapshot parts (every array copied read-only by
:func:`~asvtwin.twin.snapshot.ro`), so the runtime fills the whole tree each time and a
test can check each part alone. Units and frames as in :mod:`asvtwin.twin.snapshot`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control import FilterResult
from asvtwin.errors import StateError
from asvtwin.geo import LandMask, LocalFrame
from asvtwin.sensors import LidarScan
from asvtwin.sources.ais import TargetSnapshot
from asvtwin.tracking import EllipseFits, TrackSnapshot
from asvtwin.twin.snapshot import (
    AisTargets,
    Ellipses,
    FilterState,
    LidarFrame,
    Tracks,
    ro,
)

__all__ = ["ais_part", "cpa_tcpa", "cv_cones", "ellipses_part", "filter_part",
           "ground_velocity", "lidar_part", "tracks_part"]


def ground_velocity(x: _F8) -> _F8:
    """Velocity over ground ``[v_north, v_east]`` [m/s] of states (..., 6): η̇ = R(ψ) ν."""
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    return np.stack([c * x[..., 3] - s * x[..., 4], s * x[..., 3] + c * x[..., 4]], axis=-1)


def cpa_tcpa(p_own: _F8, v_own: _F8, p: _F8, v: _F8) -> tuple[_F8, _F8]:
    """Closest point of approach [m] and time to it [s] of targets (n, 2) relative to the
    own ship, at constant velocities; NaN where they do not close (TCPA < 0 or no relative
    motion)."""
    dp = p - p_own[None]
    dv = v - v_own[None]
    vv = np.sum(dv * dv, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = -np.sum(dp * dv, axis=1) / vv
    ok = (vv > 1e-12) & (t >= 0)
    cpa = np.hypot(*(dp + np.where(ok, t, 0.0)[:, None] * dv).T)
    return np.where(ok, cpa, np.nan), np.where(ok, t, np.nan)


def ais_part(ts: TargetSnapshot, frame: LocalFrame) -> AisTargets:
    """AIS targets, dead-reckoned (NaN where a value was not available)."""
    n = len(ts)
    vel = ts.velocity_m_s
    known = ts.velocity_known
    sog = np.where(known, np.hypot(vel[:, 0], vel[:, 1]), np.nan)
    cog = np.where(known, np.arctan2(vel[:, 1], vel[:, 0]), np.nan)
    names, L, B = [], np.full(n, np.nan), np.full(n, np.nan)
    for i, st in enumerate(ts.static):
        names.append((st.name or "").strip() if st is not None else "")
        if st is not None and st.to_bow_m is not None and st.to_stern_m is not None:
            L[i] = st.to_bow_m + st.to_stern_m
            if st.to_port_m is not None and st.to_starboard_m is not None:
                B[i] = st.to_port_m + st.to_starboard_m
    # the registry's dead-reckoned latitude and longitude where it has them (the position
    # in metres is their projection); the frame's inverse only where it has not
    lat, lon = np.asarray(ts.lat_deg, np.float64), np.asarray(ts.lon_deg, np.float64)
    if lat.shape != (n,) or lon.shape != (n,):
        lat, lon = np.full(n, np.nan), np.full(n, np.nan)
    missing = ~(np.isfinite(lat) & np.isfinite(lon))
    if missing.any():
        lat, lon = lat.copy(), lon.copy()
        lat[missing], lon[missing] = frame.to_wgs84(ts.position_m[missing, 0],
                                                    ts.position_m[missing, 1])
    return AisTargets(
        mmsi=ro(ts.mmsi, np.int64), names=tuple(names), position_m=ro(ts.position_m, shape=(-1, 2)),
        lat_deg=ro(lat), lon_deg=ro(lon), sog_m_s=ro(sog), cog_rad=ro(cog),
        heading_rad=ro(ts.heading_rad), age_s=ro(ts.age_s), stale=ro(ts.stale, np.bool_),
        length_m=ro(L), beam_m=ro(B))


def lidar_part(scan: LidarScan | None, land: LandMask | None, coast_margin_m: float
               ) -> LidarFrame:
    """The last scan's returns; ``coast`` marks those the chart puts on the shore."""
    if scan is None:
        return LidarFrame()
    pts = scan.points
    coast = (land.signed_distance(pts) < coast_margin_m if land is not None and len(pts)
             else np.zeros(len(pts), bool))
    return LidarFrame(t_s=scan.t_s, origin=ro(scan.origin_ned), range_m=scan.max_range_m,
                      n_rays=int(scan.ranges_m.shape[0]), points=ro(pts, shape=(-1, 2)),
                      coast=ro(coast, np.bool_))


def ellipses_part(fits: EllipseFits | None) -> Ellipses:
    """Ellipses fitted to the last scan's clusters."""
    if fits is None:
        return Ellipses()
    return Ellipses(centre=ro(fits.centre, shape=(-1, 2)), semi_axes_m=ro(fits.semi_axes, shape=(-1, 2)),
                    angle_rad=ro(fits.angle_rad), ok=ro(fits.ok, np.bool_))


@njit(cache=True)
def _cv_cones(x, P, tau, q, pos, radius):  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        # the position block of A P Aᵀ + Q, A = [[I, τI], [0, I]], symmetrised
        for k in range(tau.shape[0]):
            t = tau[k]
            pos[i, k, 0] = x[i, 0] + t * x[i, 2]
            pos[i, k, 1] = x[i, 1] + t * x[i, 3]
            qp = q * t**3 / 3.0
            a = P[i, 0, 0] + t * (P[i, 0, 2] + P[i, 2, 0]) + t * t * P[i, 2, 2] + qp
            d = P[i, 1, 1] + t * (P[i, 1, 3] + P[i, 3, 1]) + t * t * P[i, 3, 3] + qp
            b01 = P[i, 0, 1] + t * (P[i, 0, 3] + P[i, 2, 1]) + t * t * P[i, 2, 3]
            b10 = P[i, 1, 0] + t * (P[i, 1, 2] + P[i, 3, 0]) + t * t * P[i, 3, 2]
            b = 0.5 * (b01 + b10)
            tr = a + d
            det = a * d - b * b
            radius[i, k] = 2.0 * math.sqrt(0.5 * tr + math.sqrt(max(0.25 * tr * tr - det, 0.0)))


def cv_cones(mean: _F8, cov: _F8, t0_s: float, times_s: _F8, q: float) -> tuple[_F8, _F8]:
    """Prediction cones of tracks: CV positions (n, h, 2) [m] and the 2-σ radius (n, h)
    [m] (twice the largest position standard deviation) at ``times_s`` (h,) from estimates
    at ``t0_s``.

    The numbers of :func:`asvtwin.tracking.predict_tracks` followed by
    ``2 * position_std_max()`` (to rounding: tested to 1e-9), computed in one compiled
    pass over the 2×2 position block only: the cones are all a snapshot shows, and the full
    4×4 propagation cost a quarter of the snapshot."""
    x = np.ascontiguousarray(mean, dtype=np.float64)
    P = np.ascontiguousarray(cov, dtype=np.float64)
    tau = np.maximum(np.asarray(times_s, dtype=np.float64).reshape(-1) - t0_s, 0.0)
    if x.ndim != 2 or x.shape[1] != 4 or P.shape != (x.shape[0], 4, 4):
        raise StateError(f"mean must be (n, 4) and cov (n, 4, 4), actually: {x.shape}, {P.shape}")
    pos = np.empty((x.shape[0], tau.shape[0], 2))
    radius = np.empty((x.shape[0], tau.shape[0]))
    _cv_cones(x, P, tau, float(q), pos, radius)
    return pos, radius


def tracks_part(tr: TrackSnapshot, t_s: float, own: _F8, pred_times_s: _F8, q: float,
                own_velocity: _F8 | None = None) -> Tracks:
    """Tracks with CV prediction cones (2-σ radius) and CPA/TCPA to the own ship
    (``own_velocity``: its :func:`ground_velocity`, when the caller has it already)."""
    n = len(tr)
    h = pred_times_s.shape[0]
    if n == 0:
        return Tracks(pred_times_s=ro(pred_times_s), pred_mean=ro(np.zeros((0, h, 2))),
                      pred_radius_m=ro(np.zeros((0, h))))
    t0 = min(tr.t_s, t_s)
    pred_mean, radius = cv_cones(tr.mean, tr.cov, t0, t_s + pred_times_s, q)
    lid = np.isfinite(tr.lidar_only_mean[:, 0])
    ais = np.isfinite(tr.ais_only_mean[:, 0])
    source = tuple("fused" if a and b else "ais" if b else "lidar"
                   for a, b in zip(lid.tolist(), ais.tolist(), strict=True))
    mmsi = np.array([-1 if m is None else m for m in tr.mmsi], np.int64)
    v_own = ground_velocity(own) if own_velocity is None else own_velocity
    cpa, tcpa = cpa_tcpa(own[:2], v_own, tr.mean[:, :2], tr.mean[:, 2:])
    return Tracks(ids=ro(tr.ids, np.int64), mmsi=ro(mmsi, np.int64), status=tuple(tr.status),
                  source=source, mean=ro(tr.mean), cov=ro(tr.cov), pred_times_s=ro(pred_times_s),
                  pred_mean=ro(pred_mean), pred_radius_m=ro(radius), cpa_m=ro(cpa),
                  tcpa_s=ro(tcpa))


def plan_part(res: FilterResult, dt_s: float, d_safe_m: float
              ) -> tuple[_F8, _F8, _F8, NDArray[np.int64], str]:
    """The parts of :func:`filter_part` that depend on the filter's answer alone (plan,
    stage times, per-stage margins, critical stages, explanation), read-only: a caller
    that holds an answer for many snapshots builds them once (the twin does)."""
    margins = np.asarray(res.obstacle_margin_m, dtype=float)
    critical = np.flatnonzero(np.isfinite(margins) & (margins < 0.25 * d_safe_m))
    text = getattr(res, "explanation", "") or _explain(res, critical, dt_s)
    return (ro(res.x_pred[:, :2], shape=(-1, 2)), ro(dt_s * np.arange(res.x_pred.shape[0])),
            ro(np.where(np.isfinite(margins), margins, np.nan)), ro(critical, np.int64), text)


def filter_part(res: FilterResult | None, *, enabled: bool, t_s: float, u_L: _F8, u_0: _F8,
                dt_s: float, d_safe_m: float, calls: int, interventions: int, fallbacks: int,
                explanation: str = "", period_s: float = math.nan,
                plan: tuple[_F8, _F8, _F8, NDArray[np.int64], str] | None = None
                ) -> FilterState:
    """The filter's last answer: plan, per-stage margins, critical stages, explanation
    (``plan``: :func:`plan_part` of ``res``, when the caller has it already)."""
    if res is None:
        return FilterState(enabled=enabled, t_s=t_s, u_L=ro(u_L), u_0=ro(u_0), calls=calls,
                           interventions=interventions, fallbacks=fallbacks,
                           period_s=period_s,
                           intervened=bool(np.max(np.abs(u_L - u_0)) > 0) if enabled else False,
                           explanation=explanation)
    xy, times, margin, critical, text = plan if plan is not None else plan_part(
        res, dt_s, d_safe_m)
    if explanation and not getattr(res, "explanation", ""):
        text = explanation  # (the caller's text before the generated one)
    return FilterState(
        enabled=enabled, t_s=t_s, u_L=ro(u_L), u_0=ro(u_0), intervened=bool(res.intervened),
        certified=bool(res.success), fallback=str(res.fallback), status=str(res.status),
        explanation=text, plan=xy, plan_times_s=times, plan_margin_m=margin,
        critical_stages=critical, solve_ms=1e3 * float(res.solve_time_s),
        interventions=interventions, fallbacks=fallbacks, calls=calls, period_s=period_s)


def _explain(res: FilterResult, critical: NDArray[np.int64], dt_s: float) -> str:
    if res.fallback != "none":
        return f"no certified plan ({res.status}); fallback '{res.fallback}' applied"
    if not res.intervened:
        return "proposal kept: the plan from it stays clear of every obstacle"
    if critical.size:
        k = int(critical[0])
        return (f"proposal changed: the plan comes within its clearance of an obstacle at "
                f"stage {k} ({k * dt_s:.0f} s ahead)")
    kinds: list[str] = sorted({str(a.kind) for a in res.active}) or ["terminal set"]
    return "proposal changed to respect " + ", ".join(kinds)
