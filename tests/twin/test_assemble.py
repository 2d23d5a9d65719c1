"""The snapshot's parts against what they stand for (the tracking library's prediction)."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.errors import StateError
from asvtwin.tracking.prediction import predict_tracks
from asvtwin.twin.assemble import cv_cones


def _tracks(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    mean = np.column_stack([rng.normal(0, 2000, (n, 2)), rng.normal(0, 4, (n, 2))])
    L = rng.normal(0, 1, (n, 4, 4)) * np.array([30.0, 30.0, 1.0, 1.0])[:, None]
    cov = L @ L.transpose(0, 2, 1) + 1e-3 * np.eye(4)
    return mean, cov


@pytest.mark.parametrize("q", [0.05, 1e-4])
@pytest.mark.parametrize("n", [0, 1, 36])
def test_cones_equal_the_tracking_prediction(n: int, q: float) -> None:
    """The compiled cones equal :func:`predict_tracks`' positions and twice its largest
    position standard deviation (closed form, full 4x4 propagation by einsum) to 1e-9,
    for estimates older than the snapshot and over a filter-length horizon."""
    mean, cov = _tracks(n, 3 + n)
    t0, t = 100.0, 100.7
    times = t + np.linspace(0.0, 209.0, 7)
    ref = predict_tracks(mean, cov, t0, times, q)
    pos, radius = cv_cones(mean, cov, t0, times, q)
    assert pos.shape == (n, 7, 2) and radius.shape == (n, 7)
    np.testing.assert_allclose(pos, ref.positions, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(radius, 2.0 * ref.position_std_max(), rtol=1e-9)
    if n:
        assert (radius[:, -1] > radius[:, 0]).all()  # the cone widens over the horizon


def test_cones_refuse_bad_shapes() -> None:
    with pytest.raises(StateError, match=r"\(n, 4\)"):
        cv_cones(np.zeros((2, 3)), np.zeros((2, 4, 4)), 0.0, np.zeros(3), 0.1)
