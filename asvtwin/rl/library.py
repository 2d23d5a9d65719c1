"""The twin's scenario-library encounters as RL episodes: every setup's policy, and the
line-of-sight expert behind the filter, on head-on, crossing, overtaking and multi-vessel
encounters.

The library (:mod:`asvtwin.scenarios`) is written for the twin: mostly the 88 m
full-scale CyberShip II in the Trondheim scene. An encounter *fits the paper's vessel*
when its own ship is CyberShip II (either scale), every target moves on a straight line
from a local (north, east) start, and no coast is part of what it tests (the RL world
holds circles only). Those are converted to the training world at model scale by Froude
similarity with the length ratio s = L / 1.255 m: positions and lengths / s, speeds / √s,
times / √s. Each target becomes a moving circle of radius half its length. A target with
the ``colreg`` give-way behaviour is played as holding its course and speed (the harder
case for the own ship: the library's target turns away). Encounters whose targets follow
waypoints, and those that test the coast (``restricted_water``, the Trondheim ones), are
left out and listed with the reason by :func:`library_encounters`.

Results (:func:`evaluate_library`) are per encounter and judged by the library's own
criteria: no contact, the goal reached within the library's duration, and the closest
centre-to-centre distance to any target at least the library's
``min_distance_targets_m`` (reported at the library's scale and in model-scale metres).
Contact is a target's edge within half the own ship's length of its centre (its hull as
a circle); the episode goes on past closer approaches. The training rule (a LiDAR ray
shorter than the ship's whole length ends the episode, after Meyer et al. 2020) is much
stricter than the library's distances for long targets — an 80 m cargo ship's edge one
ship length away is 128 m centre to centre, where the library asks 100 m — so it is
reported beside the result (``within_ship_length``), not used to end the episode.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.rl.config import EnvConfig, check_setup
from asvtwin.rl.scenarios import N_MOVING, N_PATH, N_STATIC, Scenario
from asvtwin.rl.vec_env import VecPathEnv
from asvtwin.vessel import cybership2, cybership2_full_scale

__all__ = ["LibraryEncounter", "LibraryResult", "LosExpertPolicy", "evaluate_library",
           "library_encounters"]

_KN = 1852.0 / 3600.0  # m/s per knot
#: Library scenarios that test a coast (the RL world has no coast), left out by name.
_COASTAL = ("default", "restricted_water")
#: The library's own-ship hulls.
_HULLS = {"cybership2": cybership2, "cybership2_full_scale": cybership2_full_scale}


class _Policy(Protocol):
    def act(self, obs: Any) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class LibraryEncounter:
    """One library scenario converted to the training world (model scale).

    Attributes
    ----------
    name : str
        Library name.
    scale : float
        s = L / 1.255 m of the library's own ship (1 at model scale).
    scenario : Scenario
        The episode's world at model scale.
    max_steps : int
        The library's duration in 1 s model-scale steps (duration / √s, rounded up).
    min_distance_m : float
        The library's ``min_distance_targets_m`` at its own scale [m] (NaN if unset).
    """

    name: str
    scale: float
    scenario: Scenario
    max_steps: int
    min_distance_m: float


@dataclass(frozen=True)
class LibraryResult:
    """One encounter played by one controller."""

    controller: str
    setup: str
    encounter: str
    collision: bool
    within_ship_length: bool
    goal: bool
    steps: int
    min_centre_distance_model_m: float
    min_centre_distance_m: float
    required_m: float
    interventions: int
    fallbacks: int

    @property
    def passed(self) -> bool:
        """No collision, the goal within the duration, and the library's distance kept."""
        ok_d = not math.isfinite(self.required_m) or (self.min_centre_distance_m
                                                       >= self.required_m)
        return (not self.collision) and self.goal and ok_d

    def to_dict(self) -> dict[str, Any]:
        return dict(dataclasses.asdict(self), passed=self.passed)


class LosExpertPolicy:
    """The line-of-sight expert of the warm start as a policy (``act(obs)``), the RL
    world's stand-in for the twin's ``los_psf`` controller when played behind the
    filter."""

    def __init__(self, n_rays: int = 180) -> None:
        self.n_rays = n_rays

    def act(self, obs: Any) -> NDArray[np.float64]:
        from asvtwin.rl.warm_start import expert_action

        return expert_action(np.atleast_2d(obs), self.n_rays)


def _resample(points: _F8) -> _F8:
    seg = np.hypot(*np.diff(points, axis=0).T)
    s_cum = np.concatenate([[0.0], np.cumsum(seg)])
    s_new = np.linspace(0.0, s_cum[-1], N_PATH)
    return np.column_stack([np.interp(s_new, s_cum, points[:, 0]),
                            np.interp(s_new, s_cum, points[:, 1])])


def _ned(p: Any) -> tuple[float, float] | None:
    if hasattr(p, "north_m"):
        return float(p.north_m), float(p.east_m)
    return None


