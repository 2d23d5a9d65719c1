"""Benchmark of the predictive safety filter in closed loop; prints one JSON object.

Setting: N = 50 stages of 0.5 s, 20 obstacles of which 5 move (constant
velocity, ground-truth predictions), CyberShip II driven by a naive full-thrust controller
steering north through the field, a few hundred closed-loop filter calls on the project's
simulator. Timed: the whole ``SafetyFilter.filter`` call (``solve_ms_*``, what a caller
waits for) and the backend's solver call alone (``backend_ms_*``). Warm-up excluded: the
solver build (or cache load) and the first 5 calls. ``fallback_rate`` is fallbacks per
filter call (goal ≤ 1 %); ``passed_through`` counts calls where u_L was kept behind a
certified plan without a solve. ``cpu_ms_*`` is the process CPU time of a call (less
affected by other processes on a shared machine than the wall time ``solve_ms_*``; the
1-minute load average is recorded beside them).

``steered``: the same field with a learner that steers (the heading autopilot holding
north at 0.3 m/s), so that the ship actually goes through the field: the naive
full-thrust learner above spins CyberShip II in circles near the start (the hull is
course-unstable at full thrust) and meets few obstacles. Reported beside the goal's
numbers, not instead of them (``--steered-steps 0`` skips it).

Usage: ``python benchmarks/psf.py [--backend auto|acados|casadi-ipopt] [--steps 300]
[--steered-steps 300]``
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections import Counter

import numpy as np

from asvtwin.control import (
    CircleObstacles,
    MovingObstacles,
    PsfConfig,
    SafetyFilter,
    comfort_config,
)
from asvtwin.guidance import HeadingSpeedAutopilot
from asvtwin.vessel import VesselSimulator, cybership2


def _main(stdout) -> None:  # type: ignore[no-untyped-def]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--config", default="default", choices=("default", "comfort"),
                    help="the filter's defaults, or asvtwin.control.comfort_config()")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steered-steps", type=int, default=300,
                    help="calls of the steered run (0: skip it)")
    args = ap.parse_args()

    params = cybership2()
    base = {"N": 50, "dt_s": 0.5, "backend": args.backend, "n_circles": 20}
    cfg = comfort_config(**base) if args.config == "comfort" else PsfConfig(**base)
    t0 = time.perf_counter()
    psf = SafetyFilter(params, config=cfg)
    build_s = time.perf_counter() - t0

    rng = np.random.default_rng(args.seed)
    # 15 static circles in a corridor ahead, none within 6 m of the start
    n_static, n_moving = 15, 5
    cs = np.stack([rng.uniform(8, 80, n_static), rng.uniform(-15, 15, n_static)], axis=1)
    cs[np.linalg.norm(cs, axis=1) < 6.0] += [10.0, 0.0]
    static = CircleObstacles(cs, rng.uniform(0.8, 2.5, n_static))
    mp = np.stack([rng.uniform(15, 70, n_moving), rng.choice([-25.0, 25.0], n_moving)], axis=1)
    mv = np.stack([rng.uniform(-0.1, 0.1, n_moving), -np.sign(mp[:, 1]) *
                   rng.uniform(0.15, 0.35, n_moving)], axis=1)
    mr = rng.uniform(1.0, 2.0, n_moving)

    def run(steered: bool, steps: int) -> dict:
        psf.reset()
        sim = VesselSimulator(params, [0.0, 0.0, 0.0, 0.3, 0.0, 0.0], dt_s=0.1)
        u_L = np.array([2.0, 0.0, 0.0])
        ap = HeadingSpeedAutopilot(params) if steered else None
        call_ms, solver_ms, fallbacks, violations, min_clear = [], [], 0, 0, np.inf
        kinds: Counter[str] = Counter()
        cpu_ms: list[float] = []
        interventions = passed = 0
        x = sim.state
        for k in range(steps):
            t = k * cfg.dt_s
            moving = MovingObstacles.constant_velocity(mp + t * mv, mv, mr, N=cfg.N, dt_s=cfg.dt_s)
            if ap is not None:  # steer north at 0.3 m/s through the field
                u_L = ap.tau(x, 0.0, 0.3)
            c0, p0 = time.perf_counter(), time.process_time()
            res = psf.filter(x, u_L, [static, moving], t_s=t)
            c1, p1 = time.perf_counter(), time.process_time()
            if k >= 5:
                call_ms.append((c1 - c0) * 1e3)
                cpu_ms.append((p1 - p0) * 1e3)
                solver_ms.append(res.solve_time_s * 1e3)
            fallbacks += res.fallback != "none"
            if res.fallback != "none":
                kinds[res.fallback] += 1
            interventions += res.intervened
            passed += res.passed_through
            for j in range(5):
                x = sim.step(res.u0)
                tj = t + 0.1 * (j + 1)
                gap = min(float(np.min(np.linalg.norm(static.centres - x[:2], axis=1) - static.radii)),
                          float(np.min(np.linalg.norm(mp + tj * mv - x[:2], axis=1) - mr)))
                min_clear = min(min_clear, gap)
                violations += gap < psf.d_safe_m
        a, b = np.asarray(call_ms), np.asarray(solver_ms)
        return {"a": a, "b": b, "cpu_ms": cpu_ms, "fallbacks": fallbacks, "kinds": kinds,
                "interventions": interventions, "passed": passed,
                "violations": violations, "min_clear": min_clear, "x": x}

    out = run(False, args.steps)
    a, b, cpu_ms, fallbacks, kinds = (out["a"], out["b"], out["cpu_ms"], out["fallbacks"],
                                      out["kinds"])
    interventions, passed, violations = (out["interventions"], out["passed"],
                                         out["violations"])
    min_clear, x = out["min_clear"], out["x"]
    steered = {}
    if args.steered_steps > 0:
        st = run(True, args.steered_steps)
        steered = {
            "steps": args.steered_steps,
            "fallback_rate": round(st["fallbacks"] / args.steered_steps, 4),
            "fallback_kinds": dict(st["kinds"]),
            "solve_ms_median": round(float(np.median(st["a"])), 3),
            "solve_ms_p95": round(float(np.percentile(st["a"], 95)), 3),
            "cpu_ms_p95": round(float(np.percentile(st["cpu_ms"], 95)), 3),
            "violations": int(st["violations"]),
            "min_clearance_m": round(float(st["min_clear"]), 3),
            "distance_north_m": round(float(st["x"][0]), 2),
        }
    print(json.dumps({
        "backend": psf.backend.name,
        "config": args.config,
        "N": cfg.N,
        "dt_s": cfg.dt_s,
        "n_obstacles": n_static + n_moving,
        "n_moving": n_moving,
        "steps": args.steps,
        "solve_ms_median": round(float(np.median(a)), 3),
        "solve_ms_p95": round(float(np.percentile(a, 95)), 3),
        "solve_ms_max": round(float(a.max()), 3),
        "cpu_ms_median": round(float(np.median(cpu_ms)), 3),
        "cpu_ms_p95": round(float(np.percentile(cpu_ms, 95)), 3),
        "load_average_1min": round(os.getloadavg()[0], 1),
        "backend_ms_median": round(float(np.median(b)), 3),
        "backend_ms_p95": round(float(np.percentile(b, 95)), 3),
        "fallbacks": int(fallbacks),
        "fallback_rate": round(fallbacks / args.steps, 4),
        "fallback_kinds": dict(kinds),
        "interventions": int(interventions),
        "passed_through": int(passed),
        "violations": int(violations),
        "min_clearance_m": round(float(min_clear), 3),
        "d_safe_m": psf.d_safe_m,
        "distance_north_m": round(float(x[0]), 2),
        "build_s": round(build_s, 2),
        "steered": steered,
    }), file=stdout)


def main() -> None:
    """Run; native solver prints (acados' "QP solver returned error status 3") go to
    stderr, so stdout holds the one JSON object."""
    from asvtwin.cli.run import native_stdout_to_stderr

    with native_stdout_to_stderr() as out:
        _main(out)


if __name__ == "__main__":
    main()
