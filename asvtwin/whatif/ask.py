"""One what-if question: fork → draws → batched rollouts (in 1..k processes) → risk → advice.

Draws are made once in the calling process from ``seed`` and handed to the workers in
contiguous slices, so the answer does not depend on the number of processes: the same
seed gives the same numbers with 1 or 2 workers (a test pins it).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from asvtwin.errors import MissingExtraError, ParameterError
from asvtwin.geo import LandMask
from asvtwin.vessel import VesselParams
from asvtwin.whatif.alternatives import Alternative, default_alternatives
from asvtwin.whatif.fork import Fork
from asvtwin.whatif.risk import (
    AlternativeRisk,
    Encounter,
    Recommendation,
    encounters,
    recommend,
    summarise,
)
from asvtwin.whatif.rollout import RolloutConfig, RolloutResult, draw_samples, simulate

__all__ = ["RayExecutor", "WhatIfAnswer", "ask", "warm_up"]


@dataclass(frozen=True, eq=False)
class WhatIfAnswer:
    """The answer to one what-if question (``to_dict()`` is its JSON form)."""

    t_s: float
    seed: int
    rollouts: int
    horizon_s: float
    alternatives: tuple[AlternativeRisk, ...]
    recommendation: Recommendation
    encounters: tuple[Encounter, ...]
    result: RolloutResult
    timing: dict[str, float] = field(default_factory=dict)

    def ghosts(self, per_alternative: int = 10) -> list[dict[str, Any]]:
        """Up to ``per_alternative`` futures of each alternative: positions [m] every
        ``track_t_s`` and whether that future collided (for the viewer)."""
        out = []
        res = self.result
        for i, a in enumerate(self.alternatives):
            for r in range(min(per_alternative, res.track.shape[1])):
                out.append({"alternative": a.label, "rollout": r,
                            "collision": bool(res.collision[i, r]),
                            "p_collision": a.p_collision,
                            "positions_m": np.round(res.track[i, r], 1).tolist()})
        return out

    def to_dict(self, *, ghosts: int = 0) -> dict[str, Any]:
        d: dict[str, Any] = {
            "t_s": self.t_s, "seed": self.seed, "rollouts": self.rollouts,
            "horizon_s": self.horizon_s,
            "alternatives": [a.to_dict() for a in self.alternatives],
            "recommendation": self.recommendation.to_dict(),
            "encounters": [e.__dict__ for e in self.encounters],
            "timing": self.timing,
            "ghost_t_s": self.result.track_t_s.tolist(),
        }
        if ghosts:
            d["ghosts"] = self.ghosts(ghosts)
        return d


class RayExecutor(Executor):
    """A :class:`concurrent.futures.Executor` of Ray tasks, for :func:`ask`'s ``executor``.

    ``address``: ``"local"`` starts a local Ray with ``num_cpus`` CPUs (stopped again by
    :meth:`shutdown`), anything else is an existing cluster's address. Each submitted call
    is one Ray task; its result comes back as a ``concurrent.futures.Future``. The draws
    are made by :func:`ask` in the calling process, so the answer is the same as on a
    process pool for the same seed.

    Raises
    ------
    MissingExtraError
        Ray is not installed (``pip install 'asvtwin[ray]'``).
    """

    def __init__(self, address: str = "local", *, num_cpus: int = 2) -> None:
        import os

        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        try:
            import ray
        except ImportError as exc:
            raise MissingExtraError("ray", "ray") from exc
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            if address == "local":
                ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=address, log_to_driver=False)
            self._started = True
        self._remote: dict[Any, Any] = {}

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Any:
        remote = self._remote.get(fn)
        if remote is None:
            remote = self._remote[fn] = self._ray.remote(fn)
        return remote.remote(*args, **kwargs).future()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if self._started and self._ray.is_initialized():
            self._ray.shutdown()
        self._started = False


def _chunks(n: int, k: int, align: int = 1) -> list[slice]:
    """``k`` contiguous slices of ``range(n)`` with inner edges on multiples of ``align``."""
    edges = (np.linspace(0, n, k + 1) / align).round().astype(int) * align
    edges[-1] = n
    edges = np.unique(np.clip(edges, 0, n))
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]


def warm_up(psf_backend: str = "auto") -> None:
    """Load the compiled kernels and the filter's solver in this process (a worker
    initializer: the first call of a fresh process otherwise pays ~1–4 s)."""
    from asvtwin.control import MovingObstacles, SafetyFilter
    from asvtwin.twin.components import twin_filter_config
    from asvtwin.vessel import cybership2, cybership2_full_scale
    from asvtwin.whatif.rollout import filter_config

    # the twin's filter, and the rollouts' (its circle slots sized to a fork of 1 target)
    configs = {twin_filter_config(psf_backend),
               filter_config(RolloutConfig(psf_backend=psf_backend), 1)}
    for p in (cybership2(), cybership2_full_scale()):
        for cfg in configs:
            f = SafetyFilter(p, config=cfg)
            obs = MovingObstacles.constant_velocity([[20 * p.length, 0.0]], [[-0.1, 0.0]],
                                                    [p.length], N=f.config.N,
                                                    dt_s=f.config.dt_s)
            f.filter([0, 0, 0, 0.1, 0, 0], [0.0, 0.0, 0.0], obs, t_s=0.0)


def ask(fork: Fork, alternatives: Sequence[Alternative] | None = None, *, rollouts: int = 100,
        seed: int = 0, config: RolloutConfig | None = None, land: LandMask | None = None,
        params: VesselParams | None = None, executor: Executor | None = None,
        workers: int = 1, acceptable: float = 0.05) -> WhatIfAnswer:
    """Answer a what-if question about ``fork``.

    Parameters
    ----------
    fork : Fork
    alternatives : sequence of Alternative, optional
        Default :func:`~asvtwin.whatif.alternatives.default_alternatives`.
    rollouts : int
        Monte Carlo futures per alternative (≥ 1).
    seed : int
        Seed of every draw (recorded in the answer).
    config : RolloutConfig, optional
    land : LandMask, optional
        The chart (grounding, the filter's coast).
    params : VesselParams, optional
        The own ship's parameters (default from the fork's vessel name).
    executor : concurrent.futures.Executor, optional
        Where to run the ``workers`` slices (a process pool); none: this process.
    workers : int
        Number of slices the rollouts are split into (only with an executor).
    acceptable : float
        Largest acceptable upper 95 % bound of the collision/grounding probability.
    """
    t0 = time.perf_counter()
    alts = tuple(alternatives) if alternatives is not None else default_alternatives()
    if rollouts < 1:
        raise ParameterError(f"rollouts must be >= 1, actually: {rollouts}")
    cfg = config or RolloutConfig()
    rng = np.random.default_rng(seed)
    samples = draw_samples(fork, rollouts, rng, cfg)
    t_draw = time.perf_counter()
    if executor is None or workers <= 1:
        res = simulate(fork, alts, samples, config=cfg, land=land, params=params)
    else:
        futs = [executor.submit(simulate, fork, alts, samples.take(sl), config=cfg, land=land,
                                params=params)
                for sl in _chunks(rollouts, workers, cfg.share_group)]
        res = RolloutResult.join([f.result() for f in futs])
    t_sim = time.perf_counter()
    risks = summarise(alts, res)
    rec = recommend(fork, alts, risks, acceptable=acceptable)
    t1 = time.perf_counter()
    return WhatIfAnswer(
        t_s=fork.t_s, seed=int(seed), rollouts=rollouts, horizon_s=cfg.horizon_s,
        alternatives=risks, recommendation=rec, encounters=encounters(fork), result=res,
        timing={"draw_s": t_draw - t0, "rollouts_s": t_sim - t_draw,
                "answer_s": t1 - t0, **res.info})
