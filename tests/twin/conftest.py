"""Shared scenarios of the twin's tests: open water in the Trondheim Fjord, three targets
(class A, class B, and one without AIS) within LiDAR range, low rates to keep tests quick."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from asvtwin.scenarios import Scenario
from asvtwin.twin import RunSummary, Twin

BASE: dict[str, Any] = {
    "name": "twin_test",
    "scene": "trondheim",
    "start_time_utc": "2024-11-20T11:00:00Z",
    "duration_s": 60.0,
    "seed": 3,
    "own_ship": {
        "vessel": "cybership2_full_scale",
        "start": {"north_m": 3000.0, "east_m": -1500.0},
        "heading_deg": 315.0, "speed_kn": 4.0, "cruise_speed_kn": 4.5,
        "controller": "los",
        "route": [{"north_m": 4500.0, "east_m": -3000.0}, {"north_m": 5500.0, "east_m": -4000.0}],
    },
    "targets": [
        {"name": "ALPHA", "mmsi": 257000001, "ais_class": "A", "vessel_type": "cargo",
         "length_m": 80.0, "beam_m": 14.0, "start": {"north_m": 3350.0, "east_m": -1650.0},
         "heading_deg": 135.0, "speed_kn": 5.0, "behaviour": {"kind": "constant_velocity"}},
        {"name": "BRAVO", "mmsi": 257000002, "ais_class": "B", "vessel_type": "pleasure",
         "length_m": 20.0, "beam_m": 5.0, "start": {"north_m": 2800.0, "east_m": -1250.0},
         "heading_deg": 0.0, "speed_kn": 4.0, "behaviour": {"kind": "constant_velocity"}},
        {"name": "CHARLIE", "mmsi": None, "ais_class": None, "vessel_type": "fishing",
         "length_m": 30.0, "beam_m": 7.0, "start": {"north_m": 3250.0, "east_m": -1200.0},
         "heading_deg": 270.0, "speed_kn": 3.0, "behaviour": {"kind": "constant_velocity"}},
    ],
    "ais": {"mode": "synthetic"},
    "weather": {"mode": "fixture"},
    "environment": {"current_speed_m_s": 0.3, "current_to_deg": 45.0},
    "sensors": {"lidar_rays": 360, "lidar_range_m": 800.0, "lidar_noise_m": 0.1,
                "lidar_rate_hz": 2.0},
    "rates": {"sim_hz": 10.0, "tracker_hz": 2.0, "observer_hz": 5.0, "controller_hz": 5.0,
              "filter_hz": 1.0, "snapshot_hz": 1.0},
    "criteria": {"min_distance_targets_m": 50.0, "min_distance_land_m": 100.0,
                 "goal_reached": False},
}


def scenario(**changes: Any) -> Scenario:
    """The base scenario with top-level keys replaced (``own_ship__controller=...`` sets a
    nested key)."""
    d = copy.deepcopy(BASE)
    for key, value in changes.items():
        parts = key.split("__")
        cur = d
        for p in parts[:-1]:
            cur = cur[p]
        cur[parts[-1]] = value
    return Scenario.model_validate(d)


@pytest.fixture
def base_scenario() -> Scenario:
    return scenario()


def run_sampled(sc: Scenario, duration_s: float, **rates: float
                ) -> tuple[np.ndarray, np.ndarray, RunSummary]:
    """Run ``sc`` with the given ``rates`` keys replaced (``sim_hz=20.0``) for
    ``duration_s``: the own ship's (k, 2) and the targets' (k, n, 2) positions sampled
    every simulated second, and the run's summary."""
    d = sc.model_dump(mode="json")
    d["rates"].update(rates)
    twin = Twin(Scenario.model_validate(d))
    per_s = round(1.0 / twin.dt_s)
    own, targets = [], []
    for k in range(round(duration_s / twin.dt_s)):
        if k % per_s == 0:
            own.append(twin.world.own_state[:2].copy())
            targets.append(twin.world.target_states[:, :2].copy())
        twin.step()
    return np.asarray(own), np.asarray(targets), twin.summary()
