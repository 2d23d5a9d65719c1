"""The encounter set: its coverage, Froude scaling, and the filter through it.

By default a quick real subset runs on the fastest installed backend at both scales;
ASVTWIN_FULL=1 runs every case on every installed backend at both scales.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.control import PsfConfig, SafetyFilter, available_backends
from asvtwin.control.encounters import (
    SINGLE_KINDS,
    encounter_cases,
    random_vessel_cases,
    run_encounter,
)
from asvtwin.vessel import cybership2, cybership2_full_scale
from tests.conftest import full_run

TOL = 0.05  # closed-loop tolerance on d_safe: 2 % certification + model mismatch (lag)


def test_the_set_covers_the_classic_encounters():
    cases = encounter_cases()
    vessels = [c for c in cases if c.family.endswith("vessel")]
    assert len(vessels) == 22
    assert {len(c.target_r) for c in vessels} == {1, 2, 3}
    for k in SINGLE_KINDS:  # every kind alone and in company
        assert sum(k in c.name.split("+") for c in vessels) >= 4
    harbour = next(c for c in cases if c.name == "harbour_piers")
    assert len(harbour.coast) > 100
    assert {c.family for c in cases} >= {"1_vessel", "2_vessel", "3_vessel", "coast",
                                         "sudden"}


def test_scaling_is_froude():
    c = encounter_cases(include=("vessels",))[0]
    f = c.scaled(88.0)
    lam = 88.0 / 1.255
    np.testing.assert_allclose(f.target_p0, c.target_p0 * lam)
    np.testing.assert_allclose(f.target_v, c.target_v * math.sqrt(lam))
    assert f.duration_s == pytest.approx(c.duration_s * math.sqrt(lam))
    # the meeting point scales with it: target and own ship meet at the scaled time
    t = 50.0 * math.sqrt(lam)
    np.testing.assert_allclose(f.targets_at(t)[0], [f.cruise_m_s * t, 0.0], atol=1e-6)


def test_without_the_filter_every_vessel_encounter_collides():
    p = cybership2()
    for c in encounter_cases(include=("vessels", "sudden")):
        r = run_encounter(c, p, None)
        assert r.collisions >= 1, c.name


def test_random_encounters_are_reproducible_and_each_vessel_arrives():
    """The random cases are the same for the same seed, other for another, and every
    vessel reaches the own ship's unfiltered track point at the time and lateral offset
    its name records: without the filter most of them collide (a vessel 0.5 L off the
    track still touches a hull of length L)."""
    a, b = random_vessel_cases(12, 5), random_vessel_cases(12, 5)
    assert [c.name for c in a] == [c.name for c in b]
    assert all(np.array_equal(x.target_p0, y.target_p0) for x, y in zip(a, b, strict=True))
    assert [c.name for c in random_vessel_cases(12, 6)] != [c.name for c in a]
    for c in a:
        draws = c.name.split(":", 1)[1].split(",")
        assert len(draws) == len(c.target_r) in (1, 2, 3)
        for i, d in enumerate(draws):
            course, f, t, off = (float(v[1:]) for v in d.split("/"))
            U = c.cruise_m_s
            assert np.hypot(*c.target_v[i]) == pytest.approx(f * U, abs=0.005 * U)  # (rounded)
            assert math.degrees(math.atan2(c.target_v[i][1], c.target_v[i][0])) % 360 \
                == pytest.approx(course, abs=0.5)
            # where it is at its meeting time (rounded to the second in the name)
            meet = c.target_p0[i] + c.target_v[i] * t
            assert meet[1] == pytest.approx(off, abs=0.01 + f * U * 0.5)
            assert np.hypot(*(c.target_v[i] - np.array([U, 0.0]))) > 0.25 * U
    p = cybership2()
    hit = sum(run_encounter(c, p, None).collisions >= 1 for c in a)
    assert hit >= 9, hit
    with pytest.raises(ValueError):
        random_vessel_cases(-1, 0)


# Two random encounters the acados backend failed with three SQP-RTI steps per retry
# (docs/psf.md, "Random encounters"): (hull, seed, index). IPOPT keeps 0.982 and 1.014
# d_safe in them, with no fallback; since retries run the SQP towards convergence (up to
# 10 steps, the default) acados keeps 1.000 and 1.013.
RANDOM_FAILS = [(cybership2_full_scale, 1, 59), (cybership2, 3, 13)]


@pytest.mark.skipif("acados" not in available_backends(), reason="measured on acados")
@pytest.mark.parametrize(("hull", "seed", "k"), RANDOM_FAILS)
def test_random_encounters_that_short_retries_lost_keep_d_safe(hull, seed, k):
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend="acados"))
    assert psf.config.retry_rti_steps == 10
    r = run_encounter(random_vessel_cases(k + 1, seed)[k], p, psf)
    assert r.collisions == 0 and r.min_distance_m >= (1 - TOL) * psf.d_safe_m, r
    assert r.goal_reached, r


def _check(runs, d_safe):
    for r in runs:
        assert r.collisions == 0 and r.groundings == 0, r
        assert r.min_distance_m >= (1 - TOL) * d_safe, r
        assert r.min_distance_land_m >= (1 - TOL) * d_safe, r
        if r.goal_expected:
            assert r.goal_reached, r


QUICK = ("head_on", "crossing_starboard+overtaken", "harbour_piers", "sudden_rock_6m")


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_filter_through_a_quick_subset(hull):
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0]))
    names = QUICK if hull is cybership2 else QUICK[:2]
    runs = [run_encounter(c, p, psf) for c in encounter_cases() if c.name in names]
    assert len(runs) == len(names)
    _check(runs, psf.d_safe_m)
    head_on = next(r for r in runs if r.name == "head_on")
    assert head_on.starboard is True  # rule 14
    # the two vessel encounters need no fallback at model scale. At full scale (before
    # the solver's inputs were scaled: 13 and 14 fallbacks; the acados RTI steps stood
    # still) the head-on takes 2 in 155 calls since the velocity slacks are priced in
    # model-scale units: QPs stopped at HPIPM's iteration limit at its default
    # tolerance while the avoidance turns at the comfort bound (none with the twin's
    # qp_tol=1e-4; docs/psf.md)
    for r in runs:
        if r.name in QUICK[:2]:
            assert sum(r.fallbacks.values()) <= (0 if hull is cybership2 else 2), r
        # the yaw rate under fallbacks is part of the whole run's, and read only then
        assert r.yaw_rate_max_fallback <= r.yaw_rate_max, r
        if not r.fallbacks:
            assert r.yaw_rate_max_fallback == 0.0, r
    rock = [r for r in runs if r.name == "sudden_rock_6m"]
    assert all(r.fallbacks and r.yaw_rate_max_fallback > 0 for r in rock), rock


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_the_ship_rounds_a_headland_that_reaches_across_its_route(hull):
    """The route runs 1 m (model scale) inside a headland's tip. Before stage N's
    braking credit was part of the OCP the solver ended its plans moving beside the
    shore, where the certification asks d_safe + d_f √V_N, so no plan was certified:
    the ship lay stopped 1.85 m from the headland for the last 170 s (model scale: 377
    fallbacks; full scale: 53) and never reached the goal, on the RTI backend."""
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0]))
    case = next(c for c in encounter_cases(include=("coast",)) if c.name == "coast_headland")
    r = run_encounter(case, p, psf)
    _check([r], psf.d_safe_m)
    assert r.goal_reached
    assert sum(r.fallbacks.values()) <= 0.05 * r.calls, r.fallbacks  # measured 8 and 9


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_comfort_pass_through_keeps_the_avoidance_gentle(hull):
    """With comfort_pass_through the two quick vessel encounters turn within 1.3x the
    comfort bound (measured 0.57-1.12x; without it 1.33x and 1.52x at full scale before
    the velocity slacks were priced in model-scale units)."""
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0],
                                           comfort_pass_through=True))
    runs = [run_encounter(c, p, psf) for c in encounter_cases() if c.name in QUICK[:2]]
    assert len(runs) == 2
    _check(runs, psf.d_safe_m)
    for r in runs:
        assert not r.fallbacks, r
        assert r.yaw_rate_max_avoidance <= 1.3 * psf.nu_max[2], r


def test_the_full_scale_avoidance_keeps_the_comfort_bound_as_the_model_does():
    """The velocity bounds' slacks are priced in model-scale units (Froude): before, the
    88 m hull's yaw-rate excess cost 1/8.4 of the model's for the same relative excess,
    and its avoidance in the head-on and crossing-from-port encounters turned at 1.26
    and 1.45 times the comfort bound (measured 1.016 and 1.015 after), with the default
    configuration (no comfort pass-through)."""
    p = cybership2_full_scale()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0]))
    runs = [run_encounter(c, p, psf) for c in encounter_cases()
            if c.name in ("head_on", "crossing_port")]
    assert len(runs) == 2
    _check(runs, psf.d_safe_m)
    for r in runs:
        assert r.goal_reached, r
        assert r.yaw_rate_max_avoidance <= 1.1 * psf.nu_max[2], r


@pytest.mark.skipif("acados" not in available_backends(), reason="measured on acados")
def test_the_twins_comfort_options_keep_the_avoidance_within_the_bound():
    """The twin's filter with its comfort options (comfort pass-through, the yaw rate's
    slack priced ten times) on the 88 m hull: the three vessel encounters whose
    avoidance turned fastest with the twin's options alone (1.26, 1.21 and 1.19 times
    ν_max,r: a head-on with a vessel crossing from starboard and one overtaking the own
    ship, a crossing from port while overtaken, a fine crossing while overtaking) turn
    well within the bound (0.57, 0.78 and 0.57 measured), without a fallback, as safely
    and to the goal."""
    from asvtwin.twin.components import twin_filter_config

    p = cybership2_full_scale()
    psf = SafetyFilter(p, config=twin_filter_config("acados", comfort=True))
    names = ("crossing_starboard+overtaken+head_on", "crossing_port+overtaken",
             "fine_crossing+overtaking")
    runs = [run_encounter(c, p, psf) for c in encounter_cases() if c.name in names]
    assert len(runs) == 3
    _check(runs, psf.d_safe_m)
    for r in runs:
        assert r.goal_reached and not r.fallbacks, r
        assert r.interventions > 0, r  # (it did avoid)
        assert r.yaw_rate_max_avoidance <= 1.0 * psf.nu_max[2], r
        assert r.yaw_rate_max_fallback == 0.0, r


@pytest.mark.slow
@pytest.mark.skipif(not full_run(), reason="set ASVTWIN_FULL=1 for the whole set")
@pytest.mark.parametrize("backend", available_backends()[:2])
@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_filter_through_the_whole_set(hull, backend):
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=backend))
    runs = [run_encounter(c, p, psf) for c in encounter_cases()]
    _check(runs, psf.d_safe_m)
    stb = [r.starboard for r in runs if r.starboard is not None]
    assert sum(stb) >= 0.8 * len(stb)
