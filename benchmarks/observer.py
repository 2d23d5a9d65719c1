"""Benchmark of the diagnostic twin: observer speed and the injected-fault suite.

Prints one JSON object:

- ``observer_step_us``: median (and p95) wall time of one ``DisturbanceObserver.update``
  for one vessel [µs], Python call included;
- ``observer_steps_per_s_batched``: vessel-steps per second of ``update`` on 10,000
  vessels at once (median over repeats);
- ``detection_delay_s``: median delay to detect a 50 % loss of surge thrust on the
  full-scale CyberShip II under the default environment and sensor noise (40 seeded
  runs; also p95 and the fraction detected);
- ``false_alarms_per_hour``: alarms per hour of fault-free runs with the same environment
  and noise (50 h of vessel time).

The numba compile and the detector's calibration are excluded from the timings.
"""

from __future__ import annotations

import json
import time

import numpy as np

from asvtwin.observer import DisturbanceObserver
from asvtwin.observer.report import calibrate_detector, fault_suite
from asvtwin.vessel import cybership2, cybership2_full_scale


def _time_calls(fn, n: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    out = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter_ns()
        fn()
        out[i] = time.perf_counter_ns() - t0
    return out


def main() -> None:
    p = cybership2()
    rng = np.random.default_rng(0)
    # one vessel
    obs1 = DisturbanceObserver(p, 1, dt_s=0.1)
    nu1, tau1 = rng.normal(0, 0.1, (1, 3)), rng.normal(0, 1.0, (1, 3))
    obs1.update(nu1, tau1)  # warm-up (compile / load cache)
    one = _time_calls(lambda: obs1.update(nu1, tau1), 20_000) / 1e3
    # batched
    n = 10_000
    obsn = DisturbanceObserver(p, n, dt_s=0.1)
    nun, taun = rng.normal(0, 0.1, (n, 3)), rng.normal(0, 1.0, (n, 3))
    obsn.update(nun, taun)
    many = _time_calls(lambda: obsn.update(nun, taun), 300) / 1e9
    # fault suite, full scale
    full = cybership2_full_scale()
    model = calibrate_detector(full)
    t0 = time.perf_counter()
    fs = fault_suite(full, model, n_runs=40, seed=40_000, fault_free_hours=50.0)
    suite_s = time.perf_counter() - t0
    d = np.asarray(fs.delays_s)
    print(json.dumps({
        "observer_step_us": round(float(np.median(one)), 3),
        "observer_step_us_p95": round(float(np.percentile(one, 95)), 3),
        "observer_steps_per_s_batched": round(float(n / np.median(many))),
        "observer_batch_size": n,
        "detection_delay_s": round(fs.median_delay_s, 2),
        "detection_delay_s_p95": round(float(np.percentile(d[np.isfinite(d)], 95)), 2),
        "detected_fraction": fs.detected_fraction,
        "fault_runs": len(d),
        "wrong_alarms": fs.wrong_alarms,
        "false_alarms_per_hour": round(fs.false_alarms_per_hour, 4),
        "false_alarms": fs.false_alarms,
        "fault_free_hours": round(fs.fault_free_hours, 2),
        "glr_threshold": round(fs.threshold, 2),
        "kappa": [round(k, 3) for k in model.kappa],
        "fault_suite_wall_s": round(suite_s, 2),
    }))


if __name__ == "__main__":
    main()
