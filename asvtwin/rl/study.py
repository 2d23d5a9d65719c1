"""The paper's training study: three setups × several seeds, figure, tables, evaluation.

:func:`run_study` trains every (setup, seed) pair with :func:`asvtwin.rl.train.train` —
in a local process pool (default) or as Ray tasks (``ray_address``: ``"local"`` starts a
2-CPU local Ray, any other value connects to that cluster) — then evaluates each final
policy on held-out scenarios (:mod:`asvtwin.rl.evaluate`) and writes into ``out``:

- ``episodes.csv.gz``: every training episode of every run (setup, seed, global step,
  reward and its terms, collision, CTE, filter use);
- ``training.png``: the paper's figure — reward, collision rate and mean |CTE| per
  episode, rolling mean over 100 episodes, against training steps; mean over seeds with
  the seeds' range shaded;
- ``collisions.csv``: total collisions during training per setup and seed;
- ``evaluation.csv``: held-out results per setup, seed and scenario family;
- ``library.csv``: each run's policy on the scenario library's open-water encounters
  (:mod:`asvtwin.rl.library`: collision, goal, closest distance against the library's
  requirement), with the line-of-sight expert as baseline when given;
- ``eval_collisions.csv``: every held-out collision (obstacle speed against the ship's
  top speed, shortest ray, filter use);
- ``study.json``: the request, per-run results and timing.

A run is a pure function of (setup, seed, steps, configs): the same seeds give the same
CSV rows whichever executor ran them (torch uses one thread; the environment draws from
seeded generators only).
"""

from __future__ import annotations

import csv
import dataclasses
import gzip
import json
import logging
import os
import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from asvtwin.errors import ConfigError, MissingExtraError
from asvtwin.rl.config import SETUPS, EnvConfig, PpoConfig, check_setup

__all__ = ["STUDY_FAMILIES", "collect_runs", "evaluate_run", "library_baselines",
           "load_episodes", "plot_training", "run_one", "run_study", "write_study"]

log = logging.getLogger(__name__)

#: Scenario families of the held-out evaluation.
STUDY_FAMILIES = ("static", "moving")


def run_one(setup: str, seed: int, steps: int, out_dir: str, env: dict[str, Any],
            ppo: dict[str, Any], eval_episodes: int, checkpoint_every: int,
            resume: bool = False, library: Sequence[str] | None = None) -> dict[str, Any]:
    """Train one (setup, seed) and evaluate it; a plain-data result (picklable)."""
    from asvtwin.rl.train import train

    env_cfg = EnvConfig.from_dict(env)
    ppo_cfg = PpoConfig(**{**ppo, "net_arch": tuple(ppo["net_arch"])})
    res = train(setup, steps=steps, seed=seed, out_dir=out_dir, env_config=env_cfg,
                ppo=ppo_cfg, checkpoint_every=checkpoint_every, resume=resume)
    result = {"setup": setup, "seed": seed, "steps": res.steps, "episodes": res.episodes,
              "collisions": res.collisions, "wall_s": res.wall_s,
              "steps_per_s": res.steps_per_s, "out_dir": str(res.out_dir),
              "policy_path": str(res.policy_path),
              **evaluate_run(res.policy_path, setup, seed, eval_episodes, env_cfg,
                             library=library)}
    (Path(out_dir) / "result.json").write_text(json.dumps(result, indent=1))
    return result


