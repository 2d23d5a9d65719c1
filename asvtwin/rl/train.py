"""PPO training (stable-baselines3) of one setup and seed: log, checkpoints, resume.

:func:`train` runs PPO on a :class:`asvtwin.rl.vec_env.VecPathEnv` of ``n_envs``
environments (the vectorised world behind SB3's ``VecEnv`` interface, no subprocesses:
one process, one torch thread) and writes into ``out_dir``:

- ``episodes.csv``: one row per finished episode (global step, reward and each term,
  collision, goal, mean |CTE| [m], progress, filter interventions, fallbacks, filter
  calls and time [s], NaN actions replaced);
- ``checkpoints/step_<n>.zip`` every ``checkpoint_every`` steps and ``latest.zip``;
- ``run.json``: setup, seed, configs, steps done, wall time, throughput;
- ``policy.npz``: the final actor for :class:`asvtwin.rl.policy.NumpyPolicy`.

``resume=True`` continues from ``latest.zip`` after checking that ``run.json`` matches
the request (a foreign or corrupt checkpoint is a :class:`CheckpointError` naming the
file); rows logged after that checkpoint are dropped from the CSV so none repeats.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from asvtwin.errors import ConfigError, MissingExtraError
from asvtwin.rl.config import EnvConfig, PpoConfig, check_setup
from asvtwin.rl.policy import export_sb3_policy
from asvtwin.rl.vec_env import EpisodeRecord, VecPathEnv

__all__ = ["CSV_FIELDS", "CheckpointError", "TrainResult", "train"]

log = logging.getLogger(__name__)

#: Columns of ``episodes.csv``.
CSV_FIELDS = ("global_step", "wall_s") + tuple(f.name for f in
                                                dataclasses.fields(EpisodeRecord))


class CheckpointError(ConfigError):
    """A checkpoint or run directory does not belong to the requested run or is corrupt."""


@dataclass(frozen=True)
class TrainResult:
    """What one training run did."""

    out_dir: Path
    setup: str
    seed: int
    steps: int
    episodes: int
    collisions: int
    wall_s: float
    steps_per_s: float
    policy_path: Path


def _import_sb3() -> Any:
    try:
        import stable_baselines3 as sb3
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the extra
        raise MissingExtraError("stable-baselines3", "rl") from exc
    return sb3, torch


def _make_vec_env(world: VecPathEnv, on_episode: Callable[[EpisodeRecord], None]) -> Any:
    """SB3 ``VecEnv`` over the batched world (defined lazily: SB3 is an optional extra)."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecEnv

    n_rays = world.config.n_rays
    low = np.full(world.obs_dim, -10.0, dtype=np.float32)
    high = np.full(world.obs_dim, 10.0, dtype=np.float32)
    low[:n_rays], high[:n_rays] = 0.0, 1.0

    class _WorldVecEnv(VecEnv):  # type: ignore[misc]
        def __init__(self) -> None:
            super().__init__(world.n, spaces.Box(low, high, dtype=np.float32),
                             spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32))
            self._actions: np.ndarray | None = None

        def reset(self) -> np.ndarray:
            return world.reset_all()

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = actions

        def step_wait(self) -> Any:
            assert self._actions is not None, "step_wait() before step_async()"
            obs, r, term, trunc, records, final = world.step(self._actions)
            infos: list[dict[str, Any]] = [{} for _ in range(world.n)]
            for i, rec in enumerate(records):
                if rec is not None:
                    infos[i]["terminal_observation"] = final[i]
                    infos[i]["TimeLimit.truncated"] = bool(trunc[i])
                    on_episode(rec)
            return obs, r.astype(np.float32), term | trunc, infos

        def close(self) -> None:
            world.close()

        def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
            return [getattr(world, attr_name)] * len(self._idx(indices))

        def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
            setattr(world, attr_name, value)

        def env_method(self, method_name: str, *args: Any, indices: Any = None,
                       **kwargs: Any) -> list[Any]:
            return [getattr(world, method_name)(*args, **kwargs)]

        def env_is_wrapped(self, wrapper_class: Any, indices: Any = None) -> list[bool]:
            return [False] * len(self._idx(indices))

        def _idx(self, indices: Any) -> list[int]:
            if indices is None:
                return list(range(world.n))
            return [indices] if isinstance(indices, int) else list(indices)

    return _WorldVecEnv()


