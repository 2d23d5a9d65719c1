"""Benchmark of the RL environment and of PPO training; prints one JSON object.

- ``env_steps_per_s``: the batched world without the filter (64 environments, one
  ``VecPathEnv.step`` per call: physics, 180-ray LiDAR, path features, reward), after
  warm-up, environment steps per second of wall time.
- ``env_steps_per_s_single``: the Gymnasium ``PathColavEnv`` stepped one call at a time.
- ``psf_env_steps_per_s`` / ``psf_env_steps_per_s_before``: the batched world with the
  filter (setup ``ppo_psf_moving``, 8 environments, the shipped policy's actions so the
  ships meet obstacles) with the one-pass numpy pre-cull of environments out of the
  filter's reach, and without it (every environment's obstacles built in Python, the
  former path). ``psf_same_trajectories`` says both gave identical states at every step;
  ``filter_calls``, ``interventions`` and ``fallbacks`` (per 1000 environment steps) are
  those of the pre-culled run and must equal the ``*_before`` ones: the economy changes
  no filter decision.
- ``ppo_steps_per_s``: one whole ``asvtwin train`` process (interpreter start, imports,
  warm start, training, export), setup ``ppo``, for ``--train-steps`` steps: environment
  steps divided by the process's wall time.
- ``ppo_psf_steps_per_s``: the training throughput of the 2-core machine with the filter
  on (setup ``ppo_psf_moving``): two whole ``asvtwin train`` processes (seeds 0 and 1)
  started together, their environment steps summed over the wall time until both ended
  (``asvtwin study`` runs its seeds and setups this way, two processes by default).
  ``ppo_psf_steps_per_s_1proc`` is one such process alone. ``*_cpu_ms_per_step``: the
  training processes' own CPU time (user + system, from the kernel's accounting of the
  waited-for children) per environment step, start-up included: the load-independent
  figure to compare on a shared machine (two processes on two free cores give at most
  2000 / ``ppo_psf_cpu_ms_per_step`` steps/s). Early in training the agent
  rarely gets near obstacles, so the filter is called less often than in a trained
  agent's episodes.

The environment figures are medians of ``--repeats`` runs, the training figures of
``--train-repeats`` (default 1: each is a whole training process). The machine is shared
(2 cores, other jobs running; ``load_avg_1min`` is printed): compare ratios measured in
one run, not absolute numbers across runs.

Usage: ``python benchmarks/rl.py [--train-steps 16384] [--repeats 3] [--train-repeats 1]``
"""

from __future__ import annotations

import argparse
import json
import os
import resource
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


def _psf_rate(pre_cull: bool, steps: int) -> tuple[float, dict[str, float], np.ndarray]:
    from asvtwin.rl.controller import default_policy_path
    from asvtwin.rl.policy import NumpyPolicy

    env = VecPathEnv(8, EnvConfig(setup="ppo_psf_moving"), seed=0, pre_cull=pre_cull)
    pol = NumpyPolicy.load(default_policy_path())
    obs = env.reset_all()
    env._may_need_filter()  # load the compiled kernels before timing
    pol.act(obs)
    states = np.empty((steps, env.n, 6))
    totals = {"filter_calls": 0.0, "interventions": 0.0, "fallbacks": 0.0}
    t0 = time.perf_counter()
    for k in range(steps):
        obs, _, _, _, recs, _ = env.step(pol.act(obs))
        states[k] = env.x
        for r in recs:
            if r is not None:
                for key in totals:
                    totals[key] += getattr(r, key)
    rate = env.n * steps / (time.perf_counter() - t0)
    for key in totals:  # episodes still running
        totals[key] += float(env._acc[key].sum())
    per_k = {key: round(1000 * v / (env.n * steps), 2) for key, v in totals.items()}
    return rate, per_k, states


def _train_cmd(setup: str, steps: int, seed: int, out: str) -> list[str]:
    return [sys.executable, "-m", "asvtwin", "train", "--setup", setup, "--steps",
            str(steps), "--seed", str(seed), "--out", out, "--quiet",
            "--checkpoint-every", str(10 * steps)]


def _children_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _train_rate(setup: str, steps: int, procs: int = 1) -> tuple[float, float]:
    """Environment steps per second of ``procs`` whole training processes run together,
    and their CPU time per environment step [ms]."""
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    with tempfile.TemporaryDirectory() as tmp:
        c0 = _children_cpu_s()
        t0 = time.perf_counter()
        ps = [subprocess.Popen(_train_cmd(setup, steps, seed, f"{tmp}/{seed}"),
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
              for seed in range(procs)]
        for p in ps:
            _, err = p.communicate()
            if p.returncode:
                raise RuntimeError(f"asvtwin train failed ({p.returncode}): "
                                   f"{err.decode()[-2000:]}")
        wall = time.perf_counter() - t0
        return procs * steps / wall, 1000 * (_children_cpu_s() - c0) / (procs * steps)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train-steps", type=int, default=16384)
    ap.add_argument("--psf-steps", type=int, default=300,
                    help="steps of the filtered world per environment (8 environments)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--train-repeats", type=int, default=1)
    args = ap.parse_args()
    med = lambda f, *a: float(np.median([f(*a) for _ in range(args.repeats)]))
    tmed = lambda *a: tuple(np.median(
        [_train_rate(*a) for _ in range(args.train_repeats)], axis=0).tolist())
    rate_after, per_k, x_after = _psf_rate(True, args.psf_steps)
    rate_before, per_k_before, x_before = _psf_rate(False, args.psf_steps)
    out = {
        "env_steps_per_s": round(med(_vec_rate, 64, 300)),
        "env_steps_per_s_single": round(med(_single_rate, 2000)),
        "psf_env_steps_per_s": round(rate_after),
        "psf_env_steps_per_s_before": round(rate_before),
        "psf_same_trajectories": bool(np.array_equal(x_after, x_before)),
        **{f"{k}_per_1000_steps": v for k, v in per_k.items()},
        **{f"{k}_per_1000_steps_before": v for k, v in per_k_before.items()},
    }
    for key, setup, procs, tail in (("ppo", "ppo", 1, ""), ("ppo_psf", "ppo_psf_moving", 2, ""),
                                    ("ppo_psf", "ppo_psf_moving", 1, "_1proc")):
        rate, cpu_ms = tmed(setup, args.train_steps, procs)
        out[f"{key}_steps_per_s{tail}"] = round(rate)
        out[f"{key}_cpu_ms_per_step{tail}"] = round(cpu_ms, 2)
    out.update({
        "train_steps": args.train_steps,
        "repeats": args.repeats,
        "train_repeats": args.train_repeats,
        "goal_env_steps_per_s": 20000,
        "goal_ppo_psf_steps_per_s": 500,
        "load_avg_1min": round(os.getloadavg()[0], 2),
    })
    print(json.dumps(out))


if __name__ == "__main__":
    main()
