"""The weather the twin receives drives the wind-force model (sources → environment)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.environment import Environment, EnvironmentConfig, WindConfig, wind_force
from asvtwin.sources.weather import OfflineWeatherSource
from asvtwin.vessel import cybership2_full_scale


def test_forecast_wind_drives_the_wind_force():
    p = cybership2_full_scale()
    series = OfflineWeatherSource().fetch().series
    t0, _ = series.span_unix_s
    sample = series.at(t0 + 1800.0)
    assert sample.wind_speed_m_s is not None and sample.wind_from_rad is not None
    # a vessel at rest, bow into the forecast wind: pure head wind, pushed astern
    x = np.array([[0.0, 0.0, sample.wind_from_rad, 0.0, 0.0, 0.0]])
    tau = wind_force(p, x, sample.wind_ned_m_s())[0]
    q = 0.5 * 1.247 * sample.wind_speed_m_s**2
    assert tau[0] == pytest.approx(-q * 0.7 * p.area_frontal, rel=1e-9)
    assert abs(tau[1]) < 1e-9 * abs(tau[0]) + 1e-9
    # the same through the environment process (no gusts), beam-on: pushed to leeward
    env = Environment(EnvironmentConfig(wind=WindConfig(sample.wind_speed_m_s,
                                                        sample.wind_from_rad)))
    s = env.initial_state(np.random.default_rng(0))
    beam = np.array([[0.0, 0.0, sample.wind_from_rad - math.pi / 2, 0.0, 0.0, 0.0]])
    tau_b = env.forces(p, beam, s)[0]  # wind from starboard: sway force to port (< 0)
    assert tau_b[1] == pytest.approx(-q * 0.85 * p.area_lateral, rel=1e-9)
