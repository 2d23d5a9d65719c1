"""The compiled hot path of the filter equals the references it replaced."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.control import CircleObstacles, CoastSegments, MovingObstacles, stage_circles
from asvtwin.control.backends.ocp import discrete_dynamics
from asvtwin.control.kernels import certify, rollout


def _casadi_rollout(params, x0, U, d, dt, substeps=1):
    F = discrete_dynamics(params, dt, substeps).mapaccum("r", U.shape[0])
    X = np.asarray(F(x0, U.T, np.tile(d[:, None], U.shape[0])))
    return np.vstack([x0[None], X.T])


@pytest.mark.parametrize("substeps", [1, 2])
def test_rollout_is_the_solvers_model(params, substeps):
    """Same model as the OCP's eq. (a): RK4 of the CasADi expression, smoothed |·|."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        x0 = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3, 3),
                       rng.uniform(-0.2, 0.6), rng.uniform(-0.1, 0.1), rng.uniform(-0.2, 0.2)])
        U = np.column_stack([rng.uniform(0, 2, 50), np.zeros(50), rng.uniform(-0.15, 0.15, 50)])
        d = rng.normal(0, 0.2, 3)
        ref = _casadi_rollout(params, x0, U, d, 0.5, substeps)
        out = np.empty((51, 6))
        assert rollout(x0, U, d, params.packed(), 0.5, substeps, out) == -1
        # 25 s of manoeuvring: positions to 1e-9 m, velocities to 1e-12
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9)
        np.testing.assert_allclose(out[:, 3:], ref[:, 3:], rtol=0, atol=1e-12)


def test_rollout_uses_the_smoothed_abs_not_the_simulators(params):
    """Near ν = 0 the smoothed |·| differs from the exact one the vessel kernels use: the
    filter must certify on its solver's model (the difference is small but not zero)."""
    from asvtwin.vessel.kernels import rk4_batch

    x0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    U = np.tile([0.05, 0.0, 0.001], (4, 1))
    out = np.empty((5, 6))
    rollout(x0, U, np.zeros(3), params.packed(), 0.5, 1, out)
    xs = x0[None].copy()
    for k in range(4):
        nxt = np.empty_like(xs)
        rk4_batch(xs, U[k][None], np.zeros((1, 3)), params.packed()[None], 0.5, nxt)
        xs = nxt
    assert 0 < np.abs(out[-1] - xs[0]).max() < 1e-3


def test_rollout_flags_non_finite_stage(params):
    U = np.zeros((5, 3))
    U[2, 0] = np.nan
    out = np.empty((6, 6))
    assert rollout(np.zeros(6), U, np.zeros(3), params.packed(), 0.5, 1, out) == 3


def test_certify_matches_numpy_reference():
    rng = np.random.default_rng(5)
    N = 20
    X = np.zeros((N + 1, 6))
    X[:, 0] = np.linspace(0, 10, N + 1)
    X[:, 1] = rng.normal(0, 1, N + 1)
    X[-1, 3:] = [0.1, -0.05, 0.2]
    obs = [CircleObstacles(rng.uniform(-5, 15, (4, 2)), rng.uniform(0.5, 2, 4)),
           MovingObstacles.constant_velocity(rng.uniform(0, 10, (2, 2)), [[0.1, 0], [0, -0.2]],
                                             [1.0, 1.5], N=N, dt_s=0.5,
                                             covariances=np.tile(np.eye(2) * 0.1, (2, 1, 1))),
           CoastSegments([[20.0, -10.0, 20.0, 10.0], [0.0, 8.0, 5.0, 8.0]])]
    centres, radii, segs = stage_circles(obs, N)
    clear = np.full(N + 1, 1.255)
    clear[N] += 7.5
    P_f = np.array([[30.0, 1.0, 0.0], [1.0, 40.0, 0.5], [0.0, 0.5, 3.0]])
    out = np.empty((N + 1, 8))
    low, term, finite = certify(X, centres, radii, segs, clear, P_f, out)
    ref = np.concatenate([np.linalg.norm(X[:, None, :2] - centres, axis=2) - radii,
                          CoastSegments(segs).distances(X[:, :2])], axis=1) - clear[:, None]
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    assert low == pytest.approx(ref[1:].min(), abs=1e-12)
    nu = X[-1, 3:]
    assert term == pytest.approx(1.0 - nu @ P_f @ nu, abs=1e-12)
    assert finite
    X[4, 1] = np.nan
    low, _, finite = certify(X, centres, radii, segs, clear, P_f, out)
    assert np.isnan(low) and not finite  # a NaN plan never certifies


def test_stage_circles_layout():
    N = 4
    st = CircleObstacles([[1.0, 2.0], [3.0, 4.0]], [0.5, 0.7])
    mv = MovingObstacles.constant_velocity([[0.0, 0.0]], [[1.0, 0.0]], [2.0], N=N, dt_s=0.5)
    coast = CoastSegments([[0.0, 0.0, 1.0, 1.0]])
    c, r, s = stage_circles([mv, coast, st], N)
    assert c.shape == (N + 1, 3, 2) and r.shape == (N + 1, 3) and s.shape == (1, 4)
    np.testing.assert_allclose(c[:, 0, 0], 0.5 * np.arange(N + 1))  # moving first, as given
    np.testing.assert_allclose(c[3, 1:], st.centres)
    np.testing.assert_allclose(r[:, 1:], np.tile([0.5, 0.7], (N + 1, 1)))
    s[0, 0] = 99.0  # a copy, not the caller's array
    assert coast.segments[0, 0] == 0.0


def test_acados_fast_io_equals_template_interface(psf):
    """The numba-driven C calls read back what acados_template's get/get_stats return."""
    if psf.backend.name != "acados-rti":
        pytest.skip("acados backend not in use")
    psf.reset()
    res = psf.filter([0, 0, 0, 0.3, 0, 0], [2.0, 0, 0],  # near: u_L is not certified
                     CircleObstacles([[10.0, 0.5]], [2.0]), t_s=0.0)
    assert res.iterations >= 1
    be = psf.backend
    S = be._solver
    X, U = be._io.read()
    np.testing.assert_array_equal(X, np.stack([S.get(k, "x") for k in range(be.spec.N + 1)]))
    np.testing.assert_array_equal(U, np.stack([S.get(k, "u") for k in range(be.spec.N)]))
    np.testing.assert_array_equal(np.atleast_2d(be._io.statistics()),
                                  np.atleast_2d(S.get_stats("statistics")))
