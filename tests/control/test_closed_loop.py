"""Adversarial closed loops: full thrust at an obstacle, a coast, a crossing vessel.

By default a real subset runs (20 seeded scenarios on acados, 3 on IPOPT, whose solves
are ~25x slower); ASVTWIN_FULL=1 runs all 200 (the ``slow`` test).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from asvtwin.control.closed_loop import SCENARIO_KINDS, adversarial_scenario, run_closed_loop

FULL = os.environ.get("ASVTWIN_FULL") == "1"


def _check(params, psf, seeds, tol_m=0.0):
    starts_feasible = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        kind = SCENARIO_KINDS[seed % 3]
        scene = adversarial_scenario(rng, kind, n_clutter=int(rng.integers(0, 6)))
        free = run_closed_loop(params, scene, None, mode="unfiltered")
        # the test can fail: without the filter the naive controller violates d_safe
        assert free.min_clearance_m < psf.d_safe_m, (seed, kind, free.min_clearance_m)
        run = run_closed_loop(params, scene, psf)
        first = run.results[0]
        if first.obstacle_margin_m[0] < 0:
            continue  # started inside d_safe: no claim
        starts_feasible += 1
        # zero closed-loop violations of d_safe on the simulator (thruster lag included),
        # less ``tol_m``
        assert run.min_clearance_m >= psf.d_safe_m - tol_m, (seed, kind, run.min_clearance_m)
        assert all(r.fallback != "none" or r.success for r in run.results)
        assert not any(np.allclose(r.u0, [2.0, 0, 0]) and r.fallback != "none"
                       for r in run.results)
    assert starts_feasible == len(seeds)


def test_adversarial_subset(params, psf):
    # the certification's tolerance, as in the study of 200: with the defaults of
    # 2026-12-07 (the lag model, the comfort pass-through) seed 1004 comes 0.5 mm inside
    # d_safe behind certified plans (docs/psf.md, "The comfort bound by default")
    n = 20 if psf.backend.name.startswith("acados") else 3
    _check(params, psf, range(1000, 1000 + n), tol_m=psf.certify_tol_m)


@pytest.mark.slow
@pytest.mark.skipif(not FULL, reason="set ASVTWIN_FULL=1 for the 200-scenario study")
def test_adversarial_200(params, psf):
    # the certification's tolerance (2 % of the ship length, 25 mm): since retries
    # converge (2026-12-07) one of the 200 (seed 2084, a crossing) came 10 mm inside
    # d_safe behind plans certified within it, with 78 fallbacks in all instead of 271
    # (docs/psf.md, "Random encounters"); with the lag model and the comfort
    # pass-through (the defaults since, third session) one, seed 2024, 1.5 mm inside,
    # 142 fallbacks (docs/psf.md, "The comfort bound by default")
    _check(params, psf, range(2000, 2200), tol_m=psf.certify_tol_m)
