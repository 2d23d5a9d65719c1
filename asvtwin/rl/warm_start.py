"""Warm start by behaviour cloning: the policy's mean learns a line-of-sight heading
controller before PPO starts.

Why (measured, docs/rl.md): this CyberShip II model is directionally unstable at speed
and its yaw moment is small (±0.15 Nm), so an agent exploring from scratch spins in place;
in 100 k steps per run none of our from-scratch agents began to follow the path (progress
≤ 0.04 per episode). The predecessors trained 1 M steps per setup. The expert here knows
nothing of obstacles: it holds 0.6 N surge thrust and steers by
a_yaw = clip(2 χ̃_la − 2 r / r_ref) (the look-ahead heading error and the yaw rate, both in
the observation), which follows the random paths to the goal in open water. Collision
avoidance is left to PPO (and the filter), as in the paper. Every setup starts from the
same clone, so the three setups' training curves differ by the filter alone.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.rl.config import EnvConfig
from asvtwin.rl.observation import R_REF
from asvtwin.rl.vec_env import VecPathEnv

__all__ = ["clone_into", "expert_action", "expert_dataset"]

#: The expert's surge action: (a0 + 1)/2 · 2 N = 0.6 N (u ≈ 0.33 m/s, where the heading
#: loop stays out of the spin).
EXPERT_SURGE = -0.4


def expert_action(obs: NDArray[np.floating], n_rays: int) -> NDArray[np.float64]:
    """The line-of-sight expert's actions (n, 2) from observations (n, n_rays + 6)."""
    nav = np.asarray(obs, dtype=np.float64)[:, n_rays:]
    look = nav[:, 3] * np.pi  # look-ahead heading error [rad]
    r = nav[:, 2] * R_REF  # yaw rate [rad/s]
    a = np.empty((len(nav), 2))
    a[:, 0] = EXPERT_SURGE
    a[:, 1] = np.clip(2.0 * look - 2.0 * r / R_REF, -1.0, 1.0)
    return a


def expert_dataset(config: EnvConfig, *, steps: int, n_envs: int = 16, seed: int = 0
                   ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """(observations, expert actions) from ``steps`` batched steps of the expert flying
    with exploration noise (std 0.2, so the clone also sees off-track states), no filter."""
    cfg = dataclasses.replace(config, setup="ppo")
    env = VecPathEnv(n_envs, cfg, seed=seed)
    rng = np.random.default_rng(seed)
    obs = env.reset_all()
    xs, ys = [], []
    for _ in range(steps):
        a = expert_action(obs, cfg.n_rays)
        xs.append(obs.copy())
        ys.append(a.astype(np.float32))
        noisy = np.clip(a + rng.normal(0.0, 0.2, a.shape), -1, 1)
        obs, *_ = env.step(noisy)
    return np.concatenate(xs), np.concatenate(ys)


def clone_into(model: Any, obs: NDArray[np.float32], act: NDArray[np.float32], *,
               epochs: int = 20, batch: int = 256, lr: float = 1e-3, seed: int = 0) -> float:
    """Fit the SB3 policy's action mean to (obs, act) by MSE; returns the final loss."""
    import torch

    pol = model.policy
    params = list(pol.mlp_extractor.policy_net.parameters()) + list(
        pol.action_net.parameters())
    opt = torch.optim.Adam(params, lr=lr)
    X = torch.as_tensor(obs)
    Y = torch.as_tensor(act)
    g = torch.Generator().manual_seed(seed)
    loss = torch.zeros(())
    for _ in range(epochs):
        perm = torch.randperm(len(X), generator=g)
        for i in range(0, len(X), batch):
            idx = perm[i: i + batch]
            mean = pol.action_net(pol.mlp_extractor.forward_actor(X[idx]))
            loss = torch.mean((mean - Y[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
    return float(loss.detach())
