"""Simulated scenes for the tracker tests: CV targets, own ship, LiDAR, AIS."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from asvtwin.geo import LandMask
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import AisMeasurement, Tracker, TrackSnapshot, assign_tracks


def jagged_coast(shore_north_m: float = 0.0, amplitude_m: float = 15.0) -> LandMask:
    """Land north of a wavy shoreline ``n = shore + A sin(e / 40 m)``, e in [-3000, 3000] m."""
    e = np.linspace(-3000.0, 3000.0, 301)
    n = shore_north_m + amplitude_m * np.sin(e / 40.0)
    ring = np.vstack([np.column_stack([n, e]), [[shore_north_m + 2000.0, 3000.0], [shore_north_m + 2000.0, -3000.0]]])
    return LandMask(Polygon(ring))


@dataclass
class Run:
    snaps: list[TrackSnapshot]
    truth: np.ndarray  # (T, m, 4)
    times: np.ndarray


def run_scene(x0: np.ndarray, length_m: np.ndarray, *, T: int = 300, dt: float = 1.0, land: LandMask | None = None,
              tracker: Tracker | None = None, ais_period_s: float = 10.0, ais_std_m: float = 5.0, seed: int = 0,
              own: np.ndarray | None = None, lidar: LidarConfig | None = None) -> Run:
    """CV targets ``x0`` (m, 4) observed from a stationary own ship for T ticks."""
    rng = np.random.default_rng(seed)
    own = np.zeros(6) if own is None else own
    sensor = Lidar(lidar or LidarConfig(n_rays=720, max_range_m=500.0))
    tr = tracker or Tracker(land=land)
    m = len(x0)
    phase = rng.uniform(0.0, ais_period_s, m)
    snaps, truth, times = [], [], []
    for k in range(T):
        t = k * dt
        x = x0.copy()
        x[:, :2] += x0[:, 2:] * t
        scan = sensor.scan(own, x, length_m, length_m / 4.0, land, rng, t_s=t)
        ais = []
        for i in range(m):
            if ais_period_s > 0 and (t - phase[i]) % ais_period_s < dt and t >= phase[i]:
                p = x[i, :2] + rng.normal(0.0, ais_std_m, 2)
                ais.append(AisMeasurement(257000000 + i, t, float(p[0]), float(p[1]), float(np.hypot(*x[i, 2:])),
                                          float(np.arctan2(x[i, 3], x[i, 2]))))
        snaps.append(tr.step(t, scan, ais))
        truth.append(x)
        times.append(t)
    return Run(snaps, np.array(truth), np.array(times))


def errors(run: Run, *, gate_m: float = 50.0, start: int = 30, field: str = "mean",
           mask: np.ndarray | None = None) -> np.ndarray:
    """Position errors (rows: step, target) of the track following each target (NaN where none)."""
    out = np.full(run.truth.shape[:2], np.nan)
    for k in range(start, len(run.snaps)):
        s = run.snaps[k].confirmed()
        if len(s) == 0:
            continue
        ids = assign_tracks(s.mean[:, :2], s.ids, run.truth[k, :, :2], gate_m=gate_m)
        for j, tid in enumerate(ids):
            if tid < 0 or (mask is not None and not mask[k, j]):
                continue
            est = getattr(s, field)[np.flatnonzero(s.ids == tid)[0], :2]
            out[k, j] = np.hypot(*(est - run.truth[k, j, :2]))
    return out
