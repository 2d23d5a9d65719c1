from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from asvtwin.errors import StateError
from asvtwin.vessel import (
    coriolis,
    cybership2,
    cybership2_full_scale,
    damping,
    dissipation_margin,
    kinetic_energy,
    rhs,
    rotation,
    state_space,
)
from asvtwin.vessel.kernels import rhs_batch

P = cybership2()

# the vessel's operating envelope at model scale (top speed ~0.58 m/s); see
# dissipation_margin for where the published coefficients stop dissipating
nu_strategy = st.tuples(
    st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.floats(-1.5, 1.5)
).map(np.array)


@settings(max_examples=300, deadline=None)
@given(nu=nu_strategy, psi=st.floats(-10, 10))
def test_passivity_energy_never_increases_without_forces(nu, psi):
    # d/dt ½νᵀMν = νᵀ(−C(ν)ν − D(ν)ν) = −νᵀD(ν)ν ≤ 0  (C skew-symmetric)
    x = np.r_[0.0, 0.0, psi, nu]
    xdot = rhs(P, x, np.zeros(3))[0]
    dE = nu @ P.M @ xdot[3:]
    assert dE <= 1e-12
    # the discrete step too: energy after 100 RK4 steps of 0.05 s is not larger
    from asvtwin.vessel import BatchSimulator

    sim = BatchSimulator(P.replace(actuators=P.actuators.ideal()), x, dt_s=0.05)
    e0 = kinetic_energy(P, nu)[0]
    for _ in range(100):
        xk = sim.step(np.zeros(3))
    assert kinetic_energy(P, xk[:, 3:])[0] <= e0 * (1 + 1e-9) + 1e-15


def test_dissipation_margin_envelope():
    assert dissipation_margin(P, [[0.5, 0.3, 0.4]])[0] > 0
    # the published N_|v|v makes D(ν) lose dissipativity at large sway speed
    assert dissipation_margin(P, [[0.0, 3.5, 0.0]])[0] < 0


@settings(max_examples=100, deadline=None)
@given(nu=nu_strategy)
def test_coriolis_is_skew_symmetric(nu):
    C = coriolis(P, nu)[0]
    np.testing.assert_allclose(C, -C.T, atol=1e-12)
    assert abs(nu @ C @ nu) < 1e-10


def test_damping_entries_match_reference_formulas():
    u, v, r = 0.4, -0.2, 0.3
    D = damping(P, [[u, v, r]])[0]
    assert D[0, 0] == pytest.approx(0.7225 + 1.3274 * 0.4 + 5.8664 * 0.16)
    assert D[1, 1] == pytest.approx(0.8612 + 36.2823 * 0.2 + 0.01 * 0.3)
    assert D[1, 2] == pytest.approx(-0.1079 + 0.01 * 0.2 + 0.02 * 0.3)
    assert D[2, 1] == pytest.approx(-0.1052 - 5.0437 * 0.2 + 0.001 * 0.3)
    assert D[2, 2] == pytest.approx(0.5 + 0.001 * 0.2 - 0.005 * 0.3)


def test_rotation_matrix():
    R = rotation(np.pi / 2)
    # surge at ψ = 90° (heading east) moves the vessel east
    np.testing.assert_allclose(R @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-15)
    np.testing.assert_allclose(R[:2, :2] @ R[:2, :2].T, np.eye(2), atol=1e-15)


def test_state_space_form_equals_rhs(rng):
    x = rng.uniform([-50, -50, -3, -0.5, -0.3, -0.4], [50, 50, 3, 0.6, 0.3, 0.4], (64, 6))
    tau = rng.uniform([0, 0, -0.15], [2, 0, 0.15], (64, 3))
    d = rng.normal(0, 0.1, (64, 3))
    A, B = state_space(P, x)
    lhs = np.einsum("nij,nj->ni", A, x) + (B @ (tau + d).T).T
    np.testing.assert_allclose(lhs, rhs(P, x, tau, d), atol=1e-12)


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()])
def test_numba_kernel_equals_numpy_reference(params, rng):
    n = 200
    L = params.length
    x = rng.normal(0, 1, (n, 6)) * [100 * L, 100 * L, 3, 0.3, 0.1, 0.2]
    tau = rng.normal(0, 1, (n, 3)) * np.abs(params.actuators.tau_max)
    d = rng.normal(0, 0.1, (n, 3)) * np.abs(params.actuators.tau_max)
    out = np.empty_like(x)
    assert rhs_batch(x, tau, d, params.packed()[None], out) == -1
    np.testing.assert_allclose(out, rhs(params, x, tau, d), rtol=1e-11, atol=1e-14)


def test_nan_state_names_vessel_and_field():
    x = np.zeros((3, 6))
    x[2, 4] = np.nan
    with pytest.raises(StateError, match="vessel 2 has non-finite v"):
        rhs(P, x, np.zeros((3, 3)))
    with pytest.raises(StateError, match=r"shape \(6,\) or \(n, 6\)"):
        rhs(P, np.zeros((3, 5)), np.zeros((3, 3)))
