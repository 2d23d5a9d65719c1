"""The disturbance observer: convergence, tracking bounds, no drift, dropouts, bad gains."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from asvtwin.errors import ParameterError, StateError
from asvtwin.observer import DisturbanceObserver, ObserverGains, default_gains, gain_range
from asvtwin.observer.runs import SensorNoise, simulate
from asvtwin.vessel import cybership2, cybership2_full_scale
from asvtwin.vessel.model import coriolis, damping


def _run_observer(p, res, **kw):
    obs = DisturbanceObserver(p, res.x.shape[1], dt_s=res.dt_s, **kw)
    out = np.empty_like(res.tau_d)
    for k in range(res.t_s.size):
        out[k] = obs.update(res.nu_meas[k], res.tau[k])
    return obs, out


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()],
                         ids=["model", "full"])
def test_converges_to_constant_disturbance_with_documented_time_constant(params):
    top = params.actuators.tau_max
    d = np.array([-0.1, 0.08, 0.05]) * np.array([top[0], top[0], 2 * top[2]])
    T = np.array(default_gains(params).time_constant_s)
    # the vessel turns under its autopilot, so C(ν) and D(ν) vary all the time
    res = simulate(params, 2, 4.0 * T.max(), seed=3, environment=None,
                   profile=lambda t: d)
    _, dh = _run_observer(params, res)
    t = res.t_s
    for j in range(3):
        # e(t) = e^{-t/T} d exactly at the samples (exact-hold discretisation)
        expected = d[j] * (1.0 - np.exp(-t / T[j]))
        np.testing.assert_allclose(dh[1:, 0, j], expected[1:], atol=2e-3 * abs(d[j]))
        # 90 % within ln(10)·T (one sample of slack)
        k90 = np.flatnonzero(dh[:, 1, j] / d[j] >= 0.9)[0]
        assert t[k90] <= math.log(10.0) * T[j] + 2 * res.dt_s
        assert t[k90] >= math.log(10.0) * T[j] - 2 * res.dt_s


def test_bounded_error_under_slowly_varying_disturbance():
    p = cybership2()
    T = np.array(default_gains(p).time_constant_s)
    A = np.array([0.2, 0.15, 0.03])
    w = 2 * math.pi / 200.0  # a 200 s period, 20 observer time constants
    res = simulate(p, 1, 800.0, seed=4, environment=None,
                   profile=lambda t: A * math.sin(w * t))
    _, dh = _run_observer(p, res)
    err = dh - res.tau_d
    late = res.t_s > 5 * T.max()
    for j in range(3):
        bound = A[j] * w * T[j] / math.sqrt(1 + (w * T[j]) ** 2)
        peak = np.abs(err[late, 0, j]).max()
        assert peak <= 1.05 * bound + 1e-3 * A[j]
        assert peak >= 0.9 * bound  # the lag is real: the bound is tight, not vacuous


def test_no_drift_without_disturbance():
    p = cybership2()
    res = simulate(p, 2, 1500.0, seed=5, environment=None)
    _, dh = _run_observer(p, res)
    assert np.abs(dh).max() < 1e-4 * 2.0
    noisy = simulate(p, 2, 1500.0, seed=6, environment=None,
                     noise=SensorNoise.for_vessel(p))
    _, dn = _run_observer(p, noisy)
    # white noise on ν passes with gain ≈ k M: std ≈ 0.1·25.8·0.005 = 0.013 N in surge
    late = noisy.t_s > 100.0
    std = dn[late].std(axis=(0, 1))
    M = np.diag(p.M)
    k = np.array(default_gains(p).k)
    sig = np.array(SensorNoise.for_vessel(p).sigma_nu)
    assert np.all(std < 1.5 * k * M * sig)
    # the mean stays at zero: no drift (within 5 standard errors of ~100 independent values)
    assert np.all(np.abs(dn[late].mean(axis=(0, 1))) < 5 * std / math.sqrt(100))


def test_matches_numpy_reference_of_the_z_form():
    """d̂ = z + K_d M ν with z integrated exactly for a held input (module doc)."""
    p = cybership2()
    rng = np.random.default_rng(7)
    h = 0.1
    nus = rng.normal(0, [0.2, 0.05, 0.05], (50, 3))
    taus = rng.normal(0, [1.0, 0.0, 0.1], (50, 3))
    obs = DisturbanceObserver(p, 1, dt_s=h)
    k = np.array(obs.gains.k)
    a = np.exp(-k * h)
    Kd = (1 - a) / h
    M = p.M

    def n(nu):
        return (coriolis(p, nu)[0] + damping(p, nu)[0]) @ nu

    obs.update(nus[0], taus[0])
    z = -Kd * (M @ nus[0])  # d̂_0 = 0
    for i in range(1, 50):
        dh = obs.update(nus[i], taus[i - 1])[0]
        nbar = 0.5 * (n(nus[i - 1]) + n(nus[i]))
        z = a * z - (1 - a) * (Kd * (M @ nus[i - 1]) + taus[i - 1] - nbar)
        np.testing.assert_allclose(dh, z + Kd * (M @ nus[i]), rtol=1e-10, atol=1e-12)


def test_batched_equals_one_by_one_with_per_vessel_parameters():
    ps = [cybership2(), cybership2_full_scale()]
    rng = np.random.default_rng(8)
    nus = rng.normal(0, 0.1, (20, 2, 3))
    taus = rng.normal(0, 1.0, (20, 2, 3))
    gains = ObserverGains((0.1, 0.2, 0.3))
    both = DisturbanceObserver(ps, 2, dt_s=0.5, gains=gains)
    ones = [DisturbanceObserver(q, 1, dt_s=0.5, gains=gains) for q in ps]
    for k in range(20):
        b = both.update(nus[k], taus[k])
        for i in range(2):
            np.testing.assert_allclose(b[i], ones[i].update(nus[k, i], taus[k, i])[0])


def test_dropouts_hold_the_estimate_and_flag_it(caplog):
    p = cybership2()
    d = np.array([0.3, 0.0, 0.02])
    res = simulate(p, 2, 60.0, seed=9, environment=None, profile=lambda t: d)
    obs = DisturbanceObserver(p, 2, dt_s=res.dt_s)
    nu = res.nu_meas.copy()
    nu[300:320, 0, :] = np.nan           # vessel 0 loses its velocity for 2 s
    tau = res.tau.copy()
    tau[400, 1, 2] = np.nan               # vessel 1 misses one thrust sample
    caplog.set_level(logging.WARNING)
    held_at = None
    for k in range(res.t_s.size):
        est = obs.update(nu[k], tau[k])
        if k == 299:
            held_at = est[0].copy()
        if 300 <= k < 320:
            np.testing.assert_array_equal(est[0], held_at)
            assert not obs.valid[0] and obs.valid[1]
            assert obs.stale_steps[0] == k - 299
        if k == 400:
            assert not obs.valid[1] and obs.stale_steps[1] == 1
        if k == 320:  # re-anchors on the first good sample (still held), updates next
            assert obs.stale_steps[0] == 20 and not obs.valid[0]
            np.testing.assert_array_equal(est[0], held_at)
        if k == 321:
            assert obs.valid[0] and obs.stale_steps[0] == 0
    assert obs.dropouts == 21
    assert sum("holding its estimate" in r.message for r in caplog.records) == 1
    # the estimate still converges afterwards
    np.testing.assert_allclose(est[:, 0], d[0], rtol=0.05)


@pytest.mark.parametrize("gains", [(-0.1, 0.1, 0.1), (0.0, 0.1, 0.1), (0.1, math.nan, 0.1),
                                   (0.1, 0.1, math.inf)])
def test_non_positive_or_non_finite_gains_are_refused(gains):
    with pytest.raises(ParameterError, match=r"k\[\d\] \((surge|sway|yaw)\)"):
        DisturbanceObserver(cybership2(), 1, dt_s=0.1, gains=gains)


@pytest.mark.parametrize("k", [1e-7, 50.0])
def test_absurd_gains_are_refused_with_the_allowed_range(k):
    lo, hi = gain_range(0.1)
    assert (lo, hi) == (1e-5, 10.0)
    with pytest.raises(ParameterError) as exc:
        DisturbanceObserver(cybership2(), 1, dt_s=0.1, gains=(0.1, k, 0.1))
    msg = str(exc.value)
    assert "k[1] (sway)" in msg and "[1e-05, 10] 1/s" in msg and f"{k:g}" in msg


def test_bad_shapes_and_steps_raise_project_errors():
    with pytest.raises(ParameterError, match="dt_s"):
        DisturbanceObserver(cybership2(), 1, dt_s=0.0)
    obs = DisturbanceObserver(cybership2(), 2, dt_s=0.1)
    with pytest.raises(StateError, match=r"nu_meas must have shape \(3,\) or \(2, 3\)"):
        obs.update(np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="time constant T\\[2\\]"):
        ObserverGains.from_time_constants((10.0, 10.0, -1.0))


def test_default_gains_are_froude_scaled_predecessor_values():
    assert default_gains(cybership2()).k == pytest.approx((0.1, 0.1, 0.08))
    full = default_gains(cybership2_full_scale()).k
    assert full == pytest.approx(tuple(k / math.sqrt(70.0) for k in (0.1, 0.1, 0.08)))
