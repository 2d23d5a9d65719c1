"""Scoring against ground truth: hull contact, grounding, tracking RMSE/NEES recomputed by
hand, the observer's error, criteria."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.geo import default_scene
from asvtwin.scenarios import CriteriaSpec
from asvtwin.tracking import TrackSnapshot
from asvtwin.twin.summary import RunMetrics


@pytest.fixture(scope="module")
def land():
    return default_scene().land


def _metrics(land=None, names=("T",)):
    return RunMetrics(list(names), own_length_m=88.0, own_beam_m=20.0, land=land,
                      near_coast_m=350.0, gate_m=50.0, observer_settle_s=10.0)


def _rest():
    return {"scenario": "s", "seed": 0, "duration_s": 1.0, "ticks": 1, "wall_s": 1.0, "realtime_factor": 1.0,
                "filter_calls": 0, "interventions": 0, "fallbacks": {}, "ms_per_tick": {}, "degradations": ()}


def test_collision_is_hull_contact_counted_once_per_contact():
    m = _metrics(names=("CROSSING", "ALONGSIDE"))
    own = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # heading north, 88 x 20 m
    # a 80 x 14 m hull 30 m abeam, parallel: bounding circles overlap, hulls 13 m apart
    along = np.array([0.0, 30.0, 0.0, 0.0, 0.0, 0.0])
    # the same hull crossing 40 m ahead, heading east: its side cuts the own bow
    cross = np.array([40.0, 0.0, math.pi / 2, 0.0, 0.0, 0.0])
    L, B = np.array([80.0, 80.0]), np.array([14.0, 14.0])
    far = np.array([500.0, 500.0, 0.0, 0.0, 0.0, 0.0])
    assert m.truth(0.0, own, np.vstack([far, along]), L, B) == []
    ev = m.truth(1.0, own, np.vstack([cross, along]), L, B)
    assert ev == ["t=1.0 s: collision with CROSSING"]
    m.truth(2.0, own, np.vstack([cross, along]), L, B)  # still in contact: same collision
    m.truth(3.0, own, np.vstack([far, along]), L, B)
    m.truth(4.0, own, np.vstack([cross, along]), L, B)  # a second contact
    assert m.collisions == 2
    np.testing.assert_allclose(m.min_dist, [40.0, 30.0])
    s = m.summarise(criteria=CriteriaSpec(min_distance_targets_m=35.0, goal_reached=False),
                    goal_reached=False, **_rest())
    assert not s.passed
    assert s.criteria["no_collision"] == {"value": 2, "limit": 0, "pass": False}
    assert s.criteria["min_distance_targets"]["pass"] is False  # 30 m < 35 m


def test_grounding_near_the_shore(land):
    m = _metrics(land)
    p = np.array([[3000.0, -1500.0]])
    shore = land.nearest_shore_point(p)[0]
    d = (p[0] - shore) / np.linalg.norm(p[0] - shore)
    on_water = np.r_[shore + 200.0 * d, 0, 0, 0, 0]
    aground = np.r_[shore + 5.0 * d, 0, 0, 0, 0]  # 5 m < half the 20 m beam
    m.truth(0.0, on_water, np.zeros((0, 6)), np.zeros(0), np.zeros(0))
    assert m.groundings == 0 and m.min_land == pytest.approx(200.0, abs=0.5)
    ev = m.truth(1.0, aground, np.zeros((0, 6)), np.zeros(0), np.zeros(0))
    assert m.groundings == 1 and "grounding" in ev[0]


def test_tracking_rmse_and_nees_recomputed_by_hand():
    m = _metrics()
    P1 = np.diag([4.0, 9.0, 0.25, 0.25])
    P2 = np.array([[2.0, 0.5, 0, 0], [0.5, 1.0, 0, 0], [0, 0, 0.1, 0], [0, 0, 0, 0.1]])
    snap = TrackSnapshot.build(
        t_s=5.0, ids=[7, 9], mmsi=[-1, 257000001],
        mean=[[100.0, 200.0, 1.0, 0.0], [400.0, -50.0, 0.0, 2.0]], cov=[P1, P2],
        status=["confirmed", "confirmed"], semi_axes_m=np.full((2, 2), np.nan),
        last_update_s=[5.0, 5.0], updated_lidar=[True, True], updated_ais=[False, True],
        lidar_only_mean=np.zeros((2, 4)), ais_only_mean=np.zeros((2, 4)), counters={})
    # truths (x, y, psi, u, v, r): the second heads east at 2 m/s -> v = (0, 2)
    truth = np.array([[402.0, -49.0, math.pi / 2, 2.0, 0.0, 0.0],
                      [101.0, 198.0, 0.0, 1.5, 0.0, 0.0],
                      [5000.0, 5000.0, 0.0, 1.0, 0.0, 0.0]])  # untracked
    m.tracking(snap, truth)
    z = m.zones["open_sea"].result()
    assert z["samples"] == 2 and z["truth_samples"] == 3
    assert z["coverage"] == pytest.approx(2 / 3)
    e1 = np.array([1.0, -2.0, 0.5, 0.0])     # truth - estimate, track 7
    e2 = np.array([2.0, 1.0, 0.0, 0.0])      # track 9 (velocity exact up to rounding)
    nees1 = e1 @ np.linalg.inv(P1) @ e1
    nees2 = e2 @ np.linalg.inv(P2) @ e2
    assert z["rmse_m"] == pytest.approx(math.sqrt((5.0 + 5.0) / 2), rel=1e-12)
    assert z["nees_mean"] == pytest.approx((nees1 + nees2) / 2, rel=1e-9)
    # the split: position and velocity blocks by hand (block-diagonal here, so they add up)
    pos = [e[:2] @ np.linalg.inv(P[:2, :2]) @ e[:2] for e, P in ((e1, P1), (e2, P2))]
    vel = [e[2:] @ np.linalg.inv(P[2:, 2:]) @ e[2:] for e, P in ((e1, P1), (e2, P2))]
    assert z["nees_position_mean"] == pytest.approx(sum(pos) / 2, rel=1e-9)
    assert z["nees_velocity_mean"] == pytest.approx(sum(vel) / 2, abs=1e-12)
    assert z["nees_position_mean"] + z["nees_velocity_mean"] == pytest.approx(z["nees_mean"])
    assert m.zones["near_coast"].result()["samples"] == 0


def test_observer_error_after_settling_and_invalid_samples():
    m = _metrics()
    m.observer(5.0, np.array([1.0, 1.0, 1.0]), np.zeros(3), True)   # before settling
    m.observer(11.0, np.array([3.0, 0.0, -4.0]), np.zeros(3), True)
    m.observer(12.0, np.array([1.0, 0.0, 2.0]), np.zeros(3), True)
    m.observer(13.0, np.array([np.nan, 0.0, 0.0]), np.zeros(3), False)
    s = m.summarise(criteria=CriteriaSpec(goal_reached=False), goal_reached=False, **_rest())
    ob = s.observer
    assert ob["samples"] == 2 and ob["invalid_samples"] == 1
    assert ob["rmse"]["surge_N"] == pytest.approx(math.sqrt(5.0))
    assert ob["rmse"]["yaw_Nm"] == pytest.approx(math.sqrt(10.0))
    d = s.to_dict()
    assert d["min_distance_land_m"] is None  # no land: inf is not JSON
    assert "observer d_hat RMSE" in s.text()
