from __future__ import annotations

import numpy as np
import pytest

from asvtwin.control import compute_terminal_set, verify_invariance
from asvtwin.errors import ParameterError


@pytest.fixture(scope="module")
def ts(params):
    return compute_terminal_set(params, d_f_m=7.5, nu_max=(2.0, 2.0, 0.6), k_r=0.25)


def test_P_f_symmetric_positive_definite(ts):
    np.testing.assert_allclose(ts.P_f, ts.P_f.T, atol=1e-9)
    assert np.linalg.eigvalsh(ts.P_f).min() > 0


def test_ellipsoid_tied_to_braking_distance(ts):
    # the SDP's bound: horizontal speed <= alpha d_f over the ellipsoid
    Q = np.linalg.inv(ts.P_f)
    c = np.sqrt(np.linalg.eigvalsh(Q[:2, :2]).max())
    assert c <= ts.alpha * ts.d_f_m * (1 + 1e-4)
    # large enough to be useful: CyberShip II coasting 25 s from top speed (0.58 m/s)
    # slows to about 0.13 m/s, which must fit inside
    assert ts.semi_axes[0] > 0.13
    assert ts.semi_axes[2] <= 0.6 + 1e-6


def test_invariant_on_the_nonlinear_model(params, ts):
    max_V, dist = verify_invariance(params, ts, n_directions=48,
                                    rng=np.random.default_rng(3))
    assert max_V <= 1.0 + 1e-6  # trajectories from the boundary stay inside
    assert dist <= ts.d_f_m  # and stop within d_f


def test_cache_returns_same_matrix(params, ts):
    again = compute_terminal_set(params, d_f_m=7.5, nu_max=(2.0, 2.0, 0.6), k_r=0.25)
    np.testing.assert_allclose(again.P_f, ts.P_f)


def test_bad_d_f_refused(params):
    with pytest.raises(ParameterError, match="d_f_m"):
        compute_terminal_set(params, d_f_m=-1.0, nu_max=(2, 2, 0.6))
