"""Metrics: GOSPA by hand, NEES bounds, breaks and false tracks."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.tracking import (
    assign_tracks,
    false_tracks,
    gospa,
    nees,
    nees_bounds,
    rmse,
    track_breaks,
)


def test_gospa_by_hand() -> None:
    truth = np.array([[0.0, 0.0], [100.0, 0.0]])
    est = np.array([[3.0, 4.0], [500.0, 500.0]])
    g = gospa(est, truth, c=20.0, p=2.0)
    # one pair at 5 m, one missed, one false: sqrt(25 + 20^2/2 * 2)
    assert g.distance == pytest.approx(np.sqrt(25.0 + 400.0))
    assert (g.missed, g.false, g.localisation) == (1, 1, 25.0)
    assert gospa(np.empty((0, 2)), truth, c=20.0).distance == pytest.approx(np.sqrt(400.0))


def test_nees_bounds_and_rmse() -> None:
    lo, hi = nees_bounds(2, 1, 0.95)
    assert (lo, hi) == pytest.approx((0.0506, 7.3778), abs=1e-4)
    lo, hi = nees_bounds(4, 50)
    assert (lo, hi) == pytest.approx((3.255, 4.821), abs=1e-3)  # chi2(200) quantiles / 50
    assert rmse([[3.0, 4.0], [0.0, 0.0], [np.nan, 1.0]], np.zeros((3, 2))) == pytest.approx(np.sqrt(12.5))
    assert nees(np.zeros((1, 2)), np.eye(2)[None] * 4.0, np.array([[2.0, 2.0]]))[0] == pytest.approx(2.0)


def test_breaks_and_false_tracks() -> None:
    truth = [np.array([[0.0, 0.0], [50.0, 0.0]])] * 4
    tracks = [([1, 2], [[0.0, 1.0], [50.0, 1.0]]), ([1, 2], [[0.0, 1.0], [50.0, 1.0]]),
              ([1, 3, 9], [[0.0, 1.0], [51.0, 0.0], [900.0, 0.0]]), ([1, 2], [[0.0, 1.0], [50.0, 1.0]])]
    A = np.array([assign_tracks(np.array(p), ids, tr, gate_m=10.0) for (ids, p), tr in zip(tracks, truth)])
    np.testing.assert_array_equal(A[:, 0], [1, 1, 1, 1])
    np.testing.assert_array_equal(track_breaks(A), [0, 2])  # 2 -> 3 -> 2
    assert false_tracks([ids for ids, _ in tracks], A) == {9}
