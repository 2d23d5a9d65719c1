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
    calm_environment,
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


def _numpy_reference_forces(env, params, x, state):
    """τ_d as the sum of the public NumPy force functions (the environment's arithmetic
    before it was compiled into one pass)."""
    from asvtwin.environment import wave_drift_force

    x = np.atleast_2d(x)
    tau = np.zeros((x.shape[0], 3))
    if np.any(state.current_ned_m_s != 0.0):
        tau += current_force(params, x, state.current_ned_m_s)
    if np.any(state.wind_ned_m_s != 0.0) or np.any(x[:, 3:5] != 0.0):
        c = env.config.wind
        from asvtwin.environment import WindCoefficients

        tau += wind_force(params, x, state.wind_ned_m_s,
                          coefficients=WindCoefficients(c.c_x, c.c_y, c.c_n))
    if env.config.waves.Hs_m > 0.0:
        tau += wave_drift_force(params, x, env.wave_drift_magnitude(params, state),
                                env.config.waves.direction_rad)
    return tau


@pytest.mark.parametrize("params", [cybership2(), FULL], ids=["model", "full"])
@pytest.mark.parametrize("calm", [False, True])
def test_compiled_forces_equal_the_numpy_forces(params, calm):
    """The compiled one-pass τ_d equals current + wind + wave drift computed by the
    separate NumPy functions to 1e-12 (relative to the force's scale), for one vessel and
    a batch, at both hull scales, in the default sea state and in calm water (where the
    wind term is skipped for a vessel at rest)."""
    cfg = calm_environment() if calm else default_environment(params)
    env = Environment(cfg)
    rng = np.random.default_rng(11)
    state = env.initial_state(rng)
    scale = math.sqrt(params.length / 1.255)
    for _ in range(50):
        state = env.advance(state, 0.5, rng)
        x = np.column_stack([rng.normal(0, 100, (5, 2)), rng.uniform(-4, 4, 5),
                             scale * rng.normal(0, 0.3, (5, 2)), rng.normal(0, 0.05, 5) / scale])
        for xs in (x[0], x):
            got = env.forces(params, xs, state)
            ref = _numpy_reference_forces(env, params, xs, state)
            tol = 1e-12 * max(1.0, float(np.abs(ref).max()))
            np.testing.assert_allclose(got, ref, rtol=0, atol=tol)
    if calm:  # at rest in calm water: no force at all
        assert not env.forces(params, np.zeros(6), state).any()


def test_advance_matches_gauss_markov_steps():
    """The environment's step of its five Gauss-Markov processes (one draw call) gives
    the states of :func:`gauss_markov_step` applied one process at a time with the same
    generator, bit for bit, also with a process switched off (σ = 0: no draw)."""
    for cfg in (default_environment(FULL),
                EnvironmentConfig(current=CurrentConfig(0.2, 0.5, GaussMarkov(0.0, 600.0)),
                                  wind=WindConfig(5.0, 1.0, GaussMarkov(1.0, 30.0)),
                                  waves=WaveConfig(0.5, 0.3, 0.3, GaussMarkov(0.0, 120.0)))):
        env = Environment(cfg)
        r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
        s = env.initial_state(r1)
        env.initial_state(r2)
        bc, bw, bz = s._b_current, s._b_wind, s._b_wave
        for k in range(200):
            dt = 0.05 if k % 3 else 0.1
            s = env.advance(s, dt, r1)
            bc = gauss_markov_step(bc, dt, cfg.current.variation.T_s,
                                   cfg.current.variation.sigma, r2)
            bw = gauss_markov_step(bw, dt, cfg.wind.gusts.T_s, cfg.wind.gusts.sigma, r2)
            bz = float(gauss_markov_step(bz, dt, cfg.waves.variation.T_s,
                                         cfg.waves.variation.sigma, r2))
            assert np.array_equal(s._b_current, bc) and np.array_equal(s._b_wind, bw)
            assert s._b_wave == bz
        assert r1.standard_normal() == r2.standard_normal()  # the same number of draws


def test_forces_refuse_a_bad_state():
    from asvtwin.errors import StateError

    env = Environment(default_environment(FULL))
    with pytest.raises(StateError, match="shape"):
        env.forces(FULL, np.zeros(5), env.initial_state(np.random.default_rng(0)))
