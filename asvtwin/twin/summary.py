"""Scoring a run against ground truth, and the run's summary.

:class:`RunMetrics` is fed by the runtime (ground truth is used here and nowhere else in
the twin's decisions) and produces a :class:`RunSummary`:

- **safety** — collisions (own hull outline overlapping a target's, counted per contact,
  not per tick), groundings (own centre within half a beam of the shore or on land, per
  contact), the least centre-to-centre distance to every target and the least distance
  to land [m];
- **filter** — calls, interventions (u_0 ≠ u_L by > 1 % of the input range) and
  fallbacks by kind;
- **tracking** — confirmed tracks assigned to true targets (optimal assignment within a
  gate, :func:`asvtwin.tracking.assign_tracks`) at each tracker update: position RMSE [m]
  and the mean NEES of ``[x, y, v_x, v_y]`` (consistent: ≈ 4, inside the χ² bounds of
  :func:`asvtwin.tracking.nees_bounds`; the bounds treat the samples as independent,
  which successive updates of one track are not, so they are far too narrow for long
  runs) with its position and velocity parts (each ≈ 2), split into *open sea* and *near coast* (true
  target within ``near_coast_m`` of the shore), plus the share of true targets tracked;
- **observer** — RMSE of d̂ − τ_d per DOF [N, N, Nm] over the valid samples after the
  observer's 90 % convergence time (``settle_s``: 29 s for CyberShip II, 240 s at ×70),
  against the true disturbance;
- **criteria** of the scenario, each with its value, limit and pass/fail;
- **timing** — wall time per tick of every component [ms] and the realtime factor;
- **degradations** — every component that erred, overran or was degraded (dead feed,
  full disk, NaN input), in words.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely import intersects, polygons

from asvtwin.checks import F8 as _F8
from asvtwin.geo import LandMask
from asvtwin.scenarios import CriteriaSpec
from asvtwin.sensors import hull_polygons
from asvtwin.tracking import TrackSnapshot, assign_tracks, nees, nees_bounds

__all__ = ["RunMetrics", "RunSummary"]



@dataclass(frozen=True)
class RunSummary:
    """What a run did, scored against ground truth (units in the field names)."""

    scenario: str
    seed: int
    duration_s: float
    ticks: int
    wall_s: float
    realtime_factor: float
    collisions: int
    groundings: int
    min_distance_targets_m: dict[str, float]
    min_distance_land_m: float
    filter_calls: int
    interventions: int
    fallbacks: dict[str, int]
    tracking: dict[str, Any]
    observer: dict[str, Any]
    goal_reached: bool
    max_cte_m: float
    criteria: dict[str, dict[str, Any]]
    passed: bool
    ms_per_tick: dict[str, float]
    degradations: tuple[str, ...]
    counters: dict[str, int] = field(default_factory=dict)
    recording: str | None = None
    #: the own ship's controller (``own_ship.controller``, or ``--controller``)
    controller: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values (NaN becomes None)."""
        def clean(v: Any) -> Any:
            if isinstance(v, float):
                return None if not math.isfinite(v) else v
            if isinstance(v, dict):
                return {str(k): clean(x) for k, x in v.items()}
            if isinstance(v, (list, tuple)):
                return [clean(x) for x in v]
            if isinstance(v, np.generic):
                return clean(v.item())
            return v
        return {f.name: clean(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def text(self) -> str:
        """A few lines a navigator reads."""
        d = self.to_dict()
        mt = ", ".join(f"{k} {v:.0f} m" for k, v in self.min_distance_targets_m.items()) or "none"
        lines = [
            (f"scenario {self.scenario} (seed {self.seed}"
             f"{', controller ' + self.controller if self.controller else ''}): "
             f"{self.duration_s:.0f} s simulated "
             f"in {self.wall_s:.1f} s wall ({self.realtime_factor:.1f}x real time), "
             f"{self.ticks} ticks"),
            (f"collisions {self.collisions}, groundings {self.groundings}; closest approach: "
             f"{mt}; land {self.min_distance_land_m:.0f} m"),
            (f"filter: {self.filter_calls} calls, {self.interventions} interventions, "
             f"fallbacks {self.fallbacks or 0}"),
        ]
        for zone in ("open_sea", "near_coast"):
            z = d["tracking"].get(zone, {})
            if z.get("samples"):
                lines.append(f"tracking {zone.replace('_', ' ')}: RMSE {z['rmse_m']:.1f} m, mean "
                             f"NEES {z['nees_mean']:.2f} (95 % bounds {z['nees_low']:.2f}-"
                             f"{z['nees_high']:.2f}; position {z['nees_position_mean']:.2f}, "
                             f"velocity {z['nees_velocity_mean']:.2f}, each ≈ 2 when "
                             f"consistent), {z['samples']} samples")
        ob = self.observer
        if ob.get("samples"):
            lines.append("observer d_hat RMSE: " + ", ".join(
                f"{k} {v:.3g}" for k, v in ob["rmse"].items()) + f" ({ob['samples']} samples)")
        lines.append("time per tick [ms]: " + ", ".join(
            f"{k} {v:.3f}" for k, v in sorted(self.ms_per_tick.items(), key=lambda kv: -kv[1])))
        for name, c in self.criteria.items():
            lines.append(f"criterion {name}: {'pass' if c['pass'] else 'FAIL'} "
                         f"(value {c['value']}, limit {c['limit']})")
        lines.extend(f"degraded: {s}" for s in self.degradations)
        lines.append("PASSED" if self.passed else "FAILED")
        return "\n".join(lines)


class _Zone:
    """Running sums (constant memory over any run length)."""

    def __init__(self) -> None:
        self.n = 0
        self.sum_sq = 0.0
        self.sum_nees = 0.0
        self.sum_nees_pos = 0.0
        self.sum_nees_vel = 0.0
        self.truths = 0

    def add(self, err2: NDArray[np.float64], nees_values: NDArray[np.float64],
            nees_pos: NDArray[np.float64] | None = None,
            nees_vel: NDArray[np.float64] | None = None) -> None:
        self.n += int(err2.size)
        self.sum_sq += float(np.sum(err2))
        self.sum_nees += float(np.sum(nees_values))
        if nees_pos is not None:
            self.sum_nees_pos += float(np.sum(nees_pos))
        if nees_vel is not None:
            self.sum_nees_vel += float(np.sum(nees_vel))

    def result(self) -> dict[str, Any]:
        n = self.n
        lo, hi = nees_bounds(4, max(n, 1))
        return {"samples": n, "truth_samples": self.truths,
                "coverage": n / self.truths if self.truths else float("nan"),
                "rmse_m": math.sqrt(self.sum_sq / n) if n else float("nan"),
                "nees_mean": self.sum_nees / n if n else float("nan"),
                "nees_low": lo, "nees_high": hi,
                # the 4-D NEES split: position [x, y] and velocity [v_x, v_y], each ≈ 2
                # when consistent (tells a too-large position covariance from a velocity one)
                "nees_position_mean": self.sum_nees_pos / n if n else float("nan"),
                "nees_velocity_mean": self.sum_nees_vel / n if n else float("nan")}


class RunMetrics:
    """Accumulates ground-truth scores while the runtime runs.

    Parameters
    ----------
    names : list of str
        Target names (grows with injected targets).
    own_length_m, own_beam_m : float
        Own hull [m].
    land : LandMask or None
    near_coast_m : float
        A true target closer than this to the shore counts as *near coast* [m].
    gate_m : float
        Largest track-to-truth distance of an assignment [m].
    observer_settle_s : float
        Observer samples before this time are not scored [s].
    """

    def __init__(self, names: list[str], *, own_length_m: float, own_beam_m: float,
                 land: LandMask | None, near_coast_m: float, gate_m: float,
                 observer_settle_s: float) -> None:
        self.names = names
        self.own_length_m = own_length_m
        self.own_beam_m = own_beam_m
        self.land = land
        self.near_coast_m = near_coast_m
        self.gate_m = gate_m
        self.observer_settle_s = observer_settle_s
        self.min_dist = np.full(len(names), np.inf)
        self.min_land = math.inf
        self._in_contact = np.zeros(len(names), bool)
        self._aground = False
        self.collisions = 0
        self.groundings = 0
        self.collision_events: list[str] = []
        self.zones = {"open_sea": _Zone(), "near_coast": _Zone()}
        self.obs_n = 0
        self.obs_sum_sq = np.zeros(3)
        self.obs_invalid = 0
        self.max_cte = 0.0

    def add_target(self, name: str) -> None:
        """A target injected during the run."""
        self.names.append(name)
        self.min_dist = np.append(self.min_dist, np.inf)
        self._in_contact = np.append(self._in_contact, False)

    def truth(self, t_s: float, own: _F8, targets: _F8, length_m: _F8, beam_m: _F8) -> list[str]:
        """Score one tick of ground truth; returns events (new collisions or groundings)."""
        events: list[str] = []
        if len(targets):
            d = np.hypot(targets[:, 0] - own[0], targets[:, 1] - own[1])
            np.minimum(self.min_dist, d, out=self.min_dist)
            near = d < 0.5 * (length_m + self.own_length_m)
            contact = np.zeros(len(d), bool)
            if near.any():
                idx = np.flatnonzero(near)
                hulls = hull_polygons(np.vstack([own[None], targets[idx]]),
                                      np.concatenate([[self.own_length_m], length_m[idx]]),
                                      np.concatenate([[self.own_beam_m], beam_m[idx]]))
                polys = polygons(hulls)
                contact[idx] = intersects(polys[0], polys[1:])
            new = contact & ~self._in_contact
            for i in np.flatnonzero(new).tolist():
                self.collisions += 1
                events.append(f"t={t_s:.1f} s: collision with {self.names[i]}")
            self._in_contact = contact
        if self.land is not None:
            s = float(self.land.signed_distance(own[None, :2])[0])
            self.min_land = min(self.min_land, s)
            aground = s < 0.5 * self.own_beam_m
            if aground and not self._aground:
                self.groundings += 1
                events.append(f"t={t_s:.1f} s: grounding ({s:.1f} m from the shore)")
            self._aground = aground
        self.collision_events.extend(events)
        return events

    def tracking(self, tracks: TrackSnapshot, truth: _F8) -> None:
        """Score the confirmed tracks against the true targets (n, 6)."""
        if len(truth) == 0:
            return
        near = (self.land.distance_to_shore(truth[:, :2]) < self.near_coast_m
                if self.land is not None else np.zeros(len(truth), bool))
        for key, mask in (("open_sea", ~near), ("near_coast", near)):
            self.zones[key].truths += int(mask.sum())
        k = np.flatnonzero(tracks.is_confirmed)  # (the rows, not a whole sub-snapshot)
        if k.size == 0:
            return
        mean, cov, ids = tracks.mean[k], tracks.cov[k], tracks.ids[k]
        assigned = assign_tracks(mean[:, :2], ids, truth[:, :2], gate_m=self.gate_m)
        hit = np.flatnonzero(assigned >= 0)
        if hit.size == 0:
            return
        row = {int(i): j for j, i in enumerate(ids.tolist())}
        r = np.array([row[int(a)] for a in assigned[hit]])
        x = truth[hit]
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        true4 = np.column_stack([x[:, 0], x[:, 1], c * x[:, 3] - s * x[:, 4],
                                 s * x[:, 3] + c * x[:, 4]])
        m, P = mean[r], cov[r]
        err2 = np.sum((m[:, :2] - true4[:, :2]) ** 2, axis=1)
        e = nees(m, P, true4)
        ep = nees(m[:, :2], P[:, :2, :2], true4[:, :2])
        ev = nees(m[:, 2:], P[:, 2:, 2:], true4[:, 2:])
        nc = near[hit]
        self.zones["near_coast"].add(err2[nc], e[nc], ep[nc], ev[nc])
        self.zones["open_sea"].add(err2[~nc], e[~nc], ep[~nc], ev[~nc])

    def observer(self, t_s: float, d_hat: _F8, d_true: _F8, valid: bool) -> None:
        """Score one observer sample."""
        if not valid or not np.isfinite(d_hat).all():
            self.obs_invalid += 1
            return
        if t_s >= self.observer_settle_s:
            self.obs_n += 1
            self.obs_sum_sq += (d_hat - d_true) ** 2

    def cte(self, cte_m: float) -> None:
        """Track the largest cross-track error."""
        if math.isfinite(cte_m):
            self.max_cte = max(self.max_cte, abs(cte_m))

    def summarise(self, *, criteria: CriteriaSpec, goal_reached: bool, **rest: Any) -> RunSummary:
        """The summary (``rest``: the runtime's counts, timings and degradations)."""
        mind = {n: float(d) for n, d in zip(self.names, self.min_dist.tolist(), strict=True)}
        finite_t = [d for d in mind.values() if math.isfinite(d)]
        min_t = min(finite_t) if finite_t else math.inf
        crit: dict[str, dict[str, Any]] = {}
        if criteria.min_distance_targets_m > 0 and finite_t:
            crit["min_distance_targets"] = {"value": round(min_t, 1), "limit":
                                            criteria.min_distance_targets_m,
                                            "pass": min_t >= criteria.min_distance_targets_m}
        if criteria.min_distance_land_m > 0 and self.land is not None:
            crit["min_distance_land"] = {"value": round(self.min_land, 1), "limit":
                                         criteria.min_distance_land_m,
                                         "pass": self.min_land >= criteria.min_distance_land_m}
        if criteria.goal_reached:
            crit["goal_reached"] = {"value": goal_reached, "limit": True, "pass": goal_reached}
        if criteria.max_cte_m is not None:
            crit["max_cte"] = {"value": round(self.max_cte, 1), "limit": criteria.max_cte_m,
                               "pass": self.max_cte <= criteria.max_cte_m}
        crit["no_collision"] = {"value": self.collisions, "limit": 0, "pass": self.collisions == 0}
        crit["no_grounding"] = {"value": self.groundings, "limit": 0, "pass": self.groundings == 0}
        if self.obs_n:
            rm = np.sqrt(self.obs_sum_sq / self.obs_n)
            obs = {"samples": self.obs_n, "invalid_samples": self.obs_invalid,
                   "settle_s": self.observer_settle_s,
                   "rmse": {"surge_N": float(rm[0]), "sway_N": float(rm[1]),
                            "yaw_Nm": float(rm[2])}}
        else:
            obs = {"samples": 0, "invalid_samples": self.obs_invalid,
                   "settle_s": self.observer_settle_s, "rmse": {}}
        return RunSummary(
            collisions=self.collisions, groundings=self.groundings,
            min_distance_targets_m=mind, min_distance_land_m=self.min_land,
            tracking={k: z.result() for k, z in self.zones.items()} |
            {"near_coast_m": self.near_coast_m},
            observer=obs, goal_reached=goal_reached, max_cte_m=self.max_cte, criteria=crit,
            passed=all(c["pass"] for c in crit.values()), **rest)
