from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.environment import (
    CurrentConfig,
    Environment,
    EnvironmentConfig,
    GaussMarkov,
    WaveConfig,
    WindConfig,
    current_force,
    default_environment,
    gauss_markov_step,
    wind_force,
    wind_vector,
)
from asvtwin.errors import ConfigError
from asvtwin.vessel import BatchSimulator, cybership2, cybership2_full_scale, rotation

FULL = cybership2_full_scale()


def test_unpowered_vessel_drifts_with_the_current():
    Vc = 0.4 * np.array([math.cos(0.7), math.sin(0.7)])
    sim = BatchSimulator(FULL, np.zeros(6), dt_s=1.0)
    for _ in range(6000):
        x = sim.step(np.zeros(3), current_force(FULL, sim.state, Vc))
    v_ned = (rotation(x[0, 2]) @ x[0, 3:6])[:2]
    np.testing.assert_allclose(v_ned, Vc, atol=2e-3)


def test_no_hydrodynamic_force_when_moving_with_the_water():
    from asvtwin.vessel import coriolis, damping

    x = np.array([[0, 0, 0.3, 0.5 * math.cos(0.3), -0.5 * math.sin(0.3), 0.0]])
    # over-ground velocity equals the current [0.5, 0] NED → no relative flow: τ_d
    # cancels the model's C(ν)ν + D(ν)ν exactly, so the net hydrodynamic force is zero
    nu = x[:, 3:6]
    hydro = np.einsum("nij,nj->ni", coriolis(FULL, nu) + damping(FULL, nu), nu)
    np.testing.assert_allclose(current_force(FULL, x, [0.5, 0.0]), hydro, rtol=1e-12)
    assert np.abs(current_force(FULL, x, [0.0, 0.0])).max() == 0.0


def test_wind_force_directions():
    x = np.zeros((1, 6))  # at rest, heading north
    head = wind_force(FULL, x, wind_vector(10.0, 0.0))[0]          # from ahead
    beam = wind_force(FULL, x, wind_vector(10.0, math.pi / 2))[0]  # from starboard
    q = 0.5 * 1.247 * 100.0
    assert head[0] == pytest.approx(-q * 0.7 * FULL.area_frontal)  # pushed astern
    assert abs(head[1]) < 1e-6 * abs(head[0])
    assert beam[1] == pytest.approx(-q * 0.85 * FULL.area_lateral)  # pushed to port
    assert abs(beam[2]) < 1e-6 * abs(beam[1])                       # sin(2γ) = 0


def test_gauss_markov_is_stationary_with_sigma(rng):
    b = np.zeros(20000)
    for _ in range(50):
        b = gauss_markov_step(b, 10.0, 30.0, 0.5, rng)
    assert b.std() == pytest.approx(0.5, rel=0.03)
    # lag-one correlation e^{-dt/T}
    b2 = gauss_markov_step(b, 10.0, 30.0, 0.5, rng)
    assert np.corrcoef(b, b2)[0, 1] == pytest.approx(math.exp(-10 / 30), abs=0.02)


def test_environment_is_seeded_and_pure():
    env = Environment(default_environment(FULL))
    runs = []
    for _ in range(2):
        rng = np.random.default_rng(7)
        s = env.initial_state(rng)
        s0 = s
        for _ in range(100):
            s = env.advance(s, 1.0, rng)
        runs.append(env.forces(FULL, np.zeros((3, 6)), s))
        assert s0.t_s == 0.0 and s.t_s == pytest.approx(100.0)
    np.testing.assert_array_equal(runs[0], runs[1])


def test_default_environment_is_froude_scaled_for_the_model():
    full = default_environment(FULL)
    model = default_environment(cybership2())
    k = math.sqrt(1.255 / 87.85)
    assert model.wind.speed_m_s == pytest.approx(full.wind.speed_m_s * k)
    assert model.current.speed_m_s == pytest.approx(full.current.speed_m_s * k)
    assert model.waves.Hs_m == pytest.approx(full.waves.Hs_m * 1.255 / 87.85)
    # the same sea state gives Froude-similar forces: force ratio λ³ρ_ratio
    lam = 70.0
    x = np.zeros((1, 6))
    fm = Environment(EnvironmentConfig(wind=model.wind)).forces(
        cybership2(), x, Environment(EnvironmentConfig(wind=model.wind)).initial_state(
            np.random.default_rng(0)))
    ff = Environment(EnvironmentConfig(wind=full.wind)).forces(
        FULL, x, Environment(EnvironmentConfig(wind=full.wind)).initial_state(
            np.random.default_rng(0)))
    # wind acts on air: only the geometry scales with Froude here (ρ_air equal)
    assert ff[0, 0] / fm[0, 0] == pytest.approx(lam**3, rel=1e-6)


def test_wave_drift_magnitude_and_direction():
    env = Environment(EnvironmentConfig(waves=WaveConfig(1.0, math.pi / 2, 0.3,
                                                         GaussMarkov(0.0, 100.0))))
    s = env.initial_state(np.random.default_rng(0))
    F = 0.5 * 1025 * 9.81 * 0.25 * FULL.length * 0.3
    assert env.wave_drift_magnitude(FULL, s) == pytest.approx(F)
    tau = env.forces(FULL, np.zeros((1, 6)), s)[0]
    assert tau[1] > 0 and tau[1] > 0.99 * F  # beam seas from port push to starboard


@pytest.mark.parametrize("make", [
    lambda: CurrentConfig(speed_m_s=-1.0),
    lambda: WindConfig(speed_m_s=float("nan")),
    lambda: GaussMarkov(sigma=1.0, T_s=0.0),
    lambda: WaveConfig(Hs_m=1.0, reflection=2.0),
])
def test_bad_environment_config_refused(make):
    with pytest.raises(ConfigError, match="must be"):
        make()
