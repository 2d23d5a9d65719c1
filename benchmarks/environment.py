"""Cost of the current's disturbance force, before and after it used the vessel kernel.

Before: C(ν) and D(ν) built as (n, 3, 3) numpy arrays for ν and ν_r every call (the
reference model's ``coriolis``/``damping``, as ``environment.forces.current_force`` did).
After: one compiled pass calling the vessel kernel's n(ν) = C(ν)ν + D(ν)ν twice per vessel.
For scale: one step of one vessel in ``VesselSimulator`` (thrusters + RK4).

Prints one JSON object; times are medians over repeats [µs per call] measured in one run,
interleaved, on a shared machine (absolute numbers are noisy, ratios less so).
"""

from __future__ import annotations

import json
import statistics
import time

import numpy as np

from asvtwin.environment import current_force
from asvtwin.vessel import VesselSimulator, cybership2_full_scale
from asvtwin.vessel.model import coriolis, damping


def numpy_current_force(params, x, vc):  # the former implementation, for comparison
    x = np.atleast_2d(np.asarray(x, dtype=float))
    vc = np.broadcast_to(np.asarray(vc, dtype=float), (x.shape[0], 2))
    c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
    nu = x[:, 3:6]
    nu_r = nu.copy()
    nu_r[:, 0] -= c * vc[:, 0] + s * vc[:, 1]
    nu_r[:, 1] -= -s * vc[:, 0] + c * vc[:, 1]

    def hydro(n):
        return np.einsum("nij,nj->ni", coriolis(params, n) + damping(params, n), n)

    return hydro(nu) - hydro(nu_r)


def _us(fn, number: int) -> float:
    t0 = time.perf_counter()
    for _ in range(number):
        fn()
    return (time.perf_counter() - t0) / number * 1e6


def main() -> None:
    p = cybership2_full_scale()
    rng = np.random.default_rng(0)
    out: dict[str, float | int | str] = {}
    for n in (1, 100):
        x = np.column_stack([rng.normal(0, 100, (n, 2)), rng.uniform(-3, 3, n),
                             rng.uniform(0, 5, n), rng.normal(0, 0.3, n),
                             rng.normal(0, 0.02, n)])
        vc = np.array([0.5, -0.2])
        np.testing.assert_allclose(current_force(p, x, vc), numpy_current_force(p, x, vc),
                                   rtol=1e-10, atol=1e-6)
        before, after = [], []
        for _ in range(15):
            before.append(_us(lambda x=x, vc=vc: numpy_current_force(p, x, vc), 300))
            after.append(_us(lambda x=x, vc=vc: current_force(p, x, vc), 300))
        out[f"current_force_before_us_n{n}"] = round(statistics.median(before), 2)
        out[f"current_force_after_us_n{n}"] = round(statistics.median(after), 2)
        out[f"speedup_n{n}"] = round(statistics.median(before) / statistics.median(after), 1)
    sim = VesselSimulator(p, [0, 0, 0, 4.0, 0, 0], dt_s=0.1)
    cmd = np.array([3e5, 0.0, 1e6])
    sim.step(cmd)
    out["vessel_step_us"] = round(statistics.median(_us(lambda: sim.step(cmd), 300)
                                                    for _ in range(15)), 2)
    out["note"] = "median us per call; shared 2-core machine, absolute times noisy"
    print(json.dumps(out))


if __name__ == "__main__":
    main()
