from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.errors import StateError
from asvtwin.vessel import (
    ActuatorParams,
    BatchSimulator,
    VesselSimulator,
    cybership2,
    cybership2_full_scale,
)
from asvtwin.vessel.manoeuvres import steady_surge_speed, turning_circle

P = cybership2()
IDEAL = P.replace(actuators=P.actuators.ideal())


def test_steady_surge_speed_under_2N():
    # Skjetne et al. (2004) damping: d11(u)·u = 2 N gives about 0.57 m/s
    U = steady_surge_speed(P, 2.0)
    assert U == pytest.approx(0.5788, abs=1e-4)
    assert (0.7225 + 1.3274 * U + 5.8664 * U * U) * U == pytest.approx(2.0, abs=1e-10)
    sim = VesselSimulator(P, np.zeros(6), dt_s=0.1)
    for _ in range(1500):
        x = sim.step([2.0, 0.0, 0.0])
    assert x[3] == pytest.approx(U, abs=1e-6)
    assert x[4] == pytest.approx(0.0, abs=1e-12) and x[5] == pytest.approx(0.0, abs=1e-12)


def test_rk4_is_fourth_order():
    # a smooth manoeuvre: turn from cruise with ideal actuators
    x0 = np.array([0, 0, 0.3, 0.5, 0.0, 0.0])
    T = 8.0

    def run(dt):
        sim = BatchSimulator(IDEAL, x0, dt_s=dt)
        for _ in range(round(T / dt)):
            x = sim.step([1.5, 0.0, 0.1])
        return x[0]

    ref = run(0.0025)
    errs = [np.linalg.norm(run(dt) - ref) for dt in (0.4, 0.2, 0.1)]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(3.6 < o < 4.4 for o in orders), orders


def test_froude_similarity_full_scale_equals_model():
    lam = 70.0
    model, full = cybership2(), cybership2_full_scale()
    rho = 1025.0 / 1000.0
    dt = 0.1
    sm = BatchSimulator(model, np.zeros(6), dt_s=dt)
    sf = BatchSimulator(full, np.zeros(6), dt_s=dt * math.sqrt(lam))
    force = np.array([lam**3 * rho, lam**3 * rho, lam**4 * rho])
    for k in range(600):
        cmd = np.array([2.0, 0.0, 0.15 * math.sin(0.05 * k)])
        xm = sm.step(cmd)[0]
        xf = sf.step(cmd * force)[0]
    scale = np.array([lam, lam, 1.0, math.sqrt(lam), math.sqrt(lam), 1 / math.sqrt(lam)])
    np.testing.assert_allclose(xf / scale, xm, rtol=1e-9, atol=1e-9)


def test_batched_equals_single_stepping(rng):
    n = 16
    x0 = rng.normal(0, 1, (n, 6)) * [10, 10, 1, 0.2, 0.05, 0.05]
    cmds = rng.uniform([0, 0, -0.15], [2, 0, 0.15], (50, n, 3))
    batch = BatchSimulator(P, x0, dt_s=0.2)
    singles = [VesselSimulator(P, x0[i], dt_s=0.2) for i in range(n)]
    for k in range(50):
        xb = batch.step(cmds[k])
        xs = np.array([s.step(cmds[k, i]) for i, s in enumerate(singles)])
    np.testing.assert_array_equal(xb, xs)


def test_same_inputs_same_rollout(rng):
    x0 = rng.normal(0, 1, (4, 6))
    a = BatchSimulator(P, x0, dt_s=0.1)
    b = BatchSimulator(P, x0, dt_s=0.1)
    for _ in range(30):
        np.testing.assert_array_equal(a.step([1, 0, 0.1]), b.step([1, 0, 0.1]))


def test_thruster_first_order_lag_saturation_and_rate_limit():
    act = ActuatorParams(tau_min=(0, -1, -0.15), tau_max=(2, 1, 0.15),
                         time_constant_s=(0.5, 0.0, 0.0), rate_limit=(np.inf, np.inf, 0.1))
    p = P.replace(actuators=act)
    sim = BatchSimulator(p, np.zeros(6), dt_s=0.05)
    sim.step([10.0, -5.0, 1.0])  # saturates to (2, -1, 0.15)
    tau = sim.thrust[0]
    assert tau[0] == pytest.approx(2.0 * (1 - math.exp(-0.05 / 0.5)), rel=1e-12)
    assert tau[1] == -1.0                      # instantaneous and saturated
    assert tau[2] == pytest.approx(0.1 * 0.05)  # rate-limited
    for _ in range(200):
        sim.step([10.0, -5.0, 1.0])
    np.testing.assert_allclose(sim.thrust[0], [2.0, -1.0, 0.15], atol=1e-9)


def test_actuator_fault_injection():
    sim = BatchSimulator(IDEAL, np.zeros((2, 6)), dt_s=0.1)
    sim.set_fault(1, 0, gain=0.5)
    for _ in range(3000):
        x = sim.step([2.0, 0.0, 0.0])
    assert x[0, 3] == pytest.approx(steady_surge_speed(P, 2.0), abs=1e-6)
    assert x[1, 3] == pytest.approx(steady_surge_speed(P, 1.0), abs=1e-6)
    np.testing.assert_allclose(sim.applied_thrust, [[2, 0, 0], [1, 0, 0]])
    sim.stick_actuator(0, 2)  # yaw stuck at 0 while commanding a turn
    x = sim.step([2.0, 0.0, 0.15])
    assert x[0, 5] == 0.0 and x[1, 5] > 0.0
    sim.clear_faults()
    np.testing.assert_allclose(sim.applied_thrust, sim.thrust)


def test_bad_inputs_raise_naming_the_vessel():
    sim = BatchSimulator(P, np.zeros((3, 6)), dt_s=0.1)
    cmd = np.zeros((3, 3))
    cmd[1, 2] = np.inf
    with pytest.raises(StateError, match="commanded thrust of vessel 1 has non-finite yaw"):
        sim.step(cmd)
    d = np.zeros((3, 3))
    d[2, 0] = np.nan
    with pytest.raises(StateError, match="disturbance of vessel 2 has non-finite surge"):
        sim.step(np.zeros(3), d)
    with pytest.raises(StateError, match="dt_s must be finite and > 0"):
        BatchSimulator(P, np.zeros(6), dt_s=0.0)
    x0 = np.zeros((2, 6))
    x0[1, 2] = np.nan
    with pytest.raises(StateError, match="vessel 1 has non-finite psi"):
        BatchSimulator(P, x0, dt_s=0.1)
    with pytest.raises(StateError, match=r"shape \(3,\) or \(3, 3\)"):
        sim.step(np.zeros((2, 3)))


def test_divergence_is_reported_not_silent():
    sim = BatchSimulator(P.replace(actuators=ActuatorParams()), np.zeros(6), dt_s=50.0)
    with pytest.raises(StateError, match="became non-finite"):
        for _ in range(50):
            sim.step([1e6, 0.0, 0.0])


def test_turning_circle_starboard_geometry():
    r = turning_circle(P)
    # turning to starboard (positive yaw moment) drifts east
    assert r.x[-1, 5] > 0 and r.metrics["transfer_m"] > 0
    assert r.metrics["tactical_diameter_m"] < r.metrics["advance_m"]
