"""A self-contained snapshot feed with its own traffic: for the server's tests, the
browser tests and the viewer benchmark (200 targets), independent of the twin runtime.

Every part of the snapshot is filled from a small kinematic world, so the viewer has
something real to draw: the own ship (CyberShip II at full scale, 87.85 m x 20.3 m) follows
its route with a turn-rate-limited heading; ``n_targets`` vessels sail at constant velocity
from seeded positions on water; the LiDAR casts real rays against the scene's coast
(:meth:`asvtwin.geo.LandMask.cast_rays`) and samples hull points of the vessels in range;
tracks carry a constant-velocity prediction with a 2-sigma radius growing as
``sqrt(r0^2 + (q t)^2)``; CPA/TCPA are computed from relative position and velocity;
the "filter" plans the own ship's straight course ahead and marks stages that come closer
than a safety distance to a predicted target as critical. It is a test feed, not a model:
nothing here decides anything for the real twin.

The loop runs in a thread at ``tick_hz`` x speed (``max``: as fast as it can) and keeps
per-tick timings (:meth:`SyntheticFeed.tick_stats`) so tests can check that serving
clients does not slow it down.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from asvtwin.geo import Scene, default_scene
from asvtwin.server.feed import LIVE_ACTIONS, ControlError, Frame, _EncodedCache
from asvtwin.twin import snapshot as S

__all__ = ["SyntheticFeed"]

_KN = 1852.0 / 3600.0
_OWN_L, _OWN_B = 87.85, 20.3
_DEFAULT_ROUTE = ((600.0, 300.0), (1800.0, -600.0), (2600.0, -2600.0), (3000.0, -5000.0))


class SyntheticFeed:
    """A feed whose world is a few lines of kinematics (see the module docstring).

    Parameters
    ----------
    n_targets : int
        Number of other vessels (0-1000).
    seed : int
        Seed of the traffic's random positions, courses and speeds.
    tick_hz : float
        Ticks per second of wall time at speed 1 (one tick advances ``dt_s``).
    dt_s : float
        Simulation time per tick [s].
    lidar_rays : int
        Rays of the synthetic scan (cast against the coast every tick).
    """

    kind = "synthetic"
    actions: tuple[str, ...] = LIVE_ACTIONS

    def __init__(self, n_targets: int = 12, *, seed: int = 0, tick_hz: float = 10.0,
                 dt_s: float = 0.1, lidar_rays: int = 360, scene: Scene | None = None) -> None:
        if not 0 <= n_targets <= 1000:
            raise ValueError(f"n_targets must be in [0, 1000], actually: {n_targets}")
        self._scene = scene or default_scene()
        self.tick_hz = float(tick_hz)
        self.dt_s = float(dt_s)
        self.n_rays = int(lidar_rays)
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._cache = _EncodedCache()
        self._snap: S.Snapshot | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._pending_steps = 0
        self.paused = False
        self.speed: float | str = 1.0
        self.filter_enabled = True
        self.wind = (6.0, math.radians(200.0))
        self.t_s = 0.0
        self.seq = 0
        self._interventions = 0
        self._filter_calls = 0
        self.tick_ms: deque[float] = deque(maxlen=5000)
        self.tick_wall: deque[float] = deque(maxlen=5000)
        # own ship [x, y, psi, u, v, r]
        self.route = np.array(_DEFAULT_ROUTE)
        self.wp = 0
        self.own = np.array([0.0, 0.0, math.atan2(300.0, 600.0), 6.0, 0.0, 0.0])
        self.past: deque[tuple[float, float]] = deque(maxlen=300)
        self._spawn(n_targets)
        self._events: list[str] = []

    # ---------------------------------------------------------------- the world
    def _spawn(self, n: int) -> None:
        rng = self._rng
        land = self._scene.land
        pos = np.empty((0, 2))
        while len(pos) < n:  # rejection sampling on water within 5 km of the start
            cand = rng.uniform(-4000.0, 4000.0, size=(4 * n + 8, 2)) + [1500.0, -1500.0]
            ok = ~land.contains(cand) & (land.distance_to_shore(cand) > 60.0)
            pos = np.vstack([pos, cand[ok]])[:n]
        heading = rng.uniform(0.0, 2 * math.pi, n)
        speed = rng.uniform(1.0, 7.0, n)
        self.tgt_pos = pos
        self.tgt_vel = np.column_stack([speed * np.cos(heading), speed * np.sin(heading)])
        self.tgt_len = rng.uniform(12.0, 140.0, n)
        self.tgt_beam = self.tgt_len / rng.uniform(4.0, 7.0, n)
        self.tgt_ids = np.arange(n, dtype=np.int64)
        self.tgt_mmsi = np.where(rng.random(n) < 0.8, 257_000_000 + np.arange(n), -1)
        self.tgt_names = [f"VESSEL {i:03d}" for i in range(n)]

    def _advance(self) -> None:
        dt = self.dt_s
        x, y, psi, u = self.own[:4]
        if self.wp < len(self.route):
            dn, de = self.route[self.wp] - (x, y)
            if math.hypot(dn, de) < 150.0:
                self.wp += 1
                self._events.append(f"waypoint {self.wp} reached")
            want = math.atan2(de, dn)
            err = (want - psi + math.pi) % (2 * math.pi) - math.pi
            r = max(-0.03, min(0.03, 0.2 * err))
        else:
            r, u = 0.0, max(0.0, u - 0.2 * dt)
        psi = (psi + r * dt) % (2 * math.pi)
        x += u * math.cos(psi) * dt
        y += u * math.sin(psi) * dt
        self.own[:] = (x, y, psi, u, 0.0, r)
        self.tgt_pos = self.tgt_pos + self.tgt_vel * dt
        self.t_s += dt
        if self.seq % 10 == 0:
            self.past.append((x, y))

    def _snapshot(self) -> S.Snapshot:
        own = self.own
        p0, psi, u = own[:2], own[2], own[3]
        v0 = np.array([u * math.cos(psi), u * math.sin(psi)])
        n = len(self.tgt_pos)
        frame = self._scene.frame
        lat, lon = frame.to_wgs84(self.tgt_pos[:, 0], self.tgt_pos[:, 1])
        olat, olon = frame.to_wgs84(own[0], own[1])
        sog = np.hypot(self.tgt_vel[:, 0], self.tgt_vel[:, 1])
        cog = np.arctan2(self.tgt_vel[:, 1], self.tgt_vel[:, 0]) % (2 * math.pi)
        # CPA/TCPA from relative position and velocity
        dp = self.tgt_pos - p0
        dv = self.tgt_vel - v0
        dv2 = (dv * dv).sum(1)
        tcpa = np.where(dv2 > 1e-9, -(dp * dv).sum(1) / np.maximum(dv2, 1e-9), np.nan)
        cpa = np.hypot(*(dp + dv * np.nan_to_num(tcpa)[:, None]).T)
        cpa = np.where(tcpa >= 0, cpa, np.nan)
        tcpa = np.where(tcpa >= 0, tcpa, np.nan)
        # predictions (the cones): h steps over 60 s
        pt = np.linspace(0.0, 60.0, 7)
        pred = self.tgt_pos[:, None, :] + self.tgt_vel[:, None, :] * pt[None, :, None]
        rad = np.sqrt(15.0**2 + (0.25 * pt) ** 2)[None, :].repeat(n, 0) * (1 + self.tgt_len / 200)[:, None]
        # LiDAR: coast returns (real ray casting) + hull samples of vessels in range
        rmax = 1500.0
        ang = np.linspace(0.0, 2 * math.pi, self.n_rays, endpoint=False)
        rng_m = self._scene.land.cast_rays(p0, ang, rmax)
        hit = np.isfinite(rng_m) & (rng_m < rmax)
        coast_pts = p0 + np.column_stack([np.cos(ang), np.sin(ang)])[hit] * rng_m[hit, None]
        near = np.flatnonzero(np.hypot(dp[:, 0], dp[:, 1]) < rmax)
        k = 12
        th = np.linspace(0, 2 * math.pi, k, endpoint=False)
        hulls = []
        for i in near:
            c, hh = math.cos(cog[i]), math.sin(cog[i])
            a, b = self.tgt_len[i] / 2, self.tgt_beam[i] / 2
            lx, ly = a * np.cos(th), b * np.sin(th)
            hulls.append(self.tgt_pos[i] + np.column_stack([c * lx - hh * ly, hh * lx + c * ly]))
        vessel_pts = np.vstack(hulls) if hulls else np.zeros((0, 2))
        noise = self._rng.normal(0.0, 0.5, vessel_pts.shape)
        points = np.vstack([coast_pts, vessel_pts + noise])
        coast = np.r_[np.ones(len(coast_pts), bool), np.zeros(len(vessel_pts), bool)]
        # the "filter": straight plan ahead, critical where it nears a predicted target
        N, dt_plan = 20, 3.0
        ptimes = np.arange(N + 1) * dt_plan
        plan = p0 + v0 * ptimes[:, None]
        tp = self.tgt_pos[None, :, :] + self.tgt_vel[None, :, :] * ptimes[:, None, None]
        d = np.hypot(*(tp - plan[:, None, :]).transpose(2, 0, 1)).min(1) if n else np.full(N + 1, 1e4)
        land_d = self._scene.land.signed_distance(plan)
        margin = np.minimum(d - 150.0, land_d - 50.0)
        critical = np.flatnonzero(margin < 0).astype(np.int64)
        intervened = bool(self.filter_enabled and len(critical))
        self._filter_calls += 1
        if intervened:
            self._interventions += 1
        u_L = np.array([8.0e5, 0.0, 0.0])
        u_0 = np.array([2.0e5, 1.0e5, -4.0e6]) if intervened else u_L
        wind_s, wind_from = self.wind
        events, self._events = tuple(self._events), []
        stale = self._rng.random(n) < 0.03
        ais_idx = np.flatnonzero(self.tgt_mmsi >= 0)
        return S.Snapshot(
            seq=self.seq, t_s=self.t_s, scenario="synthetic",
            clock=S.ClockState(mode="max" if self.speed == "max" else "scaled",
                               speed=1.0 if self.speed == "max" else float(self.speed),
                               paused=self.paused, wall_utc=None),
            own=S.OwnShip(length_m=_OWN_L, beam_m=_OWN_B, state=S.ro(own),
                          lat_deg=float(olat), lon_deg=float(olon), sog_m_s=float(u),
                          cog_rad=float(psi), tau_cmd=S.ro(u_0), tau_applied=S.ro(u_0),
                          route=S.ro(self.route.reshape(-1, 2)), waypoint_index=self.wp,
                          cte_m=0.0, past_track=S.ro(np.array(self.past).reshape(-1, 2)),
                          goal_reached=self.wp >= len(self.route)),
            truth=S.GroundTruth(ids=S.ro(self.tgt_ids, np.int64), names=tuple(self.tgt_names),
                                mmsi=S.ro(self.tgt_mmsi, np.int64),
                                state=S.ro(np.column_stack([self.tgt_pos, cog, sog,
                                                            np.zeros(n), np.zeros(n)])),
                                length_m=S.ro(self.tgt_len), beam_m=S.ro(self.tgt_beam)),
            ais=S.AisTargets(mmsi=S.ro(self.tgt_mmsi[ais_idx], np.int64),
                             names=tuple(self.tgt_names[i] for i in ais_idx),
                             position_m=S.ro(self.tgt_pos[ais_idx]), lat_deg=S.ro(lat[ais_idx]),
                             lon_deg=S.ro(lon[ais_idx]), sog_m_s=S.ro(sog[ais_idx]),
                             cog_rad=S.ro(cog[ais_idx]), heading_rad=S.ro(cog[ais_idx]),
                             age_s=S.ro(np.full(len(ais_idx), 2.0)),
                             stale=S.ro(stale[ais_idx], np.bool_),
                             length_m=S.ro(self.tgt_len[ais_idx]),
                             beam_m=S.ro(self.tgt_beam[ais_idx])),
            lidar=S.LidarFrame(t_s=self.t_s, origin=S.ro(p0), range_m=rmax, n_rays=self.n_rays,
                               points=S.ro(points), coast=S.ro(coast, np.bool_)),
            ellipses=S.Ellipses(centre=S.ro(self.tgt_pos[near].reshape(-1, 2)),
                                semi_axes_m=S.ro(np.column_stack([self.tgt_len[near] / 2,
                                                                  self.tgt_beam[near] / 2])),
                                angle_rad=S.ro(cog[near]), ok=S.ro(np.ones(len(near)), np.bool_)),
            tracks=S.Tracks(ids=S.ro(self.tgt_ids, np.int64), mmsi=S.ro(self.tgt_mmsi, np.int64),
                            status=("confirmed",) * n,
                            source=tuple("fused" if (m >= 0 and i in set(near)) else
                                         "ais" if m >= 0 else "lidar"
                                         for i, m in enumerate(self.tgt_mmsi)),
                            mean=S.ro(np.column_stack([self.tgt_pos, self.tgt_vel])),
                            cov=S.ro(np.tile(np.eye(4) * 4.0, (n, 1, 1))),
                            pred_times_s=S.ro(pt), pred_mean=S.ro(pred), pred_radius_m=S.ro(rad),
                            cpa_m=S.ro(cpa), tcpa_s=S.ro(tcpa)),
            observer=S.ObserverState(d_hat=S.ro([2.0e4, -1.5e4, 0.0]),
                                     d_true=S.ro([2.2e4, -1.4e4, 0.0])),
            filter=S.FilterState(enabled=self.filter_enabled, t_s=self.t_s, u_L=S.ro(u_L),
                                 u_0=S.ro(u_0), intervened=intervened, certified=True,
                                 status="synthetic", plan=S.ro(plan), plan_times_s=S.ro(ptimes),
                                 plan_margin_m=S.ro(margin), critical_stages=S.ro(critical, np.int64),
                                 explanation=("plan nears a predicted target" if intervened else ""),
                                 solve_ms=1.0, interventions=self._interventions,
                                 calls=self._filter_calls),
            weather=S.WeatherState(source="synthetic", wind_speed_m_s=wind_s,
                                   wind_from_rad=wind_from, air_temperature_c=4.0,
                                   pressure_hpa=1012.0, current_m_s=S.ro([0.1, -0.05]), age_s=0.0),
            health=(S.ComponentHealth(name="world", period_s=self.dt_s, calls=self.seq,
                                      last_ms=self.tick_ms[-1] if self.tick_ms else 0.0),),
            events=events, counters={"ticks": self.seq},
        )

    # ---------------------------------------------------------------- the loop
    def tick(self) -> S.Snapshot:
        """Advance one tick and publish its snapshot (also used by tests without a thread)."""
        t0 = time.perf_counter()
        with self._lock:
            self.seq += 1
            self._advance()
            snap = self._snapshot()
            self._snap = snap
        self.tick_ms.append((time.perf_counter() - t0) * 1e3)
        self.tick_wall.append(time.perf_counter())
        return snap

    def _run(self) -> None:
        next_t = time.perf_counter()
        while not self._stop.is_set():
            if self.paused and self._pending_steps == 0:
                self._stop.wait(0.02)
                next_t = time.perf_counter()
                continue
            if self._pending_steps:
                self._pending_steps -= 1
            self.tick()
            if self.speed == "max":
                next_t = time.perf_counter()
                continue
            next_t += 1.0 / (self.tick_hz * float(self.speed))
            delay = next_t - time.perf_counter()
            if delay > 0:
                self._stop.wait(delay)
            else:
                next_t = time.perf_counter()  # overran: do not try to catch up

    def start(self) -> None:
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="synthetic-feed", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def tick_stats(self, since: float = 0.0) -> dict[str, float]:
        """Median and p95 of tick compute time [ms] and tick interval [ms] for ticks after
        ``since`` (a ``time.perf_counter()`` value)."""
        wall = np.array(self.tick_wall)
        ms = np.array(self.tick_ms)[-len(wall):]
        sel = wall > since
        w, m = wall[sel], ms[sel]
        iv = np.diff(w) * 1e3 if len(w) > 1 else np.array([np.nan])
        return {"ticks": float(len(w)), "tick_ms_median": float(np.median(m)) if len(m) else math.nan,
                "tick_ms_p95": float(np.percentile(m, 95)) if len(m) else math.nan,
                "interval_ms_median": float(np.median(iv)), "interval_ms_p95": float(np.percentile(iv, 95))}

    # ---------------------------------------------------------------- the feed
    def frame(self) -> Frame | None:
        return self._cache.get(self._snap)

    def latest(self) -> S.Snapshot | None:
        return self._snap

    def scene(self) -> Scene:
        return self._scene

    def info(self) -> dict[str, Any]:
        return {"kind": self.kind, "actions": list(self.actions), "scenario": "synthetic",
                "duration_s": None}

    def control(self, action: str, payload: dict[str, Any]) -> dict[str, Any]:
        with self._lock:
            if action == "pause":
                self.paused = True
            elif action == "resume":
                self.paused = False
            elif action == "speed":
                self.speed = payload["factor"]
            elif action == "step":
                self.paused = True
                self._pending_steps += int(payload["n_ticks"])
            elif action == "filter":
                self.filter_enabled = bool(payload["enabled"])
            elif action == "route":
                self.route = np.asarray(payload["waypoints_ned"], float).reshape(-1, 2)
                self.wp = 0
            elif action == "inject":
                spec = payload["spec"]
                p = spec["start"]
                ned = (np.array([p["north_m"], p["east_m"]]) if "north_m" in p else
                       np.array(self._scene.frame.to_ned(p["lat"], p["lon"])).ravel())
                hd, sp = math.radians(spec["heading_deg"]), spec["speed_kn"] * _KN
                i = len(self.tgt_pos)
                self.tgt_pos = np.vstack([self.tgt_pos, ned])
                self.tgt_vel = np.vstack([self.tgt_vel, [sp * math.cos(hd), sp * math.sin(hd)]])
                self.tgt_len = np.r_[self.tgt_len, spec.get("length_m") or 30.0]
                self.tgt_beam = np.r_[self.tgt_beam, spec.get("beam_m") or 8.0]
                self.tgt_ids = np.r_[self.tgt_ids, i]
                mmsi = spec.get("mmsi")
                self.tgt_mmsi = np.r_[self.tgt_mmsi, -1 if mmsi is None else int(mmsi)]
                self.tgt_names.append(spec.get("name") or f"INJECTED {i}")
                self._events.append(f"vessel {self.tgt_names[-1]} injected")
            elif action == "wind":
                self.wind = (float(payload["speed_m_s"]), math.radians(float(payload["from_deg"])))
            else:
                raise ControlError(f"action {action!r} is not available; allowed: "
                                   f"{', '.join(self.actions)}")
            # publish the new state at once (a paused world still shows what changed)
            self.seq += 1
            self._snap = self._snapshot()
        return {"ok": True, "action": action}