def library_encounters() -> tuple[list[LibraryEncounter], dict[str, str]]:
    """The library's encounters that fit the training world, and the others with the
    reason each is left out."""
    from asvtwin.scenarios import library_names, load_library

    L_m = cybership2().length
    fits: list[LibraryEncounter] = []
    skipped: dict[str, str] = {}
    for name in library_names():
        sc = load_library(name, check_scene=False)
        own = sc.own_ship
        if name in _COASTAL or name.startswith("trondheim_"):
            skipped[name] = "tests the coast (the RL world has circles only)"
            continue
        if not sc.targets:
            skipped[name] = "no targets"
            continue
        if len(sc.targets) > N_MOVING:
            skipped[name] = f"{len(sc.targets)} targets, the world holds {N_MOVING}"
            continue
        kinds = {t.behaviour.kind for t in sc.targets}
        if not kinds <= {"constant_velocity", "colreg"}:
            skipped[name] = f"targets follow {sorted(kinds)} (not a straight line)"
            continue
        pts = [_ned(own.start)] + [_ned(p) for p in own.route]
        starts_or_none = [_ned(t.start) for t in sc.targets]
        starts = [p for p in starts_or_none if p is not None]
        if None in pts or len(starts) < len(starts_or_none):
            skipped[name] = "positions given as latitude/longitude"
            continue
        s = _HULLS[own.vessel]().length / L_m
        sq = math.sqrt(s)
        route = np.array(pts, dtype=float)
        origin = route[0].copy()
        path = _resample((route - origin) / s)  # Froude: lengths / s
        moving = np.zeros((N_MOVING, 5))
        for i, (t, p0) in enumerate(zip(sc.targets, starts)):
            chi = math.radians(t.heading_deg)
            V = t.speed_kn * _KN / sq  # speeds / √s
            moving[i] = ((p0[0] - origin[0]) / s, (p0[1] - origin[1]) / s,
                         V * math.cos(chi), V * math.sin(chi), 0.5 * t.length_m / s)
        x0 = np.array([path[0, 0], path[0, 1], math.radians(own.heading_deg),
                       own.speed_kn * _KN / sq, 0.0, 0.0])
        scen = Scenario(path=path, static=np.zeros((N_STATIC, 3)), moving=moving, x0=x0)
        req = sc.criteria.min_distance_targets_m
        fits.append(LibraryEncounter(
            name=name, scale=s, scenario=scen,
            max_steps=math.ceil(sc.duration_s / sq),
            min_distance_m=float(req) if req is not None else math.nan))
    return fits, skipped


def evaluate_library(policy: _Policy, setup: str, *, controller: str = "",
                     encounters: list[LibraryEncounter] | None = None,
                     env_config: EnvConfig | None = None) -> list[LibraryResult]:
    """Play every library encounter once with ``policy`` (deterministic) in ``setup``
    (``"ppo"``: no filter; the others behind the filter of that setup).

    Every encounter runs in one batched world; an episode ends as in training (collision,
    goal) or at the encounter's own duration.
    """
    check_setup(setup)
    encs = encounters if encounters is not None else library_encounters()[0]
    if not encs:
        return []
    n = len(encs)
    horizon = max(e.max_steps for e in encs)
    cfg = dataclasses.replace(env_config or EnvConfig(), setup=setup, family="moving",
                              max_steps=horizon)
    world = VecPathEnv(n, cfg, seed=0, auto_reset=False)
    world.collision_m = 0.5 * world.params.length  # contact, not the training rule
    for i, e in enumerate(encs):
        world.load_scenario(i, e.scenario)
    obs = world._observe()
    limit = np.array([e.max_steps for e in encs])
    live = np.ones(n, dtype=bool)
    out: list[LibraryResult | None] = [None] * n

    def gaps() -> tuple[_F8, _F8]:
        """Closest centre distance and closest edge distance to any target [m]."""
        c = world.circles[:, N_STATIC:]
        d = np.hypot(c[..., 0] - world.x[:, None, 0], c[..., 1] - world.x[:, None, 1])
        used = c[..., 2] > 0
        return (np.where(used, d, np.inf).min(axis=1),
                np.where(used, d - c[..., 2], np.inf).min(axis=1))

    closest, edge = gaps()
    while live.any():
        a = np.asarray(policy.act(obs), dtype=float).reshape(n, 2)
        a[~live] = (-1.0, 0.0)  # finished ships coast (not scored)
        obs, _, _, _, recs, _ = world.step(a)
        c_now, e_now = gaps()
        closest = np.where(live, np.minimum(closest, c_now), closest)
        edge = np.where(live, np.minimum(edge, e_now), edge)
        for i in range(n):
            if not live[i]:
                continue
            rec = recs[i]
            at_limit = world.steps[i] >= limit[i]
            if rec is None and not at_limit:
                continue
            e = encs[i]
            acc = world._acc
            collision = bool(rec.collision) if rec is not None else False
            goal = bool(rec.goal) if rec is not None else False
            out[i] = LibraryResult(
                controller=controller or setup, setup=setup, encounter=e.name,
                collision=collision,
                within_ship_length=bool(edge[i] < world.params.length), goal=goal,
                steps=int(world.steps[i]),
                min_centre_distance_model_m=float(closest[i]),
                min_centre_distance_m=float(closest[i] * e.scale),
                required_m=e.min_distance_m,
                interventions=int(rec.interventions if rec is not None
                                  else acc["interventions"][i]),
                fallbacks=int(rec.fallbacks if rec is not None else acc["fallbacks"][i]))
            live[i] = False
            world.active[i] = False
    world.close()
    return [r for r in out if r is not None]
