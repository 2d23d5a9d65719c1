"""Turn rates from a track's course history, and constant-turn paths
(asvtwin.tracking.turning)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from asvtwin.errors import ParameterError
from asvtwin.tracking.turning import TurnRateEstimator, constant_turn_positions


def _feed(est, rate, speed, *, sigma_v=0.0, seed=0, n=80, dt=0.5, track=7, c0=0.3):
    rng = np.random.default_rng(seed)
    out = 0.0
    for k in range(n):
        t = k * dt
        c = c0 + rate * t
        v = speed * np.array([math.cos(c), math.sin(c)]) + sigma_v * rng.standard_normal(2)
        out = float(est.update(t, [track], [v])[0])
    return out


@pytest.mark.parametrize("rate_deg_s", [-2.0, -0.8, 0.7, 1.0, 3.0])
def test_a_steady_turn_is_measured_from_noisy_velocities(rate_deg_s):
    """2.5 m/s with 0.1 m/s velocity noise per axis (a course error of ~2.3°), sampled at
    the filter's 2 Hz over the 30 s window: the slope's standard error is ~0.035°/s, so
    every rate within 3 of them, the sign right (starboard positive)."""
    w = math.radians(rate_deg_s)
    got = [_feed(TurnRateEstimator(), w, 2.5, sigma_v=0.1, seed=s) for s in range(10)]
    assert np.all(np.sign(got) == np.sign(w))
    se = 0.04 / (math.sqrt(60) * np.std(np.arange(60) * 0.5))  # course σ / (√n σ_t)
    assert np.allclose(got, w, rtol=0.0, atol=3 * se), (np.degrees(got), rate_deg_s)


def test_a_straight_course_is_not_a_turn():
    """Over 200 seeds of a straight course with the same noise, no turn is reported (the
    slope must be both ≥ 0.5°/s and ≥ 3 standard errors), nor with a tenth of the
    threshold (0.05°/s) as the only limit: the standard-error test alone holds too."""
    for min_rate in (math.radians(0.5), math.radians(0.05)):
        est = TurnRateEstimator(min_rate=min_rate)
        hits = sum(_feed(est, 0.0, 2.5, sigma_v=0.1, seed=s, track=s) != 0.0
                   for s in range(200))
        assert hits <= (0 if min_rate > 0.005 else 2), (min_rate, hits)


def test_slow_vessels_and_short_histories_give_no_rate():
    assert _feed(TurnRateEstimator(), math.radians(2.0), 0.3, n=80) == 0.0  # too slow
    # 4.5 s of samples: shorter than min_span_s (10 s)
    assert _feed(TurnRateEstimator(), math.radians(2.0), 2.5, n=10) == 0.0
    # a rate below min_rate is not a turn, however well measured
    assert _feed(TurnRateEstimator(), math.radians(0.3), 2.5, n=80) == 0.0


def test_the_course_is_unwrapped_across_north():
    """A turn through 180° (the atan2 cut) is still one steady rate."""
    w = math.radians(3.0)
    assert _feed(TurnRateEstimator(), w, 2.5, c0=math.pi - 0.5) == pytest.approx(w, rel=1e-6)
    assert _feed(TurnRateEstimator(), -w, 2.5, c0=-math.pi + 0.5) == pytest.approx(-w,
                                                                                    rel=1e-6)


def test_histories_are_forgotten():
    est = TurnRateEstimator(forget_s=60.0)
    _feed(est, 0.01, 2.5, n=20, track=1)  # up to t = 9.5 s
    assert len(est) == 1
    est.update(100.0, [2], [[2.5, 0.0]])  # track 1 not seen for 90 s
    assert len(est) == 1
    # a stop clears a history: a turn must be measured again after it
    est = TurnRateEstimator()
    _feed(est, math.radians(2.0), 2.5, n=60, track=3)
    assert est.update(30.0, [3], [[0.0, 0.0]])[0] == 0.0
    assert est.update(30.5, [3], [[2.5, 0.0]])[0] == 0.0


def test_bad_parameters_are_refused():
    with pytest.raises(ParameterError):
        TurnRateEstimator(window_s=0.0)
    with pytest.raises(ParameterError):
        TurnRateEstimator(window_s=10.0, min_span_s=20.0)
    with pytest.raises(ParameterError):
        TurnRateEstimator(min_rate=-1.0)
    with pytest.raises(ParameterError):
        TurnRateEstimator().update(0.0, [1, 2], [[1.0, 0.0]])


def test_constant_turn_positions_against_an_ode_solver():
    """The closed form against scipy's integration of ṅ = V cos c, ė = V sin c, ċ = ω."""
    rng = np.random.default_rng(4)
    taus = np.linspace(0.0, 209.0, 51)
    p = rng.uniform(-500, 500, (6, 2))
    v = rng.uniform(-3, 3, (6, 2))
    w = np.array([0.02, -0.01, 0.003, -0.05, 0.0, 1e-12])
    got = constant_turn_positions(p, v, w, taus)
    assert got.shape == (6, 51, 2)
    for i in range(6):
        speed, c0 = math.hypot(*v[i]), math.atan2(v[i, 1], v[i, 0])
        sol = solve_ivp(lambda t, y, i=i, s=speed: [s * math.cos(y[2]), s * math.sin(y[2]),
                                                   w[i]],
                        (0.0, taus[-1]), [p[i, 0], p[i, 1], c0], t_eval=taus, rtol=1e-10,
                        atol=1e-8)
        np.testing.assert_allclose(got[i], sol.y[:2].T, atol=1e-5)
    # no turn: the CV line
    np.testing.assert_allclose(got[4], p[4] + v[4] * taus[:, None], atol=1e-9)
    # a turn that stops after 90°: on the arc until then, straight on its new course after
    capped = constant_turn_positions(p, v, w, taus, max_turn_rad=0.5 * math.pi)
    for i in range(4):
        t90 = 0.5 * math.pi / abs(w[i])
        on_arc = taus <= t90
        np.testing.assert_allclose(capped[i, on_arc], got[i, on_arc], atol=1e-9)
        if (~on_arc).sum() >= 2:
            d = np.diff(capped[i, ~on_arc], axis=0)
            speed = math.hypot(*v[i])
            np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), speed * np.diff(taus[~on_arc]))
            c1 = math.atan2(v[i, 1], v[i, 0]) + math.copysign(0.5 * math.pi, w[i])
            np.testing.assert_allclose(np.arctan2(d[:, 1], d[:, 0]),
                                       math.atan2(math.sin(c1), math.cos(c1)), atol=1e-9)
