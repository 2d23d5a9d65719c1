"""Benchmark of the tracking chain; prints one JSON object.

- ``ellipse_fit_us``: one Halir–Flusser fit (:func:`asvtwin.tracking.fit_ellipse`) of a
  100-point noisy cluster (10 × 3 m ellipse, 5 cm noise, at fjord-scale coordinates);
  also the MLR fit and the per-cluster cost of the batched fit over 200 clusters.
- ``lidar_scan_ms``: one 360-ray scan against 50 targets and the Trondheim Fjord coast
  (default scene), own ship near the shore.
- ``tracker_tick_ms``: one whole :meth:`asvtwin.tracking.Tracker.step` (scan clustering,
  ellipse fits, measurement models, association, AIS, fusion, track management, snapshot)
  with 200 targets, a 3600-ray scan (already cast) and 200 AIS reports, after the tracks
  are established. The AIS reports come as columns (:class:`AisMeasurementBatch`,
  ``"ais_input": "arrays"``); ``tracker_tick_list_ms`` is the same tick with the reports
  as a list of :class:`AisMeasurement` objects (a second tracker fed the same ticks,
  checked to give the same tracks). ``tracker_tick_cpu_ms``: the headline tick in process
  CPU time (on a machine shared with other jobs the wall-clock tick includes waiting for a
  core; the goal is on the wall-clock tick of a quiet machine).

Warm-up (numba compilation, first calls) is excluded; medians and p95 of repeats.
Run: ``python benchmarks/tracking.py``.
"""

from __future__ import annotations

import json
import time

import numpy as np

from asvtwin.geo import default_scene
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import (
    AisMeasurement,
    AisMeasurementBatch,
    Tracker,
    TrackSnapshot,
    fit_ellipse,
    fit_ellipses,
)


def _stats(samples: list[float], scale: float) -> tuple[float, float]:
    a = np.asarray(samples) * scale
    return round(float(np.median(a)), 3), round(float(np.percentile(a, 95)), 3)


def _repeat(fn, n: int, inner: int = 1) -> list[float]:  # type: ignore[no-untyped-def]
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        out.append((time.perf_counter() - t0) / inner)
    return out


def bench_ellipse(rng: np.random.Generator) -> dict[str, float]:
    t = rng.uniform(0.0, 2.0 * np.pi, 100)
    c, s = np.cos(0.6), np.sin(0.6)
    pts = np.column_stack([5.0 * np.cos(t), 1.5 * np.sin(t)]) @ np.array([[c, s], [-s, c]])
    pts += np.array([6200.0, -3400.0]) + rng.normal(0.0, 0.05, pts.shape)
    for _ in range(5):
        fit_ellipse(pts)
        fit_ellipse(pts, method="mlr")
    hf = _repeat(lambda: fit_ellipse(pts), 200, 20)
    mlr = _repeat(lambda: fit_ellipse(pts, method="mlr"), 200, 20)
    many = np.tile(pts[:20], (200, 1))
    off = np.arange(201) * 20
    fit_ellipses(many, off)
    batch = _repeat(lambda: fit_ellipses(many, off), 50)
    m, p = _stats(hf, 1e6)
    mm, mp = _stats(mlr, 1e6)
    return {"ellipse_fit_us": m, "ellipse_fit_us_p95": p, "ellipse_fit_mlr_us": mm, "ellipse_fit_mlr_us_p95": mp,
            "ellipse_fit_batched_20pt_us_per_cluster": _stats(batch, 1e6 / 200)[0]}


def _targets(rng: np.random.Generator, n: int, centre: np.ndarray, r_min: float, r_max: float, land) -> np.ndarray:  # type: ignore[no-untyped-def]
    out: list[list[float]] = []
    for _ in range(1000 * n):
        if len(out) == n:
            break
        r, b = rng.uniform(r_min, r_max), rng.uniform(-np.pi, np.pi)
        p = centre + r * np.array([np.cos(b), np.sin(b)])
        if land is not None and (land.contains(p[None])[0] or land.distance_to_shore(p[None])[0] < 30.0):
            continue
        if out and np.min(np.hypot(*(np.array(out)[:, :2] - p).T)) < 40.0:
            continue
        out.append([p[0], p[1], rng.uniform(-np.pi, np.pi), rng.uniform(0.0, 5.0), 0.0, 0.0])
    if len(out) < n:
        raise RuntimeError(f"could only place {len(out)} of {n} targets on water")
    return np.array(out)