def _read_run(out_dir: Path) -> dict[str, Any]:
    path = out_dir / "run.json"
    try:
        return dict(json.loads(path.read_text()))
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"{path}: not valid JSON ({exc}); cannot resume") from exc


def _comparable(setup: str, key: str, value: Any) -> Any:
    """A ``run.json`` entry as the resume check compares it: the filter's settings
    (``psf_*``) are left out of a ``ppo`` run's environment, where no filter runs (a run
    logged before such a setting existed resumes; a filtered run must match exactly)."""
    value = json.loads(json.dumps(value))
    if setup == "ppo" and key == "env" and isinstance(value, dict):
        value = {k: v for k, v in value.items() if not k.startswith("psf_")}
    return value


def _truncate_csv(path: Path, max_step: int) -> int:
    if not path.exists():
        return 0
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    kept = [r for r in rows if int(r["global_step"]) <= max_step]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_FIELDS)
        w.writeheader()
        w.writerows(kept)
    return len(kept)


def train(setup: str, *, steps: int, seed: int, out_dir: str | Path,
          env_config: EnvConfig | None = None, ppo: PpoConfig | None = None,
          checkpoint_every: int = 50_000, resume: bool = False,
          progress: Callable[[int, int, dict[str, float]], None] | None = None
          ) -> TrainResult:
    """Train PPO in ``setup`` for ``steps`` environment steps with ``seed``.

    ``progress(done, total, stats)`` is called after every rollout (stats: episodes,
    collision rate and mean reward over the last 100 episodes, steps/s).
    """
    check_setup(setup)
    if not (isinstance(steps, int) and steps >= 1):
        raise ConfigError(f"steps must be an int >= 1, actually: {steps!r}")
    sb3, torch = _import_sb3()
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.utils import set_random_seed

    torch.set_num_threads(1)  # one thread beats two on 2 shared cores
    ppo = ppo or PpoConfig()
    env_config = dataclasses.replace(env_config or EnvConfig(), setup=setup)
    out = Path(out_dir)
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    csv_path, latest = out / "episodes.csv", out / "checkpoints" / "latest.zip"
    request = {"setup": setup, "seed": seed, "env": env_config.to_dict(),
               "ppo": dataclasses.asdict(ppo)}
    done_before, wall_before, n_rows = 0, 0.0, 0
    if resume and latest.exists():
        prev = _read_run(out)
        for key in ("setup", "seed", "env", "ppo"):
            if _comparable(setup, key, prev.get(key)) != _comparable(setup, key, request[key]):
                raise CheckpointError(
                    f"{out / 'run.json'}: {key} is {prev.get(key)!r}, the request has "
                    f"{request[key]!r}; resume only the same run (or use a new --out)")
        done_before = int(prev.get("checkpoint_step", 0))
        wall_before = float(prev.get("wall_s", 0.0))
        n_rows = _truncate_csv(csv_path, done_before)
    elif csv_path.exists():
        csv_path.unlink()

    set_random_seed(seed)
    world = VecPathEnv(ppo.n_envs, env_config, seed=seed + 1_000_003 * done_before)
    t_start = time.perf_counter()
    state: dict[str, Any] = {"episodes": n_rows, "collisions": 0, "last": []}
    fh = csv_path.open("a", newline="")
    writer = csv.DictWriter(fh, fieldnames=CSV_FIELDS)
    if n_rows == 0:
        writer.writeheader()
    model_ref: dict[str, Any] = {}

    def on_episode(rec: EpisodeRecord) -> None:
        row = rec.to_dict()
        step = model_ref["m"].num_timesteps if "m" in model_ref else 0
        row.update(global_step=step, wall_s=round(wall_before + time.perf_counter()
                                                  - t_start, 3))
        writer.writerow(row)
        state["episodes"] += 1
        state["collisions"] += rec.collision
        state["last"] = (state["last"] + [(rec.collision, rec.reward)])[-100:]

    venv = _make_vec_env(world, on_episode)
    policy_kwargs = {"net_arch": {"pi": list(ppo.net_arch), "vf": list(ppo.net_arch)},
                     "activation_fn": torch.nn.Tanh, "log_std_init": ppo.log_std_init}
    if resume and latest.exists():
        try:
            model = sb3.PPO.load(latest, env=venv, device="cpu")
        except Exception as exc:  # a corrupt zip raises anything from zipfile to torch
            raise CheckpointError(f"{latest}: cannot load the checkpoint ({type(exc).__name__}: "
                                  f"{exc}); expected a stable-baselines3 PPO zip") from exc
        if model.observation_space.shape != (world.obs_dim,):
            raise CheckpointError(f"{latest}: observation shape "
                                  f"{model.observation_space.shape}, expected ({world.obs_dim},)")
    else:
        model = sb3.PPO("MlpPolicy", venv, n_steps=ppo.n_steps, batch_size=ppo.batch_size,
                        n_epochs=ppo.n_epochs, gamma=ppo.gamma, gae_lambda=ppo.gae_lambda,
                        ent_coef=ppo.ent_coef, learning_rate=ppo.learning_rate,
                        clip_range=ppo.clip_range, policy_kwargs=policy_kwargs,
                        seed=seed, device="cpu", verbose=0)
        if ppo.warm_start_steps:
            from asvtwin.rl.warm_start import clone_into, expert_dataset

            X, Y = expert_dataset(env_config, steps=ppo.warm_start_steps, seed=seed)
            loss = clone_into(model, X, Y, seed=seed)
            log.info("warm start: cloned the line-of-sight expert on %d samples, MSE %.4f",
                     len(X), loss)
            request["warm_start_mse"] = round(loss, 6)
    model_ref["m"] = model

    def save_run(step: int, final: bool = False) -> None:
        wall = wall_before + time.perf_counter() - t_start
        info = dict(request, checkpoint_step=step, wall_s=round(wall, 3),
                    episodes=state["episodes"], finished=final,
                    steps_per_s=round((step - done_before) /
                                      max(time.perf_counter() - t_start, 1e-9), 1))
        (out / "run.json").write_text(json.dumps(info, indent=1))

    class _Cb(BaseCallback):  # type: ignore[misc]
        def __init__(self) -> None:
            super().__init__()
            self.next_ckpt = (done_before // checkpoint_every + 1) * checkpoint_every

        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            fh.flush()
            n = self.model.num_timesteps
            if n >= self.next_ckpt:
                self.model.save(out / "checkpoints" / f"step_{n}.zip")
                self.model.save(latest)
                save_run(n)
                self.next_ckpt = (n // checkpoint_every + 1) * checkpoint_every
            if progress is not None:
                last = state["last"]
                progress(n, steps, {
                    "episodes": state["episodes"],
                    "collision_rate": float(np.mean([c for c, _ in last])) if last else 0.0,
                    "mean_reward": float(np.mean([r for _, r in last])) if last else 0.0,
                    "steps_per_s": (n - done_before) / max(time.perf_counter() - t_start,
                                                           1e-9)})

    try:
        remaining = max(steps - done_before, 0)
        if remaining:
            model.learn(total_timesteps=remaining, callback=_Cb(),
                        reset_num_timesteps=not (resume and done_before > 0))
    finally:
        fh.close()
    n_done = int(model.num_timesteps)
    model.save(latest)
    save_run(n_done, final=True)
    meta = {"obs_dim": world.obs_dim, "n_rays": env_config.n_rays,
            "lidar_range_m": env_config.lidar_range_m, "dt_s": env_config.dt_s,
            "lookahead_m": env_config.lookahead_m, "U_max": world.U_max,
            "reference_length_m": world.params.length, "setup": setup, "seed": seed,
            "steps": n_done}
    policy_path = export_sb3_policy(model, out / "policy.npz", meta)
    wall = time.perf_counter() - t_start
    with csv_path.open(newline="") as f2:
        rows = list(csv.DictReader(f2))
    return TrainResult(out_dir=out, setup=setup, seed=seed, steps=n_done,
                       episodes=len(rows),
                       collisions=sum(r["collision"] == "True" for r in rows), wall_s=wall,
                       steps_per_s=(n_done - done_before) / max(wall, 1e-9),
                       policy_path=policy_path)
