"""The tracker's outputs on a seeded many-target scene, against a recording.

The recording (``data/tracker_ticks.npz``) was made with the tracker as it was before its
tick was made faster (kernels fused, fewer numpy calls on small arrays: docs/tracking.md,
"Speed"). A speed-up must not change a track: ids, MMSIs and statuses equal, means and
covariances to 1e-12 relative. A deliberate change of the tracker's behaviour records it
again: ``ASVTWIN_RECORD_TRACKER=1 pytest tests/tracking/test_tick_regression.py``, and the
commit says why the tracks changed.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import AisMeasurementBatch, Tracker

RECORDING = Path(__file__).parent / "data" / "tracker_ticks.npz"
TICKS = 24
KEEP = (5, 11, 17, 23)  # ticks whose snapshots are recorded


def _run() -> dict[str, np.ndarray]:
    """120 vessels 80-700 m around a stationary own ship (some in close pairs), a 1800-ray
    scan per second, AIS (5 m noise) from two vessels in three, each report missing one
    tick in four."""
    rng = np.random.default_rng(20261130)
    n = 120
    r, b = rng.uniform(80.0, 700.0, n), rng.uniform(-np.pi, np.pi, n)
    pos = np.column_stack([r * np.cos(b), r * np.sin(b)])
    pos[1::10] = pos[0::10] + rng.normal(0.0, 1.0, (n // 10, 2)) + [25.0, 0.0]  # close pairs
    heading, speed = rng.uniform(-np.pi, np.pi, n), rng.uniform(0.0, 5.0, n)
    heading[1::10], speed[1::10] = heading[0::10], speed[0::10]
    vel = speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    L = rng.uniform(15.0, 60.0, n)
    has_ais = np.arange(n) % 3 != 2
    lidar = Lidar(LidarConfig(n_rays=1800, max_range_m=800.0))
    tracker = Tracker()
    out: dict[str, np.ndarray] = {}
    for k in range(TICKS):
        t = float(k)
        p = pos + vel * t
        states = np.column_stack([p, heading, speed, np.zeros((n, 2))])
        scan = lidar.scan(np.zeros(6), states, L, L / 4, None, rng, t_s=t)
        send = has_ais & (rng.uniform(size=n) > 0.25)
        noisy = p[send] + rng.normal(0.0, 5.0, (int(send.sum()), 2))
        ais = AisMeasurementBatch(200000000 + np.flatnonzero(send), np.full(int(send.sum()), t), noisy[:, 0],
                                  noisy[:, 1], speed[send], heading[send])
        snap = tracker.step(t, scan, ais)
        if k in KEEP:
            out[f"ids_{k}"] = snap.ids.copy()
            out[f"mmsi_{k}"] = np.array([-1 if m is None else m for m in snap.mmsi], np.int64)
            out[f"status_{k}"] = np.array(snap.status)
            for name in ("mean", "cov", "semi_axes_m", "lidar_only_mean", "ais_only_mean"):
                out[f"{name}_{k}"] = np.asarray(getattr(snap, name)).copy()
            out[f"updated_{k}"] = np.column_stack([snap.updated_lidar, snap.updated_ais])
    out["counters"] = np.array(sorted(tracker.counters.items()), dtype=object).astype(str)
    return out


def test_tracks_equal_the_recording() -> None:
    got = _run()
    if os.environ.get("ASVTWIN_RECORD_TRACKER", "") not in ("", "0"):
        RECORDING.parent.mkdir(exist_ok=True)
        np.savez_compressed(RECORDING, **got)
    ref = np.load(RECORDING)
    assert set(ref.files) == set(got)
    n_tracks = 0
    for key in ref.files:
        want, have = ref[key], got[key]
        assert want.shape == have.shape, key
        if want.dtype.kind == "f":
            scale = np.nanmax(np.abs(want)) if np.isfinite(want).any() else 1.0
            np.testing.assert_allclose(have, want, rtol=1e-12, atol=1e-12 * scale, equal_nan=True, err_msg=key)
        else:
            np.testing.assert_array_equal(have, want, err_msg=key)
        if key.startswith("ids_"):
            n_tracks += want.size
    assert n_tracks > 200  # the scene has tracks to compare (about 100 per recorded tick)
