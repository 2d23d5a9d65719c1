"""The current's force through the vessel kernel agrees with the numpy reference model."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.environment import current_force
from asvtwin.errors import StateError
from asvtwin.vessel import coriolis, cybership2, cybership2_full_scale, rotation


def _reference(params, x, vc):
    """τ_d = n(ν) − n(ν − ν_c) with C(ν), D(ν) from the readable model (asvtwin.vessel.model)
    and ν_c = R(ψ)ᵀ [V_N, V_E, 0] by the rotation matrix."""
    from asvtwin.vessel import damping

    out = []
    for xi, vci in zip(x, np.broadcast_to(vc, (len(x), 2))):
        nu = xi[3:6]
        nu_c = rotation(xi[2]).T @ np.array([vci[0], vci[1], 0.0])
        nu_r = nu - nu_c

        def n(v):
            return (coriolis(params, v)[0] + damping(params, v)[0]) @ v

        out.append(n(nu) - n(nu_r))
    return np.array(out)


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()])
def test_kernel_current_force_matches_the_reference_model(params):
    rng = np.random.default_rng(3)
    L = params.length
    speed = 0.57 * np.sqrt(L / 1.255)  # the hull's top speed, Froude-scaled
    n = 50
    x = np.column_stack([rng.normal(0, 10 * L, (n, 2)), rng.uniform(-np.pi, np.pi, n),
                         rng.uniform(-0.2, 1.0, n) * speed, rng.normal(0, 0.2, n) * speed,
                         rng.normal(0, 0.5, n) * speed / L])
    shared = np.array([0.3, -0.1]) * speed
    per_vessel = rng.normal(0, 0.2, (n, 2)) * speed
    scale = np.abs(_reference(params, x, per_vessel)).max()
    for vc in (shared, per_vessel):
        np.testing.assert_allclose(current_force(params, x, vc), _reference(params, x, vc),
                                   rtol=1e-9, atol=1e-12 * scale)
    # one vessel as (6,) and the same vessel in a batch give the same row
    np.testing.assert_allclose(current_force(params, x[7], shared),
                               current_force(params, x, shared)[7:8], rtol=1e-14)


def test_current_force_shapes_are_checked():
    p = cybership2()
    with pytest.raises(StateError, match=r"shape \(n, 6\)"):
        current_force(p, np.zeros((2, 5)), [0.1, 0.0])
    with pytest.raises(StateError, match="current_ned_m_s"):
        current_force(p, np.zeros((3, 6)), np.zeros((2, 2)))
