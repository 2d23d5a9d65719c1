"""``asvtwin study``: the paper's three-setup training study (needs the ``rl`` extra)."""

from __future__ import annotations

import argparse
from pathlib import Path

from asvtwin.cli.argtypes import out_dir

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    from asvtwin.rl.config import SETUPS

    p = subparsers.add_parser(
        "study", help="train PPO, PPO+PSF and PPO+PSF with moving-obstacle information",
        description="Train the three setups over several seeds (process pool, or Ray "
                    "with --ray), evaluate on held-out scenarios and the scenario "
                    "library's open-water encounters and plot the paper's figure. Writes "
                    "training.png, episodes.csv.gz, collisions.csv, evaluation.csv, "
                    "library.csv, eval_collisions.csv and study.json into --out.")
    p.add_argument("--setups", nargs="+", choices=SETUPS, default=list(SETUPS))
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=300_000, help="steps per run")
    p.add_argument("--out", type=Path, default=out_dir("study"),
                   help="output directory (default: %(default)s)")
    p.add_argument("--workers", type=int, default=2, help="local processes (default 2)")
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="run as Ray tasks: 'local' (default) starts a 2-CPU local Ray; "
                        "otherwise the cluster address")
    p.add_argument("--eval-episodes", type=int, default=20,
                   help="held-out scenarios per family and run")
    p.add_argument("--family", choices=("static", "moving", "mixed"), default="moving")
    p.add_argument("--resume", action="store_true", help="resume each run's checkpoint")
    p.add_argument("--quick", action="store_true",
                   help="a short real study: 3 setups x 1 seed x 512 steps, 2 envs, "
                        "200-step episodes, 1 held-out scenario per family, the head-on "
                        "library encounter")
    p.set_defaults(func=_study)


def _study(args: argparse.Namespace) -> int:
    from asvtwin.errors import ConfigError
    from asvtwin.rl.config import EnvConfig, PpoConfig
    from asvtwin.rl.study import run_study

    env = EnvConfig(family=args.family)
    ppo = PpoConfig()
    steps, seeds, n_eval, every = args.steps, args.seeds, args.eval_episodes, 50_000
    library = None  # every library encounter that fits the training world
    if args.quick:
        env = EnvConfig(family=args.family, max_steps=200, psf_horizon=40)
        ppo = PpoConfig(n_envs=2, n_steps=128, batch_size=128, n_epochs=1)
        steps, seeds, n_eval, every = 512, args.seeds[:1], 1, 256
        library = ("head_on",)
    if steps < 1:
        raise ConfigError(f"--steps must be >= 1, actually: {steps}")

    def done(r: dict) -> None:
        print(f"{r['setup']} seed {r['seed']}: {r['steps']} steps, {r['episodes']} episodes, "
              f"{r['collisions']} collisions, {r['steps_per_s']:.0f} steps/s", flush=True)

    s = run_study(setups=args.setups, seeds=seeds, steps=steps, out=args.out,
                  workers=args.workers, ray_address=args.ray, env=env, ppo=ppo,
                  eval_episodes=n_eval, checkpoint_every=every, resume=args.resume,
                  library=library,
                  on_done=done)
    print(f"study written to {args.out} ({s['wall_s']:.0f} s)")
    return 0