def bench_lidar(rng: np.random.Generator) -> dict[str, float]:
    land = default_scene().land
    own = np.array([-250.0, -1750.0, 0.3, 0.0, 0.0, 0.0])  # on water, ~320 m from the shore
    tg = _targets(rng, 50, own[:2], 60.0, 450.0, land)
    L = rng.uniform(10.0, 80.0, 50)
    lidar = Lidar(LidarConfig(n_rays=360, max_range_m=500.0))
    for _ in range(3):
        scan = lidar.scan(own, tg, L, L / 4, land, rng)
    runs = _repeat(lambda: lidar.scan(own, tg, L, L / 4, land, rng), 200)
    m, p = _stats(runs, 1e3)
    return {"lidar_scan_ms": m, "lidar_scan_ms_p95": p, "lidar_coast_returns": int((scan.hit_id == -2).sum()),
            "lidar_target_returns": int((scan.hit_id >= 0).sum())}


def bench_tracker(rng: np.random.Generator, n: int = 200, warm: int = 12, timed: int = 30) -> dict[str, float | str]:
    own = np.zeros(6)
    tg = _targets(rng, n, own[:2], 80.0, 950.0, None)
    L = rng.uniform(15.0, 60.0, n)
    vel = tg[:, 3:4] * np.column_stack([np.cos(tg[:, 2]), np.sin(tg[:, 2])])
    lidar = Lidar(LidarConfig(n_rays=3600, max_range_m=1000.0))
    mmsi = 200000000 + np.arange(n, dtype=np.int64)
    # two trackers fed the same ticks: AIS as columns (the headline) and as report objects
    tracker, tracker_list = Tracker(), Tracker()
    ticks: list[float] = []
    ticks_list: list[float] = []
    cpu: list[float] = []  # process CPU time of the headline tick (robust on a shared machine)
    snaps: dict[int, TrackSnapshot] = {}
    for k in range(warm + timed):
        t = float(k)
        pos = tg[:, :2] + vel * t
        states = np.column_stack([pos, tg[:, 2], tg[:, 3], np.zeros((n, 2))])
        scan = lidar.scan(own, states, L, L / 4, None, rng, t_s=t)
        noisy = pos + rng.normal(0.0, 5.0, pos.shape)
        ais = [AisMeasurement(int(mmsi[i]), t, float(noisy[i, 0]), float(noisy[i, 1]), float(tg[i, 3]), float(tg[i, 2]))
               for i in range(n)]
        batch = AisMeasurementBatch(mmsi, np.full(n, t), noisy[:, 0], noisy[:, 1], tg[:, 3], tg[:, 2])
        runs: list[tuple[Tracker, list[float], AisMeasurementBatch | list[AisMeasurement]]] = [
            (tracker, ticks, batch), (tracker_list, ticks_list, ais)]
        for trk, out, reports in runs if k % 2 else runs[::-1]:  # alternate who meets the scan first
            t0, c0 = time.perf_counter(), time.process_time()
            snaps[id(trk)] = trk.step(t, scan, reports)  # the whole tick: clustering ... snapshot
            out.append(time.perf_counter() - t0)
            if trk is tracker:
                cpu.append(time.process_time() - c0)
    snap, snap_list = snaps[id(tracker)], snaps[id(tracker_list)]
    if not (np.array_equal(snap.mean, snap_list.mean) and snap.mmsi == snap_list.mmsi):
        raise RuntimeError("AIS as arrays and as objects gave different tracks")
    m, p = _stats(ticks[warm:], 1e3)
    ml, pl = _stats(ticks_list[warm:], 1e3)
    mc, pc = _stats(cpu[warm:], 1e3)
    return {"tracker_tick_ms": m, "tracker_tick_ms_p95": p, "tracker_tick_cpu_ms": mc, "tracker_tick_cpu_ms_p95": pc,
            "ais_input": "arrays",
            "tracker_tick_list_ms": ml, "tracker_tick_list_ms_p95": pl, "tracker_targets": n,
            "tracker_confirmed_tracks": int(snap.is_confirmed.sum()),
            "tracker_lidar_updated_tracks": int(snap.updated_lidar.sum())}


def main() -> None:
    rng = np.random.default_rng(2024)
    out: dict[str, float | str] = {}
    out.update(bench_ellipse(rng))
    out.update(bench_lidar(rng))
    out.update(bench_tracker(rng))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
