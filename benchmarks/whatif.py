"""Benchmark of a what-if question; prints one JSON object.

The question: the library's head-on encounter (full-scale own ship, 60 m coaster) forked
``--at`` seconds in, four alternatives (follow the route with the filter, the same
without it, keep course, 30° to starboard), 120 s horizon, the safety filter in the loop
(acados when installed) with its economy on (:mod:`asvtwin.whatif.rollout`).

Keys (all in one run, so ratios compare like with like):

- ``fork_ms``: a live twin's snapshot (model-scale crossing, a few ticks in) to the first
  rollout step: :func:`asvtwin.whatif.fork`, the draws of 100 futures, and one step of
  all futures of the four alternatives [ms].
- ``answer_s``: wall time of the question, ``--rollouts`` × 4 alternatives, on a pool of
  2 processes (spawned and warmed before timing) [s].
- ``rollouts_per_s``: futures (rollouts × alternatives) per second of ``answer_s``.
- ``rollouts_per_s_1proc`` and ``scaling_1_to_2``: the same question in one process, and
  the ratio of the wall times (2 would be linear).
- ``ray_answer_s_1``, ``ray_answer_s_2`` and ``ray_scaling_1_to_2``: the same question as
  two Ray tasks on a local Ray of 1 and of 2 workers (warmed before timing), and the
  ratio (skipped with ``--no-ray``; ``null`` when Ray cannot start).
- ``filter_calls_per_future``, ``u_L_precertified_per_future``,
  ``solver_calls_share``: how the economy answered the filter's questions, per filtered
  future; ``cpu_s_1proc`` and ``cpu_s_2proc``: CPU seconds of the one-process run and of
  the pool's two workers together, and ``futures_per_cpu_s`` (on a loaded machine the
  wall times above measure the share of the CPU the benchmark got; these do not).
- for the record: the collision probabilities per alternative and the recommendation.

The machine may be shared: say so with the numbers (``load_avg`` is printed).

Usage: ``python benchmarks/whatif.py [--quick] [--rollouts 100] [--at 240] [--no-ray]``
(``--quick``: 20 rollouts, two groups of the economy's plan sharing, so both
processes get work).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import time
from concurrent.futures import Executor, ProcessPoolExecutor

import numpy as np

from asvtwin.scenarios import load_library, resolve_scene
from asvtwin.whatif import (
    RolloutConfig,
    ask,
    default_alternatives,
    draw_samples,
    fork,
    fork_scenario,
    simulate,
    warm_up,
)


def _fork_ms(repeats: int = 3) -> float:
    from asvtwin.twin import Twin

    twin = Twin(load_library("model_scale_crossing"))
    for _ in range(10):
        twin.step()
    snap = twin.latest()
    twin.close()
    out = []
    for k in range(repeats + 1):
        t0 = time.perf_counter()
        f = fork(snap)
        cfg = RolloutConfig(horizon_s=1e-3)  # one step
        s = draw_samples(f, 100, np.random.default_rng(k), cfg)
        simulate(f, default_alternatives(), s, config=cfg, land=twin.scene.land,
                 params=twin.params)
        out.append(1e3 * (time.perf_counter() - t0))
    return float(np.median(out[1:]))


def _timed(f, land, cfg, rollouts, executor: Executor | None):
    t0, c0 = time.perf_counter(), time.process_time()
    ans = ask(f, rollouts=rollouts, seed=0, config=cfg, land=land, executor=executor,
              workers=2 if executor is not None else 1)
    return ans, time.perf_counter() - t0, time.process_time() - c0


def _ray(f, land, cfg, rollouts, cpus: int) -> float | None:
    from asvtwin.whatif import RayExecutor

    try:
        ex = RayExecutor("local", num_cpus=cpus)
    except Exception:  # noqa: BLE001 - Ray raises a bare Exception when its raylet is slow
        return None
    try:
        for fu in [ex.submit(warm_up) for _ in range(cpus)]:
            fu.result()
        return _timed(f, land, cfg, rollouts, ex)[1]
    finally:
        ex.shutdown()


def main() -> None:
    from asvtwin.cli.run import native_stdout_to_stderr

    # acados prints QP warnings on fd 1; keep stdout for the one JSON object
    with native_stdout_to_stderr() as out:
        print(json.dumps(_measure()), file=out)


def _measure() -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rollouts", type=int, default=100)
    ap.add_argument("--quick", action="store_true", help="20 rollouts (two sharing groups)")
    ap.add_argument("--at", type=float, default=240.0)
    ap.add_argument("--no-ray", action="store_true")
    args = ap.parse_args()
    R = 20 if args.quick else args.rollouts
    sc = load_library("head_on")
    f = fork_scenario(sc, at_s=args.at)
    land = resolve_scene(sc).land
    cfg = RolloutConfig(horizon_s=120.0)
    warm_up()
    fork_ms = _fork_ms()
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=ctx, initializer=warm_up) as ex:
        list(ex.map(time.sleep, [0.5, 0.5]))  # both workers up and warm
        ans, t2, _ = _timed(f, land, cfg, R, ex)
    ans1, t1, cpu1 = _timed(f, land, cfg, R, None)
    r1 = r2 = None
    if not args.no_ray:
        r1 = _ray(f, land, cfg, R, 1)
        r2 = _ray(f, land, cfg, R, 2)
    n_fut = 4 * R
    filtered = sum(a.filter for a in default_alternatives()) * R
    tm = ans1.timing
    asked = tm["filter_calls"] + tm["u_L_precertified"]
    return {
        "rollouts_per_s": n_fut / t2,
        "fork_ms": fork_ms,
        "answer_s": t2,
        "rollouts_per_s_1proc": n_fut / t1,
        "scaling_1_to_2": t1 / t2,
        "ray_answer_s_1": r1, "ray_answer_s_2": r2,
        "ray_scaling_1_to_2": (r1 / r2) if (r1 and r2) else None,
        "cpu_s_1proc": cpu1,
        "cpu_s_2proc": ans.timing["cpu_s"],
        "futures_per_cpu_s": n_fut / cpu1,
        "rollouts": R, "alternatives": 4, "horizon_s": cfg.horizon_s, "at_s": args.at,
        "filter_calls_per_future": tm["filter_calls"] / filtered,
        "u_L_precertified_per_future": tm["u_L_precertified"] / filtered,
        "solver_calls_share": ((tm["filter_calls"] - tm["filter_kept_u_L"]) / asked
                               if asked else 0.0),
        "p_collision": {a.label: a.p_collision for a in ans.alternatives},
        "same_answer_pool_and_1proc": bool(np.array_equal(ans.result.min_distance_m,
                                                          ans1.result.min_distance_m)),
        "recommendation": ans.recommendation.label,
        "load_avg": os.getloadavg()[0],
    }


if __name__ == "__main__":
    main()
