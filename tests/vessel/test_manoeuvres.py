"""Regression values of the standard manoeuvres, checked for plausibility.

CyberShip II (1:70 supply ship) with its full yaw moment turns tightly: advance 2.5 L and
tactical diameter 1.2 L (IMO MSC.137(76) asks for < 4.5 L and < 5 L; a DP supply ship with
strong thrusters is well inside). Speed loss in the turn to 43 % of approach speed and a
drift angle of ~45° follow from its large sway added mass and Munk moment. The zig-zag at
0.27 m/s (20 % thrust) overshoots 16° then 33°; at full speed the published coefficients
are course-unstable (the reversed moment no longer checks the swing), and that is pinned
too. Full scale (×70) gives the same numbers in ship lengths and Froude-scaled times.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.vessel import cybership2, cybership2_full_scale
from asvtwin.vessel.manoeuvres import thrust_step, turning_circle, zigzag


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()])
def test_turning_circle_regression(params):
    m = turning_circle(params).metrics
    assert m["advance_L"] == pytest.approx(2.495, abs=0.01)
    assert m["tactical_diameter_L"] == pytest.approx(1.179, abs=0.01)
    assert m["steady_speed_m_s"] / m["approach_speed_m_s"] == pytest.approx(0.4335, abs=0.005)
    lam_t = math.sqrt(params.length / 1.255)
    assert m["steady_yaw_rate_deg_s"] * lam_t == pytest.approx(17.95, abs=0.1)


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()])
def test_zigzag_10_10_regression(params):
    m = zigzag(params, surge_fraction=0.2).metrics
    assert m["swing_checked"] == 1.0
    assert m["first_overshoot_deg"] == pytest.approx(16.0, abs=0.3)
    assert m["second_overshoot_deg"] == pytest.approx(33.3, abs=0.5)
    lam_t = math.sqrt(params.length / 1.255)
    assert m["period_s"] / lam_t == pytest.approx(26.46, abs=0.3)


def test_zigzag_at_full_speed_reports_course_instability():
    m = zigzag(cybership2()).metrics
    assert m["swing_checked"] == 0.0
    assert math.isnan(m["first_overshoot_deg"])


def test_thrust_step_converges_to_analytic_speed():
    r = thrust_step(cybership2())
    m = r.metrics
    assert m["final_speed_m_s"] == pytest.approx(m["steady_speed_analytic_m_s"], rel=1e-3)
    assert m["t63_s"] == pytest.approx(5.70, abs=0.05)
    assert np.all(np.diff(r.x[:, 3]) >= -1e-12)  # monotone speed-up, no overshoot
