"""``asvtwin train``: PPO in one of the paper's three setups (needs the ``rl`` extra)."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    from asvtwin.rl.config import SETUPS

    p = subparsers.add_parser(
        "train", help="train the PPO agent (optionally behind the safety filter)",
        description="Train PPO (stable-baselines3) on random paths among static and "
                    "moving obstacles; writes episodes.csv, checkpoints, run.json and "
                    "policy.npz into --out.")
    p.add_argument("--setup", choices=SETUPS, default="ppo_psf_moving",
                   help="ppo: no filter; ppo_psf: filter with LiDAR obstacles; "
                        "ppo_psf_moving: filter also given the moving obstacles' motion")
    p.add_argument("--steps", type=int, default=300_000, help="environment steps")
    p.add_argument("--seed", type=int, default=0, help="seed of PPO and the scenarios")
    p.add_argument("--out", type=Path, default=None,
                   help="run directory (default runs/<setup>_seed<seed>)")
    p.add_argument("--n-envs", type=int, default=8, help="environments stepped together")
    p.add_argument("--family", choices=("static", "moving", "mixed"), default="moving",
                   help="scenario family (default moving: 5 static + 5 moving)")
    p.add_argument("--checkpoint-every", type=int, default=50_000, help="steps")
    p.add_argument("--resume", action="store_true",
                   help="continue from <out>/checkpoints/latest.zip")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_train)


def _train(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from asvtwin.errors import ConfigError
    from asvtwin.rl.config import EnvConfig, PpoConfig
    from asvtwin.rl.train import train

    if args.steps < 1:
        raise ConfigError(f"--steps must be >= 1, actually: {args.steps}")
    out = args.out or Path("runs") / f"{args.setup}_seed{args.seed}"
    env = EnvConfig(setup=args.setup, family=args.family)
    ppo = PpoConfig(n_envs=args.n_envs)
    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total} steps"),
                  TextColumn("{task.fields[stats]}"), TimeRemainingColumn(),
                  disable=args.quiet) as bar:
        task = bar.add_task(f"{args.setup} seed {args.seed}", total=args.steps, stats="")

        def progress(done: int, total: int, st: dict[str, float]) -> None:
            bar.update(task, completed=done, stats=(
                f"{st['episodes']:.0f} ep, coll {st['collision_rate']:.2f}, "
                f"R {st['mean_reward']:.0f}, {st['steps_per_s']:.0f} steps/s"))

        res = train(args.setup, steps=args.steps, seed=args.seed, out_dir=out,
                    env_config=env, ppo=ppo, checkpoint_every=args.checkpoint_every,
                    resume=args.resume, progress=progress)
    print(f"{res.steps} steps, {res.episodes} episodes, {res.collisions} collisions, "
          f"{res.steps_per_s:.0f} steps/s; policy: {res.policy_path}")
    return 0
