"""The paper's four fusion cases, Chen 2019 gain weighting and covariance intersection."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.errors import StateError
from asvtwin.tracking import (
    H_FULL,
    H_POSITION,
    fuse_covariance_intersection,
    fuse_gain_weighted,
    fuse_product,
    kalman_update,
)

X = np.array([[100.0, 50.0, 2.0, -1.0]] * 4)
P = np.tile(np.diag([25.0, 25.0, 1.0, 1.0]), (4, 1, 1))
ZL = np.array([[104.0, 48.0]] * 4)
RL = np.tile(np.diag([4.0, 9.0]), (4, 1, 1))
ZA = np.array([[98.0, 53.0, 2.5, -0.5]] * 4)
RA = np.tile(np.diag([16.0, 16.0, 0.04, 0.04]), (4, 1, 1))
HAS_L = np.array([True, False, True, False])
HAS_A = np.array([False, True, True, False])


def test_the_four_cases_of_the_paper() -> None:
    x, Pn = fuse_product(X, P, z_lidar=ZL, R_lidar=RL, has_lidar=HAS_L, z_ais=ZA, R_ais=RA, has_ais=HAS_A)
    # case 1: LiDAR only = one Kalman update with the position measurement
    u = kalman_update(X[:1], P[:1], ZL[:1], RL[:1], H_POSITION)
    np.testing.assert_allclose(x[0], u.x[0], atol=1e-10)
    np.testing.assert_allclose(Pn[0], u.P[0], atol=1e-10)
    # by hand for north: 100 + 25/(25+4) * 4
    assert x[0, 0] == pytest.approx(100.0 + 25.0 / 29.0 * 4.0, abs=1e-10)
    # case 2: AIS only
    u = kalman_update(X[1:2], P[1:2], ZA[1:2], RA[1:2], H_FULL)
    np.testing.assert_allclose(x[1], u.x[0], atol=1e-10)
    # case 3: both = the product of three Gaussians = two sequential updates (either order)
    u1 = kalman_update(X[2:3], P[2:3], ZL[2:3], RL[2:3], H_POSITION)
    u2 = kalman_update(u1.x, u1.P, ZA[2:3], RA[2:3], H_FULL)
    np.testing.assert_allclose(x[2], u2.x[0], atol=1e-10)
    np.testing.assert_allclose(Pn[2], u2.P[0], atol=1e-10)
    assert np.trace(Pn[2]) < min(np.trace(Pn[0]), np.trace(Pn[1]))
    # case 4: neither = the prediction unchanged
    np.testing.assert_array_equal(x[3], X[3])
    np.testing.assert_array_equal(Pn[3], P[3])


def test_product_with_no_measurements_and_bad_values() -> None:
    x, _ = fuse_product(X, P)
    np.testing.assert_array_equal(x, X)
    # NaN in a row that has no measurement is ignored; in a row that has one it raises
    zl = ZL.copy()
    zl[1] = np.nan
    fuse_product(X, P, z_lidar=zl, R_lidar=RL, has_lidar=HAS_L)
    with pytest.raises(StateError, match="lidar"):
        fuse_product(X, P, z_lidar=zl, R_lidar=RL, has_lidar=np.ones(4, bool))


def test_chen_gain_weighting_weights_sum_to_identity() -> None:
    uA = kalman_update(X[:1], P[:1], ZA[:1], RA[:1], H_FULL)
    uL = kalman_update(X[:1], P[:1], ZL[:1], RL[:1], H_POSITION)
    GA, GL = uA.K @ H_FULL, uL.K @ H_POSITION
    x, Pf = fuse_gain_weighted(uA.x, uA.P, GA, uL.x, uL.P, GL)
    # equal estimates give that estimate back (W_A + W_L = I)
    xs, _ = fuse_gain_weighted(uA.x, uA.P, GA, uA.x, uA.P, GL)
    np.testing.assert_allclose(xs, uA.x, atol=1e-6)
    # the velocity comes from AIS (LiDAR's gain has no velocity column left to weigh)
    assert np.all(np.isfinite(x)) and np.all(np.linalg.eigvalsh(Pf) > 0)
    # the fused north position lies between the two estimates
    lo, hi = sorted([uA.x[0, 0], uL.x[0, 0]])
    assert lo - 1e-9 <= x[0, 0] <= hi + 1e-9


def test_covariance_intersection_is_consistent_and_optimal() -> None:
    xa, Pa = np.array([[0.0, 0.0]]), np.array([[[4.0, 0.0], [0.0, 1.0]]])
    xb, Pb = np.array([[1.0, 1.0]]), np.array([[[1.0, 0.0], [0.0, 4.0]]])
    _, Pc, w = fuse_covariance_intersection(xa, Pa, xb, Pb)
    assert w[0] == pytest.approx(0.5, abs=0.01)  # symmetric case
    assert 0.0 <= w[0] <= 1.0
    # det(P) is minimal over a fine grid of omega
    dets = [np.linalg.det(np.linalg.inv(o * np.linalg.inv(Pa[0]) + (1 - o) * np.linalg.inv(Pb[0]))) for o in np.linspace(0, 1, 1001)]
    assert np.linalg.det(Pc[0]) <= min(dets) * (1 + 1e-3)
    # versus the product: CI is larger (conservative) in every direction
    prod = np.linalg.inv(np.linalg.inv(Pa[0]) + np.linalg.inv(Pb[0]))
    assert np.all(np.linalg.eigvalsh(Pc[0] - prod) >= -1e-12)


def test_correlated_estimates_product_is_overconfident_ci_is_not() -> None:
    # two estimates with the same error (fully correlated, e.g. two filters of one track)
    rng = np.random.default_rng(0)
    n = 4000
    P1 = np.array([[9.0, 2.0], [2.0, 4.0]])
    e = rng.multivariate_normal(np.zeros(2), P1, n)
    Ps = np.tile(P1, (n, 1, 1))
    x_ci, P_ci, _ = fuse_covariance_intersection(e, Ps, e, Ps)
    nees_ci = np.einsum("ni,nij,nj->n", x_ci, np.linalg.inv(P_ci), x_ci).mean()
    P_prod = np.linalg.inv(2.0 * np.linalg.inv(P1))
    nees_prod = np.einsum("ni,ij,nj->n", e, np.linalg.inv(P_prod), e).mean()
    assert nees_ci == pytest.approx(2.0, rel=0.06)  # consistent: chi2 with 2 dof
    assert nees_prod == pytest.approx(4.0, rel=0.06)  # twice too confident
