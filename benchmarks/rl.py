"""Benchmark of the RL environment and of PPO training; prints one JSON object.

- ``env_steps_per_s``: the batched world without the filter (64 environments, one
  ``VecPathEnv.step`` per call: physics, 180-ray LiDAR, path features, reward), after
  warm-up, environment steps per second of wall time.
- ``env_steps_per_s_single``: the Gymnasium ``PathColavEnv`` stepped one call at a time.
- ``ppo_steps_per_s`` / ``ppo_psf_steps_per_s``: whole ``asvtwin train`` processes
  (interpreter start, imports, filter build or cache load, training, export) for
  ``--train-steps`` steps, setup ``ppo`` and ``ppo_psf_moving`` (filter on); environment
  steps divided by the process's wall time. Early in training the agent rarely gets near
  obstacles, so the filter is called less often than in a trained agent's episodes.

The environment figures are medians of ``--repeats`` runs, the training figures of
``--train-repeats`` (default 1: each is a whole training process). The machine is shared (2 cores, other
jobs running): compare ratios measured in one run, not absolute numbers across runs.

Usage: ``python benchmarks/rl.py [--train-steps 8192] [--repeats 3] [--train-repeats 1]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from asvtwin.rl.config import EnvConfig
from asvtwin.rl.vec_env import VecPathEnv


def _vec_rate(n_envs: int, steps: int) -> float:
    env = VecPathEnv(n_envs, EnvConfig(), seed=0)
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps, n_envs, 2))
    for k in range(10):
        env.step(acts[k])
    t0 = time.perf_counter()
    for k in range(steps):
        env.step(acts[k])
    return n_envs * steps / (time.perf_counter() - t0)


def _single_rate(steps: int) -> float:
    from asvtwin.rl.env import PathColavEnv

    env = PathColavEnv(setup="ppo")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps, 2)).astype(np.float32)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(acts[k])
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t0)


def _train_rate(setup: str, steps: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "asvtwin", "train", "--setup", setup, "--steps",
               str(steps), "--seed", "0", "--out", tmp, "--quiet",
               "--checkpoint-every", str(10 * steps)]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True,
                       env=dict(os.environ, RAY_USAGE_STATS_ENABLED="0"))
        return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train-steps", type=int, default=8192)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--train-repeats", type=int, default=1)
    args = ap.parse_args()
    med = lambda f, *a: float(np.median([f(*a) for _ in range(args.repeats)]))
    tmed = lambda *a: float(np.median(
        [_train_rate(*a) for _ in range(args.train_repeats)]))
    out = {
        "env_steps_per_s": round(med(_vec_rate, 64, 300)),
        "env_steps_per_s_single": round(med(_single_rate, 2000)),
        "ppo_steps_per_s": round(tmed("ppo", args.train_steps)),
        "ppo_psf_steps_per_s": round(tmed("ppo_psf_moving", args.train_steps)),
        "train_steps": args.train_steps,
        "repeats": args.repeats,
        "train_repeats": args.train_repeats,
        "goal_env_steps_per_s": 20000,
        "goal_ppo_psf_steps_per_s": 500,
        "load_avg_1min": round(os.getloadavg()[0], 2),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
