"""Held-out evaluation of a policy: fixed scenarios, deterministic actions, every setup.

The held-out scenarios come from their own seed stream (``HELD_OUT_SEED``), never used in
training; each is played once by the numpy policy (the Gaussian's mean) with or without
the safety filter of the policy's setup.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from asvtwin.rl.config import EnvConfig, check_setup
from asvtwin.rl.policy import NumpyPolicy
from asvtwin.rl.scenarios import N_STATIC, Scenario, random_scenario
from asvtwin.rl.vec_env import EpisodeRecord, VecPathEnv

__all__ = ["HELD_OUT_SEED", "EvalResult", "evaluate_policy", "held_out_scenarios"]

#: Seed of the held-out scenario stream (training uses the run seed's streams).
HELD_OUT_SEED = 2_000_000_011


def held_out_scenarios(family: str, n: int, *, length_m: float = 500.0,
                       U_max: float = 0.5788) -> list[Scenario]:
    """``n`` scenarios of ``family`` from the held-out stream (same list every call)."""
    rng = np.random.default_rng([HELD_OUT_SEED, ("static", "moving", "mixed").index(family)])
    return [random_scenario(rng, family, length_m=length_m, U_max=U_max) for _ in range(n)]


@dataclass(frozen=True)
class EvalResult:
    """Outcome of one policy on a scenario set."""

    setup: str
    family: str
    episodes: int
    collision_rate: float
    goal_rate: float
    mean_abs_cte_m: float
    mean_progress: float
    interventions_per_episode: float
    fallbacks_per_episode: float
    records: tuple[EpisodeRecord, ...]
    #: One entry per collision: what was hit and how fast (see :func:`evaluate_policy`).
    collisions: tuple[dict[str, Any], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d.pop("records")
        d.pop("collisions")
        return d


def evaluate_policy(policy: NumpyPolicy | str | Path, setup: str, family: str, *,
                    n_episodes: int = 20, env_config: EnvConfig | None = None
                    ) -> EvalResult:
    """Play ``n_episodes`` held-out scenarios of ``family`` with ``policy`` in ``setup``.

    Each collision is described in ``EvalResult.collisions``: the scenario index, whether
    the obstacle hit was moving, its speed and the own ship's top speed U_max [m/s]
    (``faster``: the obstacle outran the ship, so no manoeuvre of the ship alone can
    always keep clear of it), the own speed at contact [m/s], the shortest LiDAR ray
    [m] against the collision threshold (the ship's length) and the filter's
    interventions and fallbacks in that episode.
    """
    check_setup(setup)
    pol = policy if isinstance(policy, NumpyPolicy) else NumpyPolicy.load(policy)
    cfg = dataclasses.replace(env_config or EnvConfig(), setup=setup, family=family)
    world = VecPathEnv(n_episodes, cfg, seed=0, auto_reset=False)
    for i, sc in enumerate(held_out_scenarios(family, n_episodes,
                                              length_m=cfg.path_length_m,
                                              U_max=world.U_max)):
        world.load_scenario(i, sc)
    obs = world._observe()
    records: list[EpisodeRecord | None] = [None] * n_episodes
    live = np.ones(n_episodes, dtype=bool)
    hits: list[dict[str, Any]] = []
    while live.any():
        a = pol.act(obs)
        a[~live] = (-1.0, 0.0)  # finished ships coast (their steps are not counted)
        obs, _, _, _, recs, _ = world.step(a)
        for i, rec in enumerate(recs):
            if rec is not None and live[i]:
                records[i] = rec
                live[i] = False
                if rec.collision:
                    hits.append(_collision(world, i, rec))
    done = [r for r in records if r is not None]
    world.close()
    return EvalResult(
        setup=setup, family=family, episodes=len(done),
        collision_rate=float(np.mean([r.collision for r in done])),
        goal_rate=float(np.mean([r.goal for r in done])),
        mean_abs_cte_m=float(np.mean([r.mean_abs_cte_m for r in done])),
        mean_progress=float(np.mean([r.progress for r in done])),
        interventions_per_episode=float(np.mean([r.interventions for r in done])),
        fallbacks_per_episode=float(np.mean([r.fallbacks for r in done])),
        records=tuple(done), collisions=tuple(hits),
    )


def _collision(world: VecPathEnv, i: int, rec: EpisodeRecord) -> dict[str, Any]:
    """What environment ``i`` (just ended by a collision, not reset) ran into."""
    k = int(np.argmin(world.ranges[i]))
    j = int(world.hit[i, k])
    moving = j >= N_STATIC
    speed = float(np.hypot(*world.moving0[i, j - N_STATIC, 2:4])) if moving else 0.0
    return {"scenario": i, "moving": moving, "obstacle_speed_m_s": round(speed, 4),
            "U_max_m_s": round(world.U_max, 4), "faster": bool(speed > world.U_max),
            "own_speed_m_s": round(float(np.hypot(*world.x[i, 3:5])), 4),
            "shortest_ray_m": round(float(world.ranges[i, k]), 4),
            "threshold_m": world.collision_m, "interventions": rec.interventions,
            "fallbacks": rec.fallbacks}
