"""Simulated scenes for the tracker tests: CV targets, own ship, LiDAR, AIS."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from asvtwin.geo import LandMask
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import AisMeasurement, Tracker, TrackSnapshot, assign_tracks

#: Duration of the seeded benchmark scenes [s].
T_SCENE_S = 300


def _clear(x: np.ndarray, L: np.ndarray) -> bool:
    """Whether vessel ``x[-1]`` keeps clear over the run of the others (centres never closer
    than the half-lengths plus 30 m) and of the own ship at the origin (its half-length plus
    50 m: the LiDAR's near field, where a hull fills a wide sector, is a separate study)."""
    t = np.arange(0.0, T_SCENE_S + 1.0, 5.0)
    p = x[:, None, :2] + x[:, None, 2:] * t[None, :, None]
    d = np.hypot(*(p[:-1] - p[-1]).transpose(2, 0, 1))
    own = np.hypot(*p[-1].T).min()
    return bool((d.min(axis=1) > 0.5 * (L[:-1] + L[-1]) + 30.0).all() and own > 0.5 * L[-1] + 50.0)


def _draw(rng: np.random.Generator, m: int, one) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    xs, Ls = np.empty((0, 4)), np.empty(0)
    while len(xs) < m:
        x, L = one(rng), rng.uniform(15.0, 60.0)
        cand, cl = np.vstack([xs, x]), np.append(Ls, L)
        if _clear(cand, cl):
            xs, Ls = cand, cl
    return xs, Ls


def open_sea_vessels(seed: int, m: int = 6) -> tuple[np.ndarray, np.ndarray]:
    def one(rng: np.random.Generator) -> np.ndarray:
        r, b = rng.uniform(80.0, 350.0), rng.uniform(-np.pi, np.pi)
        sp, c = rng.uniform(0.5, 4.0), rng.uniform(-np.pi, np.pi)
        # in view all run: the drawn point is where it is at mid-run
        x = np.array([r * np.cos(b), r * np.sin(b), sp * np.cos(c), sp * np.sin(c)])
        x[:2] -= x[2:] * 0.5 * T_SCENE_S
        return x

    return _draw(np.random.default_rng(1000 + seed), m, one)


def coastal_vessels(seed: int, m: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vessels 100-190 m off a shore at north = +450 m, running along it; own ship at the
    origin (350 m off)."""
    def one(rng: np.random.Generator) -> np.ndarray:
        sp = rng.uniform(0.5, 3.0) * rng.choice([-1.0, 1.0])
        return np.array([450.0 - rng.uniform(100.0, 190.0), rng.uniform(-250.0, 250.0) - sp * 0.5 * T_SCENE_S, 0.0, sp])

    x0, L = _draw(np.random.default_rng(2000 + seed), m, one)
    return x0, L, np.ones(m, bool)


def vessel_pairs(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Four pairs 30 m apart: abreast, in column, crossing (at right angles, the second
    passing 30 m astern of the first: closest point of approach 30 m), overtaking."""
    rng = np.random.default_rng(3000 + seed)
    rows = []
    base = [(-200.0, -250.0), (150.0, -250.0), (-150.0, 150.0), (200.0, 150.0)]
    for kind, (n0, e0) in zip(("abreast", "column", "crossing", "overtaking"), base):
        v = rng.uniform(1.0, 2.5)
        if kind == "abreast":
            rows += [[n0, e0, 0.0, v], [n0 + 30.0, e0, 0.0, v]]
        elif kind == "column":
            rows += [[n0, e0, 0.0, v], [n0, e0 - 30.0 - 25.0, 0.0, v]]
        elif kind == "crossing":  # tracks cross at (n0, e0 + v T/2), 90° apart; the second
            # reaches it 30√2 m later: CPA 30 m (a crossing that meets at one point is a collision)
            mid = np.array([n0, e0 + v * 0.5 * T_SCENE_S])
            rows += [[n0, e0, 0.0, v], [mid[0] - v * 0.5 * T_SCENE_S - 30.0 * np.sqrt(2.0), mid[1], v, 0.0]]
        else:  # the second overtakes the first 30 m abeam
            rows += [[n0, e0, 0.0, v], [n0 + 30.0, e0 - 0.5 * T_SCENE_S * 0.6, 0.0, v + 0.6]]
    x0 = np.array(rows)
    ais = np.tile([True, False], len(rows) // 2)
    return x0, rng.uniform(15.0, 30.0, len(rows)), ais


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
              own: np.ndarray | None = None, lidar: LidarConfig | None = None,
              ais_mask: np.ndarray | None = None, sensor_land: LandMask | None = None,
              beam_m: np.ndarray | None = None) -> Run:
    """CV targets ``x0`` (m, 4) observed from a stationary own ship for T ticks.

    ``ais_mask`` (m,) selects the targets that transmit AIS (MMSI ``257000000 + i``);
    ``sensor_land`` is the coast the LiDAR sees when it differs from the tracker's
    ``land`` (an imperfect chart); ``beam_m`` defaults to a quarter of the length."""
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
        scan = sensor.scan(own, x, length_m, length_m / 4.0 if beam_m is None else beam_m,
                           land if sensor_land is None else sensor_land, rng, t_s=t)
        ais = []
        for i in range(m):
            if ais_mask is not None and not ais_mask[i]:
                continue
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


def mmsi_swaps(run: Run, ais_mask: np.ndarray, *, gate_m: float = 50.0, start: int = 0) -> int:
    """Times an MMSI appears on a confirmed track that follows a different target (onsets:
    a run of consecutive steps counts once; a wrong tie present at step ``start`` counts)."""
    swaps, prev = 0, set()
    for k, snap in enumerate(run.snaps[start:], start):
        s = snap.confirmed()
        cur = set()
        if len(s):
            ids = assign_tracks(s.mean[:, :2], s.ids, run.truth[k, :, :2], gate_m=gate_m)
            for j, tid in enumerate(ids):
                if tid < 0:
                    continue
                mm = s.mmsi[int(np.flatnonzero(s.ids == tid)[0])]
                if mm is not None and mm != 257000000 + j:
                    cur.add((mm, j))
        swaps += len(cur - prev)
        prev = cur
    return swaps
