"""The heading/speed autopilot: hand formulas, limits, integrators, batching, step response."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.errors import ParameterError, StateError
from asvtwin.guidance import AutopilotGains, HeadingSpeedAutopilot
from asvtwin.vessel import BatchSimulator, cybership2, cybership2_full_scale, froude_scale
from asvtwin.vessel.model import damping

BOTH = pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()],
                               ids=["model", "full"])


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _states(params, rng, n):
    f = math.sqrt(params.length / 1.255)
    x = np.zeros((n, 6))
    x[:, 2] = rng.uniform(-4, 4, n)
    x[:, 3] = rng.uniform(-0.2, 0.6, n) * f
    x[:, 4] = rng.uniform(-0.1, 0.1, n) * f
    x[:, 5] = rng.uniform(-0.2, 0.2, n) / f
    return x


@BOTH
def test_critically_damped_pd_is_the_hand_formula(params, rng):
    f = math.sqrt(params.length / 1.255)
    w = 0.8 / f
    ap = HeadingSpeedAutopilot(params, AutopilotGains.critically_damped(params, w))
    x = _states(params, rng, 64)
    psi_d = rng.uniform(-4, 4, 64)
    u_d = rng.uniform(0.0, 0.3, 64) * f
    tau = ap.tau(x, psi_d, u_d)
    m_r = params.M[2, 2]
    e = _wrap(psi_d - x[:, 2])
    tau_r = m_r * (w * w * e - 2 * w * x[:, 5])  # τ_r = m_r(ω² e − 2ω r)
    ff = np.array([(damping(params, np.array([u, 0, 0])) @ np.array([u, 0, 0])).ravel()[0]
                   for u in u_d])
    act = params.actuators
    np.testing.assert_allclose(tau[:, 2], np.clip(tau_r, act.tau_min[2], act.tau_max[2]),
                               rtol=1e-12, atol=1e-12 * act.tau_max[2])
    np.testing.assert_allclose(tau[:, 0], np.clip(ff, act.tau_min[0], act.tau_max[0]),
                               rtol=1e-12, atol=1e-12 * act.tau_max[0])
    assert (tau[:, 1] == 0).all()


def test_rate_limited_cascade_and_crab_angle_are_the_hand_formula(rng):
    p = cybership2_full_scale()
    g = AutopilotGains.rate_limited(p, 0.05, 0.01, 1000.0, crab_compensation=True)
    ap = HeadingSpeedAutopilot(p, g)
    x = _states(p, rng, 64)
    x[:, 3] = np.abs(x[:, 3]) + 0.1
    chi_d = rng.uniform(-4, 4, 64)
    u_d = 2.0
    tau = ap.tau(x, chi_d, u_d)
    beta = np.arctan2(x[:, 4], x[:, 3])
    e = _wrap(chi_d - beta - x[:, 2])
    r_d = np.clip(0.05 * e, -0.01, 0.01)
    m_r = p.I_z - p.N_rdot
    tau_r = 20 * 0.05 * m_r * (r_d - x[:, 5]) - p.N_r * r_d
    d_u = -(p.X_u * u_d + p.X_uu * u_d * abs(u_d) + p.X_uuu * u_d**3)
    tau_u = d_u + 1000.0 * (u_d - x[:, 3])
    act = p.actuators
    np.testing.assert_allclose(tau[:, 2], np.clip(tau_r, act.tau_min[2], act.tau_max[2]),
                               rtol=1e-10)
    np.testing.assert_allclose(tau[:, 0], np.clip(tau_u, act.tau_min[0], act.tau_max[0]),
                               rtol=1e-10)


@BOTH
def test_output_within_actuator_limits(params, rng):
    ap = HeadingSpeedAutopilot(params)
    x = _states(params, rng, 500) * 5.0  # far outside the envelope
    tau = ap.tau(x, rng.uniform(-10, 10, 500), rng.uniform(-5, 50, 500))
    act = params.actuators
    assert (tau >= np.array(act.tau_min) - 1e-9).all()
    assert (tau <= np.array(act.tau_max) + 1e-9).all()


def test_batched_with_per_vessel_params_equals_one_by_one(rng):
    plist = [froude_scale(cybership2(), s) for s in (1.0, 10.0, 70.0)]
    gains = AutopilotGains(k_psi=np.array([0.3, 0.1, 0.05]), r_max_rad_s=np.array([0.1, 0.05, np.inf]),
                           k_r=np.array([1.0, 100.0, 1e6]), k_u=np.array([5.0, 50.0, 5e4]))
    batch = HeadingSpeedAutopilot(plist, gains)
    x = np.vstack([_states(p, rng, 1) for p in plist])
    chi = rng.uniform(-3, 3, 3)
    u = np.array([0.2, 0.6, 1.5])
    tb = batch.tau(x, chi, u)
    for i, p in enumerate(plist):
        gi = AutopilotGains(k_psi=gains.k_psi[i], r_max_rad_s=gains.r_max_rad_s[i],
                            k_r=gains.k_r[i], k_u=gains.k_u[i])
        np.testing.assert_allclose(HeadingSpeedAutopilot(p, gi).tau(x[i], chi[i], u[i]), tb[i],
                                   rtol=1e-13)


def test_integrators_freeze_while_saturated():
    p = cybership2()
    g = AutopilotGains.critically_damped(p, 0.8, integral=True, speed_time_constant_s=5.0)
    ap = HeadingSpeedAutopilot(p, g, dt_s=0.1)
    x = np.array([0.0, 0.0, 0.0, 0.1, 0.0, 0.0])
    # small heading error, speed error inside the range: both integrate
    ap.tau(x, 0.01, 0.12)
    assert ap._ipsi[0] == pytest.approx(0.1 * 0.01) and ap._iu[0] == pytest.approx(0.1 * 0.02)
    # a 3 rad heading error saturates the yaw moment: its integrator stays put
    before = ap._ipsi.copy()
    tau = ap.tau(x, 3.0, 0.12)
    assert tau[2] == p.actuators.tau_max[2]
    assert ap._ipsi[0] == before[0]
    ap.reset()
    ap.tau(x, 0.0, 0.1)
    assert ap._ipsi[0] == 0.0 and ap._iu[0] == 0.0


def test_bad_input_is_refused():
    p = cybership2()
    with pytest.raises(ParameterError, match="dt_s"):
        HeadingSpeedAutopilot(p, AutopilotGains.critically_damped(p, 0.8, integral=True))
    with pytest.raises(ParameterError, match="k_r"):
        AutopilotGains(k_psi=1.0, r_max_rad_s=1.0, k_r=-1.0)
    ap = HeadingSpeedAutopilot(p)
    with pytest.raises(StateError, match="finite"):
        ap.tau(np.array([0, 0, np.nan, 0, 0, 0.0]), 0.0, 0.1)
    with pytest.raises(StateError, match="finite"):
        ap.tau(np.zeros(6), np.inf, 0.1)
    with pytest.raises(StateError, match="shape"):
        ap.tau(np.zeros(5), 0.0, 0.1)


@BOTH
def test_heading_step_response_settles_without_large_overshoot(params):
    """30 deg course change at 0.25 sqrt(λ) m/s: within 1 deg after 60 s sqrt(λ)."""
    f = math.sqrt(params.length / 1.255)
    U = 0.25 * f
    dt = 0.1 * f
    ap = HeadingSpeedAutopilot(params)
    sim = BatchSimulator([params], np.array([[0, 0, 0, U, 0, 0.0]]), dt_s=dt)
    psi_d = math.radians(30.0)
    x = sim.state[0]
    psi, beta = [], []
    for _ in range(round(90 * f / dt)):
        x = sim.step(ap.tau(x, psi_d, U)[None])[0]
        psi.append(x[2])
        beta.append(math.atan2(x[4], x[3]))
    course = np.degrees(np.array(psi) + np.array(beta))  # χ = ψ + β
    t = np.arange(len(psi)) * dt / f
    # the sway of the turn adds crab: the course overshoots by < 20 % of the step
    assert course.max() < 30.0 + 6.0
    assert abs(course[t >= 60.0] - 30.0).max() < 1.0
