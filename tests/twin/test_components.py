"""The twin's filter stage builds its moving obstacles from the tracker's safety predictions
(consistency-inflated covariance), checked against an independent CV propagation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.tracking import COVARIANCE_INFLATION, TrackSnapshot
from asvtwin.twin.components import FilterStage
from asvtwin.vessel import cybership2, cybership2_full_scale


def _tracks(t_s: float, scale: float) -> TrackSnapshot:
    # track 7 confirmed (ellipse known), track 9 coasting (no ellipse), track 4 tentative
    mean = np.array([[30.0, 5.0, -1.0, 0.2], [-20.0, 10.0, 0.5, 0.0], [0.0, -15.0, 0.0, 1.0]])
    mean[:, :2] *= scale
    cov = np.stack([np.diag([4.0, 1.0, 0.04, 0.01]), np.diag([2.0, 2.0, 0.09, 0.09]),
                    np.diag([1.0, 1.0, 0.01, 0.01])])
    cov[0, 0, 1] = cov[0, 1, 0] = 0.5  # correlated position errors
    return TrackSnapshot.build(
        t_s=t_s, ids=[7, 9, 4], mmsi=[-1, 257000001, -1], mean=mean, cov=cov,
        status=["confirmed", "coasting", "tentative"],
        semi_axes_m=[[3.0 * scale, 1.0 * scale], [math.nan, math.nan], [1.0, 1.0]],
        last_update_s=[t_s, t_s - 1.0, t_s], updated_lidar=[True, False, True],
        updated_ais=[False, False, False], lidar_only_mean=mean, ais_only_mean=mean,
        counters={})


def _independent_clearance(mean: np.ndarray, P0: np.ndarray, taus: np.ndarray, q: float,
                           hull: float) -> np.ndarray:
    """hull + 2.4477 √(1.6 λ_max(P_pos(τ))) by explicit CV propagation."""
    out = []
    for tau in taus:
        A = np.eye(4)
        A[0, 2] = A[1, 3] = tau
        Q1 = q * np.array([[tau**3 / 3, tau**2 / 2], [tau**2 / 2, tau]])
        Q = np.zeros((4, 4))
        Q[np.ix_([0, 2], [0, 2])] = Q1
        Q[np.ix_([1, 3], [1, 3])] = Q1
        P = A @ P0 @ A.T + Q
        lam = np.linalg.eigvalsh(P[:2, :2])[-1]
        out.append(hull + math.sqrt(-2 * math.log(0.05)) * math.sqrt(COVARIANCE_INFLATION * lam))
    return np.array(out)


@pytest.mark.parametrize("make, scale", [(cybership2, 1.0), (cybership2_full_scale, 70.0)])
def test_moving_obstacles_use_the_trackers_inflated_safety_prediction(make, scale) -> None:
    params = make()
    stage = FilterStage(params, None, tracker_q=0.05)
    t = 12.0
    tracks = _tracks(t - 0.25, scale)  # the tracker ran a little before the filter
    x = np.zeros(6)
    obs = stage.obstacles(t, x, tracks)
    assert len(obs) == 1  # no scene: no coast
    mo = obs[0]
    assert mo.ids == (7, 9)  # confirmed and coasting, not the tentative track 4
    taus = 0.25 + stage.dt_s * np.arange(stage.N + 1)
    r = mo.effective_radii()
    assert r.shape == (2, stage.N + 1)
    for k, (i, hull) in enumerate([(0, 3.0 * scale), (1, stage.hull_radius_m)]):
        want = _independent_clearance(tracks.mean[i], tracks.cov[i], taus, 0.05, hull)
        np.testing.assert_allclose(r[k], want, rtol=1e-9)
        # the inflation is really there: larger than the tracker's raw covariance gives
        raw = hull + (want - hull) / math.sqrt(COVARIANCE_INFLATION)
        assert np.all(r[k] > raw + 1e-9)
        # centres: the CV path from the track's time
        np.testing.assert_allclose(mo.positions[k], tracks.mean[i, :2] + taus[:, None]
                                   * tracks.mean[i, 2:], rtol=1e-12)


def test_no_confirmed_tracks_no_moving_obstacles() -> None:
    stage = FilterStage(cybership2(), None)
    tr = _tracks(0.0, 1.0)
    only_tentative = tr.select(np.array([False, False, True]))
    assert stage.obstacles(0.0, np.zeros(6), only_tentative) == []


def _circling(t_s: float, rate: float, speed: float = 2.5) -> TrackSnapshot:
    """One confirmed track at 400 m north, on course rate·t_s (from north, to starboard)."""
    c = rate * t_s
    mean = np.array([[400.0, 0.0, speed * math.cos(c), speed * math.sin(c)]])
    return TrackSnapshot.build(
        t_s=t_s, ids=[5], mmsi=[-1], mean=mean, cov=np.diag([4.0, 4.0, 0.01, 0.01])[None],
        status=["confirmed"], semi_axes_m=[[30.0, 8.0]], last_update_s=[t_s],
        updated_lidar=[True], updated_ais=[False], lidar_only_mean=mean, ais_only_mean=mean,
        counters={})


def test_a_turning_track_is_given_on_its_arc_beside_its_straight_path() -> None:
    """A vessel circling at 0.8°/s (the benchmark scene's loop that hit the own ship while
    its CV prediction ran off along the tangent): after 10 s of course history the filter
    gets it twice, with one id: on the CV line and on the constant-turn arc (ending after
    90°); a vessel on a steady course stays a single obstacle."""
    from asvtwin.tracking.turning import constant_turn_positions

    stage = FilterStage(cybership2_full_scale(), None)
    w = math.radians(0.8)
    obs: list = []
    for k in range(30):  # the filter's 2 Hz over 14.5 s
        t = 0.5 * k
        obs = stage.obstacles(t, np.zeros(6), _circling(t, w))
    assert len(obs) == 2 and stage.turning_tracks == 1
    cv, arc = obs
    assert cv.ids == arc.ids == (5,)
    tr = _circling(14.5, w)
    taus = stage.dt_s * np.arange(stage.N + 1)
    np.testing.assert_allclose(cv.positions[0], tr.mean[0, :2] + taus[:, None] * tr.mean[0, 2:])
    want = constant_turn_positions(tr.mean[:, :2], tr.mean[:, 2:], [w], taus,
                                   max_turn_rad=0.5 * math.pi)[0]
    np.testing.assert_allclose(arc.positions[0], want, atol=0.05 * 2.5 * taus[-1])
    # the arc really bends (90° in 112 s, then straight on), far from the straight line
    assert np.hypot(*(arc.positions[0, -1] - cv.positions[0, -1])) > 300.0
    np.testing.assert_allclose(arc.effective_radii(), cv.effective_radii())
    # a steady course: one obstacle
    stage = FilterStage(cybership2_full_scale(), None)
    for k in range(30):
        obs = stage.obstacles(0.5 * k, np.zeros(6), _circling(0.5 * k, 0.0))
    assert len(obs) == 1 and stage.turning_tracks == 0


def test_the_twins_filter_options():
    """The twin's speed options hold with or without its comfort options; the comfort
    options (comfort pass-through, the yaw rate's slack at ten times) are not the
    default: they cost the twin's benchmark its realtime goal (docs/psf.md)."""
    from asvtwin.twin.components import twin_filter_config

    plain, comfort = twin_filter_config(), twin_filter_config("acados", comfort=True)
    assert not plain.comfort_pass_through and plain.yaw_slack_weight == 1.0
    assert comfort.comfort_pass_through and comfort.yaw_slack_weight == 10.0
    for c in (plain, comfort):
        assert (c.qp_tol, c.hpipm_mode, c.retry_rti_steps) == (1e-4, "SPEED_ABS", 10)
    assert plain.backend == "auto" and comfort.backend == "acados"
    stage = FilterStage(cybership2_full_scale(), None)
    assert stage.psf.config.comfort_pass_through is False
    assert not stage.psf.config.model_actuator_lag and stage.psf.config.cold_start_solves == 5
    assert stage.psf.config.yaw_slack_weight == 1.0
