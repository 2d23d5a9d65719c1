"""The scenario library's encounters in the RL world: Froude conversion recomputed from
the YAML, and the no-filter line-of-sight expert meeting the head-on coaster."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.rl.library import LosExpertPolicy, evaluate_library, library_encounters
from asvtwin.rl.scenarios import N_STATIC
from asvtwin.scenarios import library_names, load_library


def test_open_water_encounters_fit_and_coastal_ones_are_named() -> None:
    encs, skipped = library_encounters()
    names = {e.name for e in encs}
    assert {"head_on", "crossing_give_way", "crossing_stand_on", "overtaking",
            "being_overtaken", "multi_vessel", "model_scale_crossing"} <= names
    assert "restricted_water" in skipped and "coast" in skipped["restricted_water"]
    assert names | set(skipped) == set(library_names())  # nothing dropped silently


def test_head_on_is_froude_scaled_from_the_yaml() -> None:
    """Recomputed by hand from head_on.yaml: own ship 4200 N → 5800 N, coaster at 6400 N
    heading 180° at 6 kn, 60 m long; s = 70 (CyberShip II is a 1:70 model)."""
    enc = {e.name: e for e in library_encounters()[0]}["head_on"]
    sc = load_library("head_on", check_scene=False)
    s = 70.0
    assert enc.scale == pytest.approx(s, rel=1e-3)
    path = enc.scenario.path
    assert path[0] == pytest.approx([0.0, 0.0])
    assert path[-1] == pytest.approx([1600.0 / s, 0.0], rel=1e-3)
    m = enc.scenario.moving[0]
    v = 6 * 1852 / 3600 / math.sqrt(s)
    assert m == pytest.approx([2200.0 / s, 0.0, -v, 0.0, 30.0 / s], rel=1e-3, abs=1e-9)
    assert enc.scenario.x0[3] == pytest.approx(4.5 * 1852 / 3600 / math.sqrt(s), rel=1e-3)
    assert enc.max_steps == math.ceil(sc.duration_s / math.sqrt(s))
    assert enc.min_distance_m == sc.criteria.min_distance_targets_m == 150


def test_expert_without_filter_runs_into_the_head_on_coaster() -> None:
    """The expert knows no obstacles: on the reciprocal track it runs into the coaster.
    Contact is the coaster's edge within half a ship length (the LiDAR's shortest ray
    against the exact circle, up to its 2° ray spacing)."""
    encs = [e for e in library_encounters()[0] if e.name in ("head_on", "overtaking")]
    res = {r.encounter: r for r in evaluate_library(LosExpertPolicy(), "ppo",
                                                    encounters=encs)}
    r = res["head_on"]
    enc = next(e for e in encs if e.name == "head_on")
    radius = enc.scenario.moving[0, 4]
    assert r.collision and r.within_ship_length and not r.goal and not r.passed
    assert r.min_centre_distance_model_m - radius < 0.5 * 1.255 + 0.05
    assert r.min_centre_distance_m == pytest.approx(r.min_centre_distance_model_m
                                                    * enc.scale)
    # they close at ~(0.28 + 0.37) m/s from 31.4 m: contact after ~45 s, not before 30 s
    assert 30 <= r.steps <= 60
    assert r.interventions == 0 and r.fallbacks == 0
    assert np.all(enc.scenario.static[:, 2] == 0) and N_STATIC == 8
