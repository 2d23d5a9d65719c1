"""Vessel simulation speed: batched and single-vessel stepping. Prints one JSON object.

- ``vessel_steps_per_s_batched``: 1024 CyberShip II vessels, thrusters + RK4, one
  ``BatchSimulator.step`` call per step (numba kernel).
- ``vessel_steps_per_s_single``: one vessel stepped from Python with
  ``VesselSimulator.step`` (as an RL environment calls it), including argument handling.
- ``numpy_vessel_steps_per_s_batched`` / ``_single``: the same RK4 with the vectorised numpy
  reference right-hand side (``asvtwin.vessel.model.rhs``), for the numba-vs-numpy choice.

Each figure is the median over repeats after a warm-up (numba compilation excluded).
"""

from __future__ import annotations

import json
import platform
import statistics
import time

import numpy as np

from asvtwin.vessel import BatchSimulator, VesselSimulator, cybership2, rhs


def _median_rate(fn, work: int, repeats: int) -> float:
    fn()  # warm-up
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        rates.append(work / (time.perf_counter() - t0))
    return statistics.median(rates)


def main() -> dict:
    p = cybership2()
    rng = np.random.default_rng(0)
    n = 1024
    x0 = rng.normal(0, 1, (n, 6)) * [50, 50, 1, 0.2, 0.05, 0.05]
    cmd = np.tile([2.0, 0.0, 0.1], (n, 1))
    batch = BatchSimulator(p, x0, dt_s=0.1)
    steps = 200

    def run_batch():
        for _ in range(steps):
            batch.step(cmd)

    single = VesselSimulator(p, x0[0], dt_s=0.1)
    n_single = 100_000
    c1 = np.array([2.0, 0.0, 0.1])

    def run_single():
        for _ in range(n_single):
            single.step(c1)

    def rk4_numpy(x, tau, dt):
        k1 = rhs(p, x, tau)
        k2 = rhs(p, x + 0.5 * dt * k1, tau)
        k3 = rhs(p, x + 0.5 * dt * k2, tau)
        k4 = rhs(p, x + dt * k3, tau)
        return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def run_numpy_batch():
        x = x0
        for _ in range(20):
            x = rk4_numpy(x, cmd, 0.1)

    def run_numpy_single():
        x = x0[:1]
        for _ in range(2000):
            x = rk4_numpy(x, cmd[:1], 0.1)

    result = {
        "vessel_steps_per_s_batched": _median_rate(run_batch, n * steps, 7),
        "vessel_steps_per_s_single": _median_rate(run_single, n_single, 7),
        "numpy_vessel_steps_per_s_batched": _median_rate(run_numpy_batch, n * 20, 5),
        "numpy_vessel_steps_per_s_single": _median_rate(run_numpy_single, 2000, 5),
        "n_batched": n,
        "machine": platform.machine(),
        "python": platform.python_version(),
    }
    result["goal_batched_met"] = result["vessel_steps_per_s_batched"] >= 2_000_000
    result["goal_single_met"] = result["vessel_steps_per_s_single"] >= 200_000
    return result


if __name__ == "__main__":
    print(json.dumps({k: (round(v) if isinstance(v, float) else v)
                      for k, v in main().items()}))
