"""Fault diagnosis: derived thresholds, detection delay, no false alarms, isolation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from asvtwin.errors import ParameterError, StateError
from asvtwin.observer import (
    DetectorConfig,
    FaultDetector,
    InjectedFault,
    ResidualModel,
    SensorNoise,
    default_window_s,
    simulate,
)
from asvtwin.observer.report import calibrate_detector, fault_suite, run_detector
from asvtwin.vessel import cybership2, cybership2_full_scale

FULL = cybership2_full_scale()
N_RUNS = 40
#: Stated detection delays at full scale [s] (docs/observer.md).
DELAY_LOSS_S = 30.0
DELAY_STUCK_YAW_S = 120.0


@pytest.fixture(scope="module")
def model() -> ResidualModel:
    # calibration seed 10_000: never used by the runs below
    return calibrate_detector(FULL)


def test_threshold_is_derived_from_the_false_alarm_target(model):
    det = FaultDetector(FULL, 1, model, DetectorConfig(false_alarms_per_hour=0.1))
    h = model.dt_s
    W = round(default_window_s(FULL) / h)
    assert det.W == W
    assert det.dofs == (0, 2)  # CyberShip II has no sway actuator
    p = 0.1 * h / 3600.0 / (W * 2)
    assert det.threshold == pytest.approx(chi2.isf(p, 1))
    lax = FaultDetector(FULL, 1, model, DetectorConfig(false_alarms_per_hour=10.0))
    assert lax.threshold < det.threshold


def test_calibrated_noise_model_is_consistent(model):
    # R comes from the sensor noise: (M Σ Mᵀ)_ii
    sig = np.array(SensorNoise.for_vessel(FULL).sigma_nu)
    R = np.diag(FULL.M @ np.diag(sig**2) @ FULL.M.T)
    np.testing.assert_allclose(model.R, R)
    # the matched filter's variance inflation is modest: the model explains the residuals
    assert all(1.0 <= k < 2.0 for k in model.kappa)


def test_half_thrust_loss_is_detected_within_the_stated_delay(model):
    res = fault_suite(FULL, model, n_runs=N_RUNS, seed=30_000,
                      fault_free_hours=N_RUNS * 900.0 / 3600.0)
    delays = np.asarray(res.delays_s)
    assert np.mean(delays <= DELAY_LOSS_S) >= 0.95
    assert res.median_delay_s <= DELAY_LOSS_S
    assert res.wrong_alarms == 0
    # fault-free runs of the same length and number: no alarm at all
    assert res.fault_free_hours == pytest.approx(N_RUNS * 900.0 / 3600.0)
    assert res.false_alarms == 0


def test_stuck_yaw_actuator_is_detected_and_isolated(model):
    tf = 600.0
    faults = [InjectedFault(tf, i, 2, stuck=True) for i in range(N_RUNS)]
    res = simulate(FULL, N_RUNS, tf + 300.0, seed=31_000,
                   noise=SensorNoise.for_vessel(FULL), faults=faults)
    events = run_detector(FULL, model, res)
    first = {}
    for e in events:
        assert e.t_s >= tf, f"alarm before the fault: {e}"
        first.setdefault(e.vessel, e)
    delays = np.array([first[i].t_s - tf if i in first else np.inf for i in range(N_RUNS)])
    assert np.mean(delays <= DELAY_STUCK_YAW_S) >= 0.95
    # the first alarm names the yaw actuator
    assert all(first[i].dof == 2 for i in first)
    e = first[min(first)]
    assert e.kind in ("stuck", "bias", "loss_of_thrust") and 0 < e.confidence <= 1
    assert e.onset_t_s <= e.t_s


def test_surge_bias_is_detected_with_its_sign_and_size(model):
    tf = 600.0
    b = -0.1 * FULL.actuators.tau_max[0]  # 70 kN against the thrust
    faults = [InjectedFault(tf, i, 0, bias=b) for i in range(N_RUNS)]
    res = simulate(FULL, N_RUNS, tf + 300.0, seed=32_000,
                   noise=SensorNoise.for_vessel(FULL), faults=faults)
    events = run_detector(FULL, model, res)
    assert len({e.vessel for e in events if e.dof == 0}) >= 0.95 * N_RUNS
    assert all(e.t_s >= tf for e in events)
    forces = np.array([e.force for e in events if e.dof == 0])
    assert np.all(forces < 0)
    assert np.median(forces) == pytest.approx(b, rel=0.5)


def test_diagnose_refines_with_more_data_and_clear_rearms(model):
    tf = 300.0
    res = simulate(FULL, 1, 600.0, seed=33_000, noise=SensorNoise.for_vessel(FULL),
                   faults=[InjectedFault(tf, 0, 0, gain=0.5)])
    det = FaultDetector(FULL, 1, model)
    hit = None
    for k in range(res.t_s.size):
        ev = det.update(res.t_s[k], res.nu_meas[k], res.tau[k])
        if ev:
            hit = (k, ev[0])
    assert hit is not None and det.latched[0, 0]
    later = det.diagnose(res.t_s[-1], 0, 0)
    assert later.onset_t_s == pytest.approx(hit[1].onset_t_s)
    assert later.kind in ("loss_of_thrust", "bias", "stuck")
    det.clear(0, 0)
    assert not det.latched[0, 0]
    with pytest.raises(StateError, match="no fault latched"):
        det.diagnose(res.t_s[-1], 0, 0)


def test_dropouts_do_not_raise_alarms(model):
    res = simulate(FULL, 4, 900.0, seed=34_000, noise=SensorNoise.for_vessel(FULL))
    nu = res.nu_meas.copy()
    nu[200:230, 1] = np.nan
    nu[500, 2, 0] = np.inf
    det = FaultDetector(FULL, 4, model)
    events = []
    for k in range(res.t_s.size):
        events += det.update(res.t_s[k], nu[k], res.tau[k])
    assert events == []


def test_bad_configuration_is_refused():
    with pytest.raises(ParameterError, match="false_alarms_per_hour"):
        DetectorConfig(false_alarms_per_hour=0.0)
    with pytest.raises(ParameterError, match="window_s"):
        DetectorConfig(window_s=-1.0)
    with pytest.raises(ParameterError, match=r"sigma_nu must be 3 finite values > 0"):
        ResidualModel.from_sensor_noise(cybership2(), (0.0, 0.1, 0.1), 0.1)
    with pytest.raises(ParameterError, match=r"kappa\[1\] \(sway\)"):
        ResidualModel(0.1, (1.0, 1.0, 1.0), (0, 0, 0), (0, 0, 0), (1.0, 0.5, 1.0))
    m = ResidualModel.from_sensor_noise(cybership2(), (0.01, 0.01, 0.01), 0.1)
    det = FaultDetector(cybership2(), 2, m)
    with pytest.raises(StateError, match=r"nu_meas must have shape \(2, 3\)"):
        det.update(0.0, np.zeros(3), np.zeros((2, 3)))
    assert math.isfinite(det.threshold)
