"""Maximum-likelihood calibration of the residual model."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.errors import StateError
from asvtwin.observer import SensorNoise, fit_residual_model, simulate
from asvtwin.vessel import cybership2


def test_calm_water_fit_is_white_and_the_windy_one_needs_more_process_noise():
    p = cybership2()
    noise = SensorNoise.for_vessel(p)
    calm = simulate(p, 3, 400.0, seed=50, environment=None, noise=noise)
    windy = simulate(p, 3, 400.0, seed=51, noise=noise)
    m_calm = fit_residual_model(p, calm.nu_meas, calm.tau, calm.dt_s, noise.sigma_nu)
    m_wind = fit_residual_model(p, windy.nu_meas, windy.tau, windy.dt_s, noise.sigma_nu)
    # only sensor noise: the matched filter is χ²₁ as modelled (κ near 1)
    assert all(1.0 <= k < 1.3 for k in m_calm.kappa)
    # a moving environment is explained by a faster disturbance random walk in surge
    assert m_wind.q_d[0] > m_calm.q_d[0]
    np.testing.assert_allclose(m_calm.R, m_wind.R)


def test_calibration_refuses_short_or_broken_data():
    p = cybership2()
    sig = SensorNoise.for_vessel(p).sigma_nu
    short = simulate(p, 1, 5.0, seed=52, environment=None)
    with pytest.raises(StateError, match="calibration needs at least"):
        fit_residual_model(p, short.nu_meas, short.tau, short.dt_s, sig)
    with pytest.raises(StateError, match=r"shape \(T, r, 3\)"):
        fit_residual_model(p, short.nu_meas[:, 0], short.tau[:, 0], short.dt_s, sig)
    bad = short.nu_meas.copy()
    bad[2, 0, 0] = np.nan
    with pytest.raises(StateError, match="finite"):
        fit_residual_model(p, bad, short.tau, short.dt_s, sig)
