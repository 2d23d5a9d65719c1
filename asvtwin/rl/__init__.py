"""Reinforcement learning: the paper's PPO agent behind the predictive safety filter.

- :mod:`asvtwin.rl.config` — typed configs of the environment, reward and PPO, with sources;
- :mod:`asvtwin.rl.reward` — the paper's reward, term by term;
- :mod:`asvtwin.rl.vec_env` — the batched world (numba kernels, one filter per vessel);
- :mod:`asvtwin.rl.env` — the Gymnasium environment (``rl`` extra);
- :mod:`asvtwin.rl.train`, :mod:`asvtwin.rl.study` — PPO training and the three-setup study;
- :mod:`asvtwin.rl.evaluate`, :mod:`asvtwin.rl.library` — held-out evaluation and the
  scenario library's open-water encounters in the RL world;
- :mod:`asvtwin.rl.policy`, :mod:`asvtwin.rl.controller` — the shipped numpy policy and the
  twin's ``rl`` / ``rl_psf`` controller (no torch needed).

Only numpy-level modules are imported here; Gymnasium, stable-baselines3 and Ray load where
used.
"""

from __future__ import annotations

from asvtwin.rl.config import SETUPS, EnvConfig, PpoConfig, RewardConfig

__all__ = ["SETUPS", "EnvConfig", "PpoConfig", "RewardConfig"]
