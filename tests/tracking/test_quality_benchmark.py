"""``benchmarks/tracking_quality.py --quick`` runs and prints the keys issue 15 names.

The full run (4 seeds per scene) is what docs/tracking.md reports; the quick run (2 seeds)
checks that the script works and that the goals that hold per seed hold here: no MMSI
swap, near-coast false tracks and RMSE within 1.5x open sea. (The NEES bounds need the
full run's samples.)"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "tracking_quality.py"


def test_quick_run_prints_every_key_with_the_goals_that_hold_per_seed():
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick"], capture_output=True,
                         text=True, timeout=300, check=True).stdout
    d = json.loads(out)
    for key in ("nees_in_bounds", "nees_open_sea", "nees_near_coast", "nees_bounds_open_sea",
                "mmsi_swaps", "coast_false_track_ratio", "coast_rmse_ratio",
                "open_sea_lost_tracks_per_h", "coast_lost_tracks_per_h"):
        assert key in d, key
    assert d["mmsi_swaps"] == 0
    assert d["coast_false_track_ratio"] <= 1.5 and d["coast_rmse_ratio"] <= 1.5
    for scene in d["scenes"].values():
        for key in ("rmse_m", "nees", "nis_lidar", "nis_ais", "id_switches",
                    "false_tracks_per_h", "lost_tracks_per_h"):
            assert np.isfinite(scene[key]), (key, scene[key])
        assert 0 <= scene["lost_tracks"] <= scene["id_switches"]  # a loss is a switch by deletion