def collect_runs(run_dirs: Sequence[str | Path], *, eval_episodes: int = 0,
                 env: EnvConfig | None = None, library: Sequence[str] | None = None
                 ) -> list[dict[str, Any]]:
    """Results of run directories, finished or not (e.g. stopped at a deadline).

    A finished run's ``result.json`` is used as written; otherwise the run is described
    from ``run.json`` and ``episodes.csv`` (``"finished": False``, ``steps`` the last
    logged step) and, when it has a ``policy.npz`` and ``eval_episodes`` > 0, evaluated.
    """
    out: list[dict[str, Any]] = []
    for d in map(Path, run_dirs):
        if (d / "result.json").exists():
            out.append(dict(json.loads((d / "result.json").read_text()), finished=True))
            continue
        run = json.loads((d / "run.json").read_text()) if (d / "run.json").exists() else {}
        with open(d / "episodes.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        setup, _, seed = d.name.rpartition("_seed")
        setup = run.get("setup", setup)
        finished = bool(run.get("finished")) and (d / "policy.npz").exists()
        ev: dict[str, Any] = {"evaluation": [], "library": [], "collision_details": []}
        if finished and eval_episodes > 0:
            cfg = EnvConfig.from_dict(run["env"]) if "env" in run else (env or EnvConfig())
            ev = evaluate_run(d / "policy.npz", setup, int(run.get("seed", seed)),
                              eval_episodes, cfg, library=library)
        out.append({"setup": setup, "seed": int(run.get("seed", seed)),
                    "steps": int(run["checkpoint_step"]) if finished else
                    (int(rows[-1]["global_step"]) if rows else 0),
                    "episodes": len(rows),
                    "collisions": sum(r["collision"] == "True" for r in rows),
                    "wall_s": float(rows[-1]["wall_s"]) if rows else 0.0,
                    "steps_per_s": float(run.get("steps_per_s", 0.0)), "out_dir": str(d),
                    "policy_path": str(d / "policy.npz") if finished else "",
                    **ev, "finished": finished})
    return out


def evaluate_run(policy_path: str | Path, setup: str, seed: int, eval_episodes: int,
                 env: EnvConfig, *, library: Sequence[str] | None = None
                 ) -> dict[str, Any]:
    """A trained policy on the held-out scenarios of :data:`STUDY_FAMILIES`
    (``eval_episodes`` each) and on the scenario library's encounters
    (:mod:`asvtwin.rl.library`; ``library`` names a subset, default all that fit), in
    its own setup. Nothing when ``eval_episodes`` is 0.

    Returns ``evaluation`` (one row per family), ``library`` (one row per encounter) and
    ``collision_details`` (each held-out collision: obstacle speed against U_max, the
    shortest ray, filter use)."""
    from asvtwin.rl.evaluate import evaluate_policy
    from asvtwin.rl.library import evaluate_library, library_encounters

    evals: list[dict[str, Any]] = []
    hits: list[dict[str, Any]] = []
    lib: list[dict[str, Any]] = []
    if eval_episodes > 0:
        for fam in STUDY_FAMILIES:
            ev = evaluate_policy(policy_path, setup, fam, n_episodes=eval_episodes,
                                 env_config=env)
            evals.append(dict(ev.to_dict(), seed=seed))
            hits += [dict(h, setup=setup, seed=seed, family=fam) for h in ev.collisions]
        from asvtwin.rl.policy import NumpyPolicy

        encs = [e for e in library_encounters()[0] if library is None or e.name in library]
        lib = [dict(r.to_dict(), seed=seed) for r in
               evaluate_library(NumpyPolicy.load(policy_path), setup, encounters=encs,
                                env_config=env)]
    return {"evaluation": evals, "library": lib, "collision_details": hits}


def library_baselines(env: EnvConfig | None = None) -> list[dict[str, Any]]:
    """The line-of-sight expert on the library's encounters without the filter (``los``)
    and behind the filter with the moving obstacles' prediction (``los_psf``): the
    reference a trained policy must match to replace ``los_psf`` as the default."""
    from asvtwin.rl.library import LosExpertPolicy, evaluate_library

    cfg = env or EnvConfig()
    out: list[dict[str, Any]] = []
    for name, setup in (("los", "ppo"), ("los_psf", "ppo_psf_moving")):
        out += [dict(r.to_dict(), seed=-1) for r in
                evaluate_library(LosExpertPolicy(cfg.n_rays), setup, controller=name,
                                 env_config=cfg)]
    return out


def write_study(out: str | Path, results: list[dict[str, Any]],
                baselines: Sequence[dict[str, Any]] = ()) -> None:
    """Write the study's CSVs and figure for ``results`` (see the module docstring);
    ``baselines`` (:func:`library_baselines`) join the library table."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _write_outputs(out, results, baselines)


def _ray_map(tasks: list[tuple[Any, ...]], address: str) -> list[dict[str, Any]]:
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    try:
        import ray
    except ImportError as exc:  # pragma: no cover - depends on the extra
        raise MissingExtraError("ray", "ray") from exc
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_one)
        return list(ray.get([remote.remote(*t) for t in tasks]))
    finally:
        if started:
            ray.shutdown()


def run_study(*, setups: Sequence[str] = SETUPS, seeds: Sequence[int] = (0, 1, 2),
              steps: int = 300_000, out: str | Path, workers: int = 2,
              ray_address: str | None = None, env: EnvConfig | None = None,
              ppo: PpoConfig | None = None, eval_episodes: int = 20,
              checkpoint_every: int = 50_000, resume: bool = False,
              library: Sequence[str] | None = None,
              on_done: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Train and evaluate every (setup, seed); write the CSVs, the figure and study.json."""
    for s in setups:
        check_setup(s)
    if not seeds:
        raise ConfigError("seeds must name at least one seed")
    if not (isinstance(workers, int) and workers >= 1):
        raise ConfigError(f"workers must be an int >= 1, actually: {workers!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = env or EnvConfig()
    ppo = ppo or PpoConfig()
    env_d = env.to_dict()
    ppo_d = dataclasses.asdict(ppo)
    tasks = [(s, int(seed), int(steps), str(out / "runs" / f"{s}_seed{seed}"), env_d, ppo_d,
              int(eval_episodes), int(checkpoint_every), resume,
              None if library is None else tuple(library))
             for seed in seeds for s in setups]
    t0 = time.perf_counter()
    results: list[dict[str, Any]] = []
    if ray_address is not None:
        results = _ray_map(tasks, ray_address)
        for r in results:
            if on_done:
                on_done(r)
    elif workers == 1:
        for t in tasks:
            results.append(run_one(*t))
            if on_done:
                on_done(results[-1])
    else:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as ex:
            futs = [ex.submit(run_one, *t) for t in tasks]
            for f in futs:
                results.append(f.result())
                if on_done:
                    on_done(results[-1])
    wall = time.perf_counter() - t0
    _write_outputs(out, results)
    summary = {"setups": list(setups), "seeds": list(seeds), "steps": steps,
               "workers": workers, "ray": ray_address, "wall_s": round(wall, 1),
               "env": env_d, "ppo": ppo_d, "runs": results}
    (out / "study.json").write_text(json.dumps(summary, indent=1))
    return summary


def load_episodes(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every run's ``episodes.csv`` rows with its setup and seed, numbers parsed."""
    rows: list[dict[str, Any]] = []
    for r in results:
        with open(Path(r["out_dir"]) / "episodes.csv", newline="") as fh:
            for row in csv.DictReader(fh):
                d: dict[str, Any] = {"setup": r["setup"], "seed": r["seed"]}
                for k, v in row.items():
                    d[k] = (v == "True" if v in ("True", "False") else float(v))
                rows.append(d)
    return rows


def _write_dicts(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as fh:
        if rows:
            dw = csv.DictWriter(fh, fieldnames=list(rows[0]))
            dw.writeheader()
            dw.writerows(rows)


def _write_outputs(out: Path, results: list[dict[str, Any]],
                   baselines: Sequence[dict[str, Any]] = ()) -> None:
    rows = load_episodes(results)
    keys = ["setup", "seed", "global_step", "length", "reward", "r_path", "r_colav",
            "r_psf", "r_exists", "r_collision", "collision", "collision_moving", "goal",
            "mean_abs_cte_m", "progress", "interventions", "fallbacks", "filter_calls",
            "filter_time_s", "nan_actions"]
    with gzip.open(out / "episodes.csv.gz", "wt", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        for r in rows:
            w.writerow([_cell(k, r[k]) for k in keys])
    with open(out / "collisions.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["setup", "seed", "steps", "finished", "episodes", "collisions",
                    "collisions_with_moving", "last100_collision_rate",
                    "last100_mean_abs_cte_m"])
        for r in results:
            mine = [x for x in rows if x["setup"] == r["setup"] and x["seed"] == r["seed"]]
            last = mine[-100:]
            w.writerow([r["setup"], r["seed"], r["steps"], int(r.get("finished", True)),
                        len(mine),
                        sum(x["collision"] for x in mine),
                        sum(x["collision_moving"] for x in mine),
                        round(float(np.mean([x["collision"] for x in last])), 3) if last else "",
                        round(float(np.mean([x["mean_abs_cte_m"] for x in last])), 2)
                        if last else ""])
    _write_dicts(out / "evaluation.csv", [e for r in results for e in r["evaluation"]])
    _write_dicts(out / "library.csv",
                 [e for r in results for e in r.get("library", [])] + list(baselines))
    _write_dicts(out / "eval_collisions.csv",
                 [e for r in results for e in r.get("collision_details", [])])
    fig = plot_training(rows)
    fig.savefig(out / "training.png", dpi=110)


_INTS = {"seed", "global_step", "length", "interventions", "fallbacks", "filter_calls",
         "nan_actions"}


def _cell(key: str, v: Any) -> Any:
    if isinstance(v, bool) or key in _INTS:
        return int(v)
    return round(v, 4) if isinstance(v, float) else v


def _rolling(x: np.ndarray, n: int = 100) -> np.ndarray:
    c = np.cumsum(np.insert(x.astype(float), 0, 0.0))
    k = np.arange(1, len(x) + 1)
    lo = np.maximum(k - n, 0)
    return (c[k] - c[lo]) / (k - lo)


def plot_training(rows: Sequence[dict[str, Any]], *, window: int = 100) -> Any:
    """The paper's figure: reward, collision rate, |CTE| (rolling mean over ``window``
    episodes) against training steps; one colour per setup, mean over seeds, seeds' range
    shaded. Returns a matplotlib Figure."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    fig = Figure(figsize=(13, 3.8), layout="constrained")
    axes = fig.subplots(1, 3)
    names = {"ppo": "PPO", "ppo_psf": "PPO+PSF", "ppo_psf_moving": "PPO+PSF (moving info)"}
    quantities = (("reward", "average reward per episode"),
                  ("collision", "collision rate"), ("mean_abs_cte_m", "mean |CTE| [m]"))
    for setup, colour in zip(SETUPS, ("tab:red", "tab:blue", "tab:green")):
        mine = [r for r in rows if r["setup"] == setup]
        if not mine:
            continue
        seeds = sorted({r["seed"] for r in mine})
        top = max(r["global_step"] for r in mine)
        grid = np.linspace(0, top, 200)
        for ax, (key, label) in zip(axes, quantities):
            curves = []
            for s in seeds:
                rs = sorted((r for r in mine if r["seed"] == s), key=lambda r: r["global_step"])
                if not rs:
                    continue
                xs = np.array([r["global_step"] for r in rs])
                ys = _rolling(np.array([float(r[key]) for r in rs]), window)
                curves.append(np.interp(grid, xs, ys, left=np.nan))
            arr = np.array(curves)
            with warnings.catch_warnings():  # a grid point before any seed's first episode
                warnings.simplefilter("ignore", RuntimeWarning)
                ax.plot(grid, np.nanmean(arr, axis=0), color=colour, label=names[setup])
                ax.fill_between(grid, np.nanmin(arr, axis=0), np.nanmax(arr, axis=0),
                                color=colour, alpha=0.2, lw=0)
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v / 1000:g}k"))
            ax.set_xlabel("training steps")
            ax.set_ylabel(label)
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle(f"Training, rolling mean over {window} episodes (mean over seeds, range "
                 f"shaded)")
    return fig
