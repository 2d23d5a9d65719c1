"""Metrics: GOSPA by hand, NEES bounds, breaks and false tracks."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.errors import ParameterError
from asvtwin.tracking import (
    assign_tracks,
    effective_sample_size,
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


def _ar_chi2(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    """χ²₂ values of a 2-D Gaussian AR(1) series (lag-1 correlation ``phi`` of each axis)."""
    e = rng.normal(size=(n, 2))
    y = np.empty((n, 2))
    y[0] = e[0]
    for t in range(1, n):
        y[t] = phi * y[t - 1] + np.sqrt(1.0 - phi * phi) * e[t]
    return (y * y).sum(axis=1)


def test_effective_sample_size_matches_the_spread_of_correlated_means() -> None:
    """Independent χ²₂ samples: n_eff ≈ N. Correlated ones (AR(1), φ = 0.95, 10 series of
    300): the mean's Monte Carlo variance equals 4 / n_eff, and the χ² bounds at n_eff
    cover ~95 % of the means where the naive bounds (N = 3000) cover far fewer."""
    rng = np.random.default_rng(7)
    n_eff, n = effective_sample_size([rng.chisquare(2, 300) for _ in range(20)])
    assert n == 6000 and 0.85 * n < n_eff <= n
    means, neffs = [], []
    for _ in range(150):
        s = [_ar_chi2(rng, 300, 0.95) for _ in range(10)]
        means.append(np.mean(np.concatenate(s)))
        neffs.append(effective_sample_size(s)[0])
    means_a, ne = np.asarray(means), float(np.mean(neffs))
    assert 0.7 < np.var(means_a) / (4.0 / ne) < 1.4  # (theory: n_eff ≈ 3000 (1 − φ²) / (1 + φ²) ≈ 154)
    assert 100 < ne < 250
    lo, hi = nees_bounds(2, ne)
    assert 0.88 <= np.mean((means_a >= lo) & (means_a <= hi)) <= 0.99
    lo_n, hi_n = nees_bounds(2, 3000)
    assert np.mean((means_a >= lo_n) & (means_a <= hi_n)) < 0.5
    with pytest.raises(ParameterError):
        effective_sample_size([np.array([1.0, np.nan])])
