"""Benchmark of a what-if question; prints one JSON object.

The question: the library's head-on encounter (full-scale own ship, 60 m coaster) forked
``--at`` seconds in (the coaster then ~600 m ahead, contact within the horizon without
avoiding action), four alternatives (follow the route with the filter, the same without
it, keep course, 30° to starboard), 120 s horizon, the safety filter in the loop
(acados when installed), its economy on (:mod:`asvtwin.whatif.rollout`).

- ``fork_ms``: a live twin's snapshot (model-scale crossing, a few ticks in) to the first
  rollout step: :func:`asvtwin.whatif.fork`, the draws, and one step of all futures.
- ``answer_s``: wall time of the question, ``--rollouts`` × 4 alternatives, in a pool of
  2 processes (spawned and warmed before timing).
- ``rollouts_per_s``: futures (rollouts × alternatives) per second of ``answer_s``.
- ``rollouts_per_s_1proc`` and ``scaling_1_to_2``: the same question in one process,
  and the ratio of the rates (2 would be linear).
- ``filter_calls_per_rollout`` (economy) and, for the record, the same question's
  collision probabilities per alternative.

Medians of ``--repeats`` runs. The machine is shared (2 cores, other jobs running):
compare ratios measured in one run, not absolute numbers across runs.

Usage: ``python benchmarks/whatif.py [--rollouts 100] [--repeats 1] [--at 300]``
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import time
from concurrent.futures import ProcessPoolExecutor

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


def _fork_ms(repeats: int) -> float:
    from asvtwin.twin import Twin

    twin = Twin(load_library("model_scale_crossing"))
    for _ in range(40):
        twin.step()
    snap = twin.latest()
    twin.close()
    cfg = RolloutConfig(horizon_s=twin.dt_s)
    out = []
    for k in range(repeats + 1):
        t0 = time.perf_counter()
        f = fork(snap)
        s = draw_samples(f, 100, np.random.default_rng(k), cfg)
        simulate(f, default_alternatives(), s, config=cfg, land=twin.scene.land)
        out.append(1e3 * (time.perf_counter() - t0))
    return statistics.median(out[1:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rollouts", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--at", type=float, default=300.0)
    args = ap.parse_args()
    sc = load_library("head_on")
    f = fork_scenario(sc, at_s=args.at)
    land = resolve_scene(sc).land
    cfg = RolloutConfig(horizon_s=120.0)
    warm_up()
    n_fut = 4 * args.rollouts
    one, two = [], []
    ans = None
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=ctx, initializer=warm_up) as ex:
        list(ex.map(time.sleep, [0.5, 0.5]))  # both workers up and warm
        for r in range(args.repeats):
            t0 = time.perf_counter()
            ans = ask(f, rollouts=args.rollouts, seed=r, config=cfg, land=land, executor=ex,
                      workers=2)
            two.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            ask(f, rollouts=args.rollouts, seed=r, config=cfg, land=land)
            one.append(time.perf_counter() - t0)
    assert ans is not None
    t2, t1 = statistics.median(two), statistics.median(one)
    print(json.dumps({
        "rollouts_per_s": n_fut / t2,
        "fork_ms": _fork_ms(max(3, args.repeats)),
        "answer_s": t2,
        "rollouts_per_s_1proc": n_fut / t1,
        "scaling_1_to_2": t1 / t2,
        "rollouts": args.rollouts, "alternatives": 4, "horizon_s": 120.0,
        "filter_calls_per_rollout": ans.timing["filter_calls"] / (3 * args.rollouts),
        "p_collision": {a.label: a.p_collision for a in ans.alternatives},
        "recommendation": ans.recommendation.label,
    }))


if __name__ == "__main__":
    main()
