"""The safety filter through the classic encounter set; prints one JSON object.

Runs every case of :func:`asvtwin.control.encounters.encounter_cases` (22 vessel
encounters with 1-3 targets, a head-on followed by 100 m of open water, 2 coast
approaches including a harbour with piers, 2 sudden rocks) with a path-following learner (LOS + autopilot) through the filter, for each
requested hull scale and backend, and the same cases unfiltered as the control.

Keys: ``collisions``, ``groundings`` (sums over every filtered run), ``min_distance_m``
(closest approach to any vessel or rock, from the own ship's origin to the obstacle's
edge), ``min_distance_ratio`` (that over d_safe), ``min_distance_land_m``, ``fallbacks``
(by kind), ``fallback_rate`` (per call), ``starboard_share`` (of the runs where COLREG
expects an alteration to starboard and the ship manoeuvred),
``fallback_sides_where_starboard_expected`` (the fallbacks applied in those runs, by the
side their plan goes: starboard, port, straight), ``goal_reached`` (of the runs
where the goal is reachable), ``open_water_intervention_share`` (of the calls with
nothing within 15 ship lengths, those where the filter changed u_L),
``open_water_turning_interventions`` (a learner holding 30 % and then 100 % of the yaw
moment with nothing to avoid, 200 calls each: the calls where the filter changed u_L;
the hull turns at 2.5-2.8 ν_max,r under it, and that is the learner's business),
``yaw_rate_max_avoidance_ratio`` per setting (the largest |r| while a changed input was
applied, over the comfort bound ν_max,r; ``yaw_rate_max_fallback_ratio`` the same while
a fallback manoeuvre was applied; ``avoidance_above_comfort_cases`` the cases whose
avoidance turned faster than the filter's own comfort tolerance,
1.05 ν_max,r; ``yaw_rate_max_steered_ratio`` and ``steered_above_comfort_cases`` the
same leaving out the moments when the applied yaw moment opposed the turn at full
strength: the yaw the filter steered into, not a turn the hull kept up against all its
thrusters could do), ``failed_cases`` per setting (collided, grounded, or closer than
0.95 d_safe), ``unfiltered_collisions``, per-setting breakdowns, and the
median filter call time [ms].

``--random K [--random-seed S]`` runs K random vessel encounters
(:func:`asvtwin.control.encounters.random_vessel_cases`) instead of the set: cases
nobody chose, for the filter's behaviour where it was not looked at.

Usage: ``python benchmarks/psf_encounters.py [--backend acados,casadi-ipopt]
[--scale model,full] [--cases all|NAME,...] [--config default|comfort|twin|twin-comfort]
[--random K [--random-seed S]]``
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter

import numpy as np

from asvtwin.control import PsfConfig, SafetyFilter, available_backends, comfort_config
from asvtwin.control.encounters import (
    encounter_cases,
    random_vessel_cases,
    run_encounter,
    run_open_water_turning,
)
from asvtwin.control.psf import COMFORT_TOL
from asvtwin.vessel import cybership2, cybership2_full_scale


def _main(stdout) -> None:  # type: ignore[no-untyped-def]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default=available_backends()[0],
                    help="comma-separated backends (default: the fastest installed)")
    ap.add_argument("--scale", default="model,full",
                    help="model, full, or both (comma-separated: model,full)")
    ap.add_argument("--cases", default="all", help="all, or comma-separated case names")
    ap.add_argument("--config", default="default",
                    choices=("default", "comfort", "twin", "twin-comfort"),
                    help="the filter's options: PsfConfig's defaults, "
                         "asvtwin.control.comfort_config(), the twin's "
                         "(asvtwin.twin.components.twin_filter_config), or the twin's "
                         "with its comfort options (comfort=True)")
    ap.add_argument("--random", type=int, default=0, metavar="K",
                    help="instead of the set, K random vessel encounters "
                         "(asvtwin.control.encounters.random_vessel_cases)")
    ap.add_argument("--random-seed", type=int, default=1, metavar="S",
                    help="the random encounters' seed (default 1)")
    args = ap.parse_args()
    if args.random < 0:
        ap.error(f"--random must be >= 0, actually: {args.random}")
    cases = (random_vessel_cases(args.random, args.random_seed) if args.random
             else encounter_cases())
    if args.cases != "all":
        names = set(args.cases.split(","))
        cases = [c for c in cases if c.name in names]
    hulls = {"model": cybership2, "full": cybership2_full_scale}
    runs, settings = [], {}
    turning = [0, 0]  # open-water turning learner: interventions, calls
    unfiltered = 0
    t0 = time.perf_counter()
    scales = ["model", "full"] if args.scale == "both" else args.scale.split(",")
    if bad := [s for s in scales if s not in hulls]:
        ap.error(f"--scale: unknown {', '.join(bad)}; expected model, full or both")
    for scale in scales:
        params = hulls[scale]()
        for c in cases:
            unfiltered += run_encounter(c, params, None).collisions
        for backend in args.backend.split(","):
            if args.config.startswith("twin"):
                from asvtwin.twin.components import twin_filter_config
                config = twin_filter_config(backend, comfort=args.config == "twin-comfort")
            else:
                config = (comfort_config(backend=backend) if args.config == "comfort"
                          else PsfConfig(backend=backend))
            psf = SafetyFilter(params, config=config)
            d_safe = psf.d_safe_m
            rs = []
            for c in cases:
                r = run_encounter(c, params, psf)
                rs.append(r)
                print(f"{scale:5s} {backend:12s} {c.name:45s} min {r.min_distance_m / d_safe:6.2f}"
                      f" d_safe, land {r.min_distance_land_m / d_safe:6.2f}, coll {r.collisions},"
                      f" goal {r.goal_reached}, fb {r.fallbacks} sides {r.fallback_sides},"
                      f" stb {r.starboard}",
                      file=sys.stderr, flush=True)
            fb = Counter()
            for r in rs:
                fb.update(r.fallbacks)
            calls = sum(r.calls for r in rs)
            name = f"{scale}/{psf.backend.name}" + (
                "" if args.config == "default" else f"/{args.config}")
            settings[name] = {
                "collisions": sum(r.collisions for r in rs),
                "groundings": sum(r.groundings for r in rs),
                "min_distance_ratio": round(min(r.min_distance_m for r in rs) / d_safe, 4),
                "fallback_rate": round(sum(fb.values()) / max(calls, 1), 4),
                "goal_reached": f"{sum(r.goal_reached for r in rs if r.goal_expected)}/"
                                f"{sum(r.goal_expected for r in rs)}",
                "starboard": f"{sum(bool(r.starboard) for r in rs)}/"
                             f"{sum(r.starboard is not None for r in rs)}",
                "min_distance_land_ratio": round(min(r.min_distance_land_m for r in rs)
                                                 / d_safe, 4),
                "open_water_interventions": f"{sum(r.open_water_interventions for r in rs)}/"
                                            f"{sum(r.open_water_calls for r in rs)}",
                "yaw_rate_max_avoidance_ratio": round(max(
                    r.yaw_rate_max_avoidance for r in rs) / float(psf.nu_max[2]), 3),
                "yaw_rate_max_fallback_ratio": round(max(
                    r.yaw_rate_max_fallback for r in rs) / float(psf.nu_max[2]), 3),
                "avoidance_above_comfort_cases": sum(
                    r.yaw_rate_max_avoidance > (1.0 + COMFORT_TOL) * float(psf.nu_max[2])
                    for r in rs),
                "yaw_rate_max_steered_ratio": round(max(
                    r.yaw_rate_max_steered for r in rs) / float(psf.nu_max[2]), 3),
                "steered_above_comfort_cases": sorted(
                    r.name for r in rs
                    if r.yaw_rate_max_steered > (1.0 + COMFORT_TOL) * float(psf.nu_max[2])),
                # the cases that collided, grounded or came closer than 0.95 d_safe
                "failed_cases": sorted(
                    r.name for r in rs if r.collisions or r.groundings
                    or r.min_distance_m < 0.95 * d_safe),
                "call_ms_median": round(float(np.median(np.concatenate(
                    [r.call_ms for r in rs]))), 3),
            }
            # a learner turning hard in open water: the filter must leave it be
            ow_turn = [run_open_water_turning(params, psf, yaw_share=ys)[:2]
                       for ys in (0.3, 1.0)]
            inter, n_calls = (sum(col) for col in zip(*ow_turn, strict=True))
            settings[name]["open_water_turning_interventions"] = f"{inter}/{n_calls}"
            turning[0] += inter
            turning[1] += n_calls
            runs += [(r, d_safe) for r in rs]
    fb_all: Counter = Counter()
    for r, _ in runs:
        fb_all.update(r.fallbacks)
    calls = sum(r.calls for r, _ in runs)
    stb = [r.starboard for r, _ in runs if r.starboard is not None]
    fb_sides: Counter = Counter()  # fallbacks where COLREG expects starboard, by side
    for r, _ in runs:
        if r.starboard_expected:
            fb_sides.update(r.fallback_sides)
    print(json.dumps({
        "cases": len(cases),
        "runs": len(runs),
        "collisions": sum(r.collisions for r, _ in runs),
        "groundings": sum(r.groundings for r, _ in runs),
        "min_distance_m": round(min(r.min_distance_m for r, _ in runs), 4),
        "min_distance_ratio": round(min(r.min_distance_m / d for r, d in runs), 4),
        "min_distance_land_m": round(min(r.min_distance_land_m for r, _ in runs), 4),
        "fallbacks": dict(fb_all),
        "fallback_rate": round(sum(fb_all.values()) / max(calls, 1), 4),
        "calls": calls,
        "starboard_share": round(sum(stb) / len(stb), 3) if stb else None,
        "starboard_runs": len(stb),
        "fallback_sides_where_starboard_expected": dict(fb_sides),
        "goal_reached": f"{sum(r.goal_reached for r, _ in runs if r.goal_expected)}/"
                        f"{sum(r.goal_expected for r, _ in runs)}",
        "open_water_calls": sum(r.open_water_calls for r, _ in runs),
        "open_water_intervention_share": round(
            sum(r.open_water_interventions for r, _ in runs)
            / max(sum(r.open_water_calls for r, _ in runs), 1), 4),
        "open_water_turning_interventions": f"{turning[0]}/{turning[1]}",
        "unfiltered_collisions": unfiltered,
        "settings": settings,
        "wall_s": round(time.perf_counter() - t0, 1),
    }), file=stdout)


def main() -> None:
    """Run; native solver prints (acados' "QP solver returned error status 3") go to
    stderr, so stdout holds the one JSON object."""
    from asvtwin.cli.run import native_stdout_to_stderr

    with native_stdout_to_stderr() as out:
        _main(out)


if __name__ == "__main__":
    main()
