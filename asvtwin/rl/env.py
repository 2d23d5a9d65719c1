"""Gymnasium environment: path following and collision avoidance for one own ship.

:class:`PathColavEnv` is the one-environment face of :class:`asvtwin.rl.vec_env.VecPathEnv`
(the same world, reward and filter code, n = 1, no automatic reset). The setup —
``"ppo"`` (no filter), ``"ppo_psf"`` (safety filter with the LiDAR's obstacles) or
``"ppo_psf_moving"`` (also the moving obstacles' predicted motion) — is chosen by
:class:`asvtwin.rl.config.EnvConfig` or the ``setup=`` keyword.

Examples
--------
>>> from asvtwin.rl.env import PathColavEnv
>>> env = PathColavEnv(setup="ppo")
>>> obs, info = env.reset(seed=3)
>>> obs.shape
(186,)
>>> obs, r, terminated, truncated, info = env.step(env.action_space.sample())
>>> sorted(k for k in info if k.startswith("r_"))
['r_colav', 'r_collision', 'r_exists', 'r_path', 'r_psf']
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

try:
    import gymnasium as gym
    from gymnasium import spaces
except ImportError as exc:  # pragma: no cover - depends on the extra
    from asvtwin.errors import MissingExtraError

    raise MissingExtraError("gymnasium", "rl") from exc

from asvtwin.rl.config import EnvConfig, check_setup
from asvtwin.rl.scenarios import Scenario
from asvtwin.rl.vec_env import VecPathEnv
from asvtwin.vessel.params import VesselParams

__all__ = ["PathColavEnv"]


class PathColavEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """One own ship on a random path among static and moving obstacles.

    Observation: ``n_rays`` LiDAR closeness values and 6 navigation features
    (:mod:`asvtwin.rl.observation`); action: [surge, yaw] in [−1, 1]². An episode
    terminates on a collision (a LiDAR ray shorter than the ship's length) or at the goal
    (progress ≥ 0.99) and is truncated at ``max_steps``. ``info`` holds each reward term,
    the CTE [m], progress, whether the filter intervened, and at the end the
    :class:`~asvtwin.rl.vec_env.EpisodeRecord` as ``info["episode_record"]``.

    ``reset(options={"scenario": Scenario})`` plays a given scenario (held-out sets).
    """

    metadata = {"render_modes": []}  # noqa: RUF012 (Gymnasium declares it so)

    def __init__(self, config: EnvConfig | None = None, *, setup: str | None = None,
                 params: VesselParams | None = None) -> None:
        cfg = config or EnvConfig()
        if setup is not None:
            cfg = dataclasses.replace(cfg, setup=check_setup(setup))
        self.config = cfg
        self._params = params
        self._vec = VecPathEnv(1, cfg, seed=0, params=params, auto_reset=False)
        n = self._vec.obs_dim
        low = np.full(n, -10.0, dtype=np.float32)
        high = np.full(n, 10.0, dtype=np.float32)
        low[: cfg.n_rays] = 0.0
        high[: cfg.n_rays] = 1.0
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._done = True

    @property
    def world(self) -> VecPathEnv:
        """The underlying one-environment world (state, path, obstacles, filter)."""
        return self._vec

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            # re-seed the world's scenario stream from the gymnasium seed
            self._vec._rngs = [np.random.default_rng(seed)]
        sc = (options or {}).get("scenario")
        if sc is not None:
            if not isinstance(sc, Scenario):
                from asvtwin.errors import ConfigError

                raise ConfigError(f"options['scenario'] must be a Scenario, actually: "
                                  f"{type(sc).__name__}")
            self._vec.load_scenario(0, sc)
        else:
            self._vec._reset(np.array([0]))
        self._done = False
        return self._vec._observe()[0], {}

    def step(self, action: NDArray[np.floating]
             ) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        if self._done:
            from asvtwin.errors import StateError

            raise StateError("step() called on an ended episode: call reset() first")
        vec = self._vec
        interventions_before = vec._acc["interventions"][0]
        _obs, r, term, trunc, records, final = vec.step(np.asarray(action)[None])
        info: dict[str, Any] = {
            "cte_m": float(vec.feat[0, 1]),
            "progress": float(vec.feat[0, 4]),
            "intervened": bool(vec._acc["interventions"][0] > interventions_before),
        }
        rec = records[0]
        if rec is not None:
            info["episode_record"] = rec
            self._done = True
        info.update(self._last_terms())
        return final[0], float(r[0]), bool(term[0]), bool(trunc[0]), info

    def _last_terms(self) -> dict[str, float]:
        t = self._vec.last_terms
        return {k: float(getattr(t, k)[0]) for k in
                ("r_path", "r_colav", "r_psf", "r_exists", "r_collision")}

    def close(self) -> None:
        self._vec.close()
