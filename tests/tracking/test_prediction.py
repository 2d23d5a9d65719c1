"""Prediction over a horizon: closed form, widening cone, inputs for the safety filter."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from asvtwin.errors import ParameterError
from asvtwin.tracking import (
    TrackSnapshot,
    cv_predict,
    predict_tracks,
    predictions_for_safety,
    uncertainty_polygon,
)
from asvtwin.tracking.prediction import COVARIANCE_INFLATION


def _snapshot() -> TrackSnapshot:
    P = np.tile(np.diag([4.0, 4.0, 0.04, 0.04]), (2, 1, 1))
    return TrackSnapshot.build(
        t_s=10.0, ids=[7, 8], mmsi=[257000000, -1], mean=[[0.0, 0.0, 5.0, 0.0], [100.0, 100.0, 0.0, 0.0]], cov=P,
        status=["confirmed", "tentative"], semi_axes_m=[[20.0, 5.0], [np.nan, np.nan]], last_update_s=[10.0, 10.0],
        updated_lidar=[True, True], updated_ais=[True, False], lidar_only_mean=np.full((2, 4), np.nan),
        ais_only_mean=np.full((2, 4), np.nan), counters={})


def test_closed_form_equals_stepwise_prediction() -> None:
    s = _snapshot()
    times = 10.0 + np.arange(0, 121, 5.0)
    pred = predict_tracks(s.mean, s.cov, s.t_s, times, 0.05)
    x, P = np.array(s.mean), np.array(s.cov)
    for k in range(1, len(times)):
        x, P = cv_predict(x, P, 5.0, 0.05)
        np.testing.assert_allclose(pred.mean[:, k], x, atol=1e-9)
        np.testing.assert_allclose(pred.cov[:, k], P, atol=1e-9)
    np.testing.assert_allclose(pred.positions[0, -1], [600.0, 0.0])
    std = pred.position_std_max()
    assert np.all(np.diff(std, axis=1) > 0)  # the cone widens
    # at 120 s: sqrt(4 + 0.04 * 120^2 + 0.05 * 120^3 / 3) per axis
    assert std[0, -1] == pytest.approx(np.sqrt(4 + 0.04 * 120**2 + 0.05 * 120**3 / 3), rel=1e-9)


def test_uncertainty_polygon_contains_the_path_and_widens() -> None:
    s = _snapshot()
    pred = predict_tracks(s.mean, s.cov, s.t_s, 10.0 + np.arange(0, 121, 5.0), 0.05)
    poly = shapely.Polygon(uncertainty_polygon(pred.positions[0], pred.cov[0, :, :2, :2], k_sigma=2.0))
    assert poly.is_valid
    assert poly.buffer(1e-6).contains(shapely.LineString(pred.positions[0]))
    half = lambda north: poly.intersection(shapely.LineString([(north, -1e4), (north, 1e4)])).length / 2
    assert half(300.0) > half(50.0) > 0
    # at rest: the 2-sigma ellipse of the last covariance
    rest = uncertainty_polygon(pred.positions[1], pred.cov[1, :, :2, :2])
    r = np.hypot(*(rest - pred.positions[1, -1]).T)
    np.testing.assert_allclose(r, 2.0 * np.sqrt(pred.cov[1, -1, 0, 0]), rtol=1e-9)


def test_safety_prediction_is_plain_and_conservative() -> None:
    s = _snapshot()
    times = 10.0 + np.linspace(0.0, 60.0, 13)
    sp = predictions_for_safety(s, times, k_sigma=2.0, covariance_inflation=1.0)
    assert sp.track_ids.tolist() == [7] and sp.positions.shape == (1, 13, 2)
    assert sp.clearance_radius_m[0, 0] == pytest.approx(20.0 + 2.0 * 2.0)
    assert np.all(np.diff(sp.clearance_radius_m[0]) > 0)
    allp = predictions_for_safety(s, times, confirmed_only=False, default_hull_radius_m=12.0,
                                  covariance_inflation=1.0)
    assert allp.clearance_radius_m[1, 0] == pytest.approx(12.0 + 4.0)
    # by default the covariance is scaled by the measured NEES/dof (the tracker's fused
    # covariance is ~1.6x too small in the worst benchmark scene): σ grows by √1.6
    dflt = predictions_for_safety(s, times, k_sigma=2.0)
    assert dflt.clearance_radius_m[0, 0] == pytest.approx(20.0 + 2.0 * np.sqrt(COVARIANCE_INFLATION) * 2.0)
    with pytest.raises(ParameterError, match="covariance_inflation"):
        predictions_for_safety(s, times, covariance_inflation=0.5)
    with pytest.raises(ParameterError, match="times_s"):
        predictions_for_safety(s, [5.0, 10.0])


def test_cached_contraction_order_gives_the_searched_result_for_every_shape():
    """predict_tracks reuses the einsum contraction order per shape (the search cost 40 %
    of a call): the covariances must equal einsum(optimize=True) exactly, for track counts
    and horizons whose best order differs (1 and 36 tracks do), in any call order."""
    from asvtwin.tracking.kalman import cv_process_noise, cv_transition

    rng = np.random.default_rng(3)
    for n, k in [(36, 7), (1, 7), (5, 25), (36, 7), (1, 1), (90, 13), (5, 25)]:
        x = rng.normal(size=(n, 4))
        L = rng.normal(size=(n, 4, 4))
        P = L @ L.swapaxes(-1, -2)
        t = np.linspace(3.0, 120.0, k)
        pred = predict_tracks(x, P, 2.0, t, 0.05)
        A = cv_transition(t - 2.0)
        ref = np.einsum("tij,njk,tlk->ntil", A, P, A, optimize=True) + \
            cv_process_noise(t - 2.0, 0.05)[None]
        assert np.array_equal(pred.cov, 0.5 * (ref + ref.swapaxes(-1, -2))), (n, k)
