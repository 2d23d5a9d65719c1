"""COLREG classification: the textbook geometries, CPA/TCPA recomputed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.control.colreg import EncounterLimits, classify_encounters, cpa_tcpa
from asvtwin.errors import StateError

U = 4.0  # m/s, the 88 m ship's cruise


def _target(bearing_deg, range_m, course_deg, speed=U):
    """Position and velocity of a target at a bearing and range from the origin."""
    b, c = math.radians(bearing_deg), math.radians(course_deg)
    return ([range_m * math.cos(b), range_m * math.sin(b)],
            [speed * math.cos(c), speed * math.sin(c)])


@pytest.mark.parametrize("course, kind, rule", [
    (180.0, "head_on", 14),
    (183.0, "head_on", 14),
    (270.0, "crossing_give_way", 15),  # from starboard, heading west
    (90.0, "crossing_stand_on", 17),  # from port, heading east
    (0.0, "overtaking", 13),  # slower ship ahead, same course
    (0.0, "overtaken", 17),  # faster ship astern, same course
    (210.0, "crossing_give_way", 15),  # fine crossing from starboard (15° on the bow)
    (150.0, "crossing_stand_on", 17),  # fine crossing from port
])
def test_classic_geometries(course, kind, rule):
    # the target is placed where the two meet in 300 s if both keep their velocity
    own_v = np.array([U, 0.0])
    speed = 2.0 if kind == "overtaking" else (6.0 if kind == "overtaken" else U)
    c = math.radians(course)
    vt = speed * np.array([math.cos(c), math.sin(c)])
    t_meet = 300.0
    p_meet = own_v * t_meet
    pt = p_meet - vt * t_meet
    own = [0.0, 0.0, 0.0, U, 0.0, 0.0]
    enc = classify_encounters(own, [pt], [vt])
    b = math.degrees(enc.bearing_rad[0])
    assert enc.kind == (kind,), (b, enc.geometry)
    assert enc.rule[0] == rule
    assert enc.cpa_m[0] == pytest.approx(0.0, abs=1e-6)
    assert enc.tcpa_s[0] == pytest.approx(t_meet, rel=1e-9)


def test_cpa_tcpa_by_hand():
    # target 1000 m north, 100 m east, heading south at 5 m/s; own stopped: CPA 100 m
    # in 200 s
    cpa, tcpa = cpa_tcpa([[1000.0, 100.0]], [[-5.0, 0.0]])
    assert cpa[0] == pytest.approx(100.0)
    assert tcpa[0] == pytest.approx(200.0)
    # no relative motion: range kept, TCPA 0
    cpa, tcpa = cpa_tcpa([[30.0, 40.0]], [[0.0, 0.0]])
    assert (cpa[0], tcpa[0]) == (pytest.approx(50.0), 0.0)


def test_no_risk_is_none_but_geometry_is_kept():
    own = [0.0, 0.0, 0.0, U, 0.0, 0.0]
    # head-on geometry but 2 km abeam of each other: CPA beyond the limit
    p, v = _target(0.0, 5000.0, 180.0)
    p[1] += 2000.0
    enc = classify_encounters(own, [p], [v])
    assert enc.kind == ("none",) and enc.rule[0] == 0
    # receding: TCPA < 0
    enc2 = classify_encounters(own, [[-1000.0, 0.0]], [[-U, 0.0]])
    assert enc2.kind == ("none",) and enc2.tcpa_s[0] < 0
    # a target not underway has no course to classify against
    enc3 = classify_encounters(own, [[1000.0, 0.0]], [[0.0, 0.0]])
    assert enc3.geometry == ("none",)


def test_heading_not_north_and_batch():
    psi = math.radians(90.0)  # own heading east
    own = [100.0, 200.0, psi, U, 0.0, 0.0]
    # target due south of own (starboard beam when heading east), heading north
    enc = classify_encounters(own, [[-900.0, 1400.0], [1300.0, 1400.0]],
                              [[U, 0.0], [-U, 0.0]])
    assert math.degrees(enc.bearing_rad[0]) == pytest.approx(
        math.degrees(math.atan2(1200.0, -1000.0)) - 90.0)
    assert enc.kind[0] == "crossing_give_way" and enc.kind[1] == "crossing_stand_on"
    assert list(enc.starboard_expected) == [True, True]
    assert list(enc.give_way) == [True, False]


def test_limits_scale_and_validate():
    lim = EncounterLimits.for_length(1.255)
    lam = 1.255 / 88.0
    assert lim.cpa_limit_m == pytest.approx(463.0 * lam)
    assert lim.tcpa_limit_s == pytest.approx(600.0 * math.sqrt(lam))
    with pytest.raises(StateError, match="cpa_limit_m"):
        EncounterLimits(cpa_limit_m=-1.0)
    with pytest.raises(StateError, match="own_state"):
        classify_encounters([0, 0, np.nan, 0, 0, 0], [[1.0, 1.0]], [[0.0, 0.0]])
    with pytest.raises(StateError, match="positions and velocities"):
        classify_encounters([0, 0, 0, 0, 0, 0], [[1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0]])
