"""Rollouts of library encounters: determinism, worker split, filter on vs off, the
recommendation and its COLREG rule, and the filter economy against the full rate."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from asvtwin.errors import ParameterError
from asvtwin.scenarios import load_library, resolve_scene
from asvtwin.whatif import (
    RolloutConfig,
    ask,
    encounters,
    fork_scenario,
    parse_alternative,
)


def _alts(*specs):
    return [parse_alternative(s) for s in specs]


@pytest.fixture(scope="module")
def crossing():
    sc = load_library("model_scale_crossing")
    return fork_scenario(sc), resolve_scene(sc).land


def test_fork_of_library_crossing_is_a_give_way_crossing(crossing):
    f, _ = crossing
    (e,) = encounters(f)
    assert (e.kind, e.rule) == ("crossing_give_way", 15)
    assert e.cpa_m < 0.1 and 35.0 < e.tcpa_s < 45.0  # the file: "after about 39 s"


def test_filter_lowers_collision_probability_and_keep_course_is_not_recommended(crossing):
    f, land = crossing
    alts = _alts("route", "route+filter_off", "keep_course+filter_off", "starboard:40+filter_off")
    ans = ask(f, alts, rollouts=12, seed=3, config=RolloutConfig(horizon_s=60.0), land=land)
    by = {a.label: a for a in ans.alternatives}
    assert by["route+filter_off"].collisions >= 4  # a collision course without the filter
    assert by["route"].collisions == 0
    assert by["route"].p_collision < by["route+filter_off"].p_collision
    assert by["route"].interventions > 0
    # with the filter in the loop only filter-on decisions are candidates; ask again as
    # a navigator whose filter is off (the fork's filter state decides)
    import dataclasses

    f_off = dataclasses.replace(f, filter_enabled=False)
    rec = ask(f_off, alts, rollouts=12, seed=3, config=RolloutConfig(horizon_s=60.0),
              land=land).recommendation
    assert by["keep_course+filter_off"].collisions >= 4
    assert rec.label == "starboard:40+filter_off"
    assert rec.rule == 15 and "rule 15" in rec.reason and "starboard" in rec.reason


def test_same_seed_same_answer_for_one_and_two_workers(crossing):
    f, land = crossing
    alts = _alts("route", "port:30+filter_off")
    cfg = RolloutConfig(horizon_s=20.0, share_group=2)  # two groups of futures share plans
    a = ask(f, alts, rollouts=4, seed=5, config=cfg, land=land)
    b = ask(f, alts, rollouts=4, seed=5, config=cfg, land=land)
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=ctx) as ex:
        c = ask(f, alts, rollouts=4, seed=5, config=cfg, land=land, executor=ex, workers=2)
    assert c.timing["filters_built"] > 0
    for other in (b, c):
        assert np.array_equal(a.result.min_distance_m, other.result.min_distance_m)
        assert np.array_equal(a.result.track, other.result.track)
        assert np.array_equal(a.result.interventions, other.result.interventions)
    d = ask(f, alts, rollouts=4, seed=6, config=cfg, land=land)
    assert not np.array_equal(a.result.min_distance_m, d.result.min_distance_m)


def test_bad_alternatives_are_refused():
    with pytest.raises(ParameterError, match=r"starboard:200.*\[1, 120\]"):
        parse_alternative("starboard:200")
    with pytest.raises(ParameterError, match="unknown name 'hard_a_port'"):
        parse_alternative("hard_a_port")
    with pytest.raises(ParameterError, match="only modifier"):
        parse_alternative("route+psf_on")


def test_filter_economy_agrees_with_the_full_rate_filter(crossing):
    """The economy (filter only within reach, certified plans followed for 4 stages)
    against the twin's full 2 Hz filter on the same draws: each collision estimate inside
    the other's interval, the economy's closest approaches no nearer than the full rate's
    less 10 % of the safety distance, and at least 2× fewer filter calls. (Measured: the
    route's median closest approach agrees within 0.05 m; after a 40° turn the economy's
    futures pass 1.6 m wider, since the full-rate filter intervenes in the turn more often.)"""
    f, land = crossing
    alts = _alts("route", "starboard:40")
    runs = {econ: ask(f, alts, rollouts=6, seed=8, land=land,
                      config=RolloutConfig(horizon_s=60.0, economy=econ))
            for econ in (True, False)}
    for i in range(len(alts)):
        e, full = runs[True].alternatives[i], runs[False].alternatives[i]
        assert e.p_collision_ci[0] <= full.p_collision <= e.p_collision_ci[1]
        assert full.p_collision_ci[0] <= e.p_collision <= full.p_collision_ci[1]
        assert e.min_distance_m[0] > full.min_distance_m[0] - 0.1 * 1.255
        assert e.min_distance_m[0] > 1.255 - 0.1  # the filter's d_safe holds in both
    assert runs[True].timing["filter_calls"] * 2 <= runs[False].timing["filter_calls"]


def _economy_against_full_rate(f, alts, *, rollouts, seed, land, horizon_s, d_safe=87.85):
    """Ask the same question with the economy and at the full filter rate; each collision
    estimate lies inside the other's interval and the economy's 5 % closest approach is no
    nearer than the full rate's less a tenth of d_safe (88 m hull). Returns both answers."""
    runs = {econ: ask(f, alts, rollouts=rollouts, seed=seed, land=land,
                      config=RolloutConfig(horizon_s=horizon_s, economy=econ))
            for econ in (True, False)}
    for e, full in zip(runs[True].alternatives, runs[False].alternatives, strict=True):
        assert e.p_collision_ci[0] <= full.p_collision <= e.p_collision_ci[1]
        assert full.p_collision_ci[0] <= e.p_collision <= full.p_collision_ci[1]
        assert e.min_distance_m[0] > full.min_distance_m[0] - 0.1 * d_safe
    return runs


def test_filter_economy_agrees_with_the_full_rate_filter_at_full_scale():
    """The same comparison on the 88 m hull (the library's head-on, the coaster ~1 km ahead
    and closing at 5.4 m/s, tracked to 10 m and 0.1 m/s): the filter stage is 4.2 s there,
    so plans and fallbacks are held for whole stages and sibling futures share plans.
    (Measured, 4 futures × 90 s: 14 filter calls against 864; the route's closest
    approaches 419/431/433 m against 414/428/429 m, 5/50/95 %.)"""
    sc = load_library("head_on")
    f = fork_scenario(sc, at_s=240.0, position_std_m=10.0, velocity_std_m_s=0.1)
    land = resolve_scene(sc).land
    alts = _alts("route", "starboard:30")
    runs = _economy_against_full_rate(f, alts, rollouts=4, seed=1, land=land, horizon_s=90.0)
    d_safe = 87.85
    for e, full in zip(runs[True].alternatives, runs[False].alternatives, strict=True):
        # the economy's median closest approach is no nearer than the full rate's (less a
        # tenth of d_safe); it may be farther: since the full-scale solver's inputs are
        # scaled (2026-12-01) the full-rate filter re-plans at every call and passes
        # closer on the starboard alternative (434 m against the economy's 448 m)
        assert e.min_distance_m[1] > full.min_distance_m[1] - 0.1 * d_safe
    assert runs[False].alternatives[0].interventions > 0  # the full rate had work to do
    assert runs[True].timing["filter_calls"] * 5 <= runs[False].timing["filter_calls"]


def test_circle_slots_sized_to_the_fork_leave_the_filters_answer_unchanged():
    """The rollouts' filter has 4 circle slots for up to four targets (8 up to eight, the
    filter's 20 beyond) and the same answer as with 20 slots: the slots no target fills
    are dummies that never bind. (The full rate keeps the twin's filter settings.) Checked on a head-on and a crossing vessel
    at both hull scales (u0 within 1 % of the actuator range, the same fallback)."""
    import dataclasses

    from asvtwin.control import MovingObstacles, PsfConfig, SafetyFilter
    from asvtwin.vessel import cybership2, cybership2_full_scale
    from asvtwin.whatif import filter_config

    cfg = RolloutConfig()
    assert [filter_config(cfg, m).n_circles for m in (0, 1, 4, 5, 8, 9)] == [4, 4, 4, 8, 8, 20]
    full_rate = filter_config(RolloutConfig(economy=False), 1)
    assert (full_rate.n_circles, full_rate.uncertified_retries) == (
        PsfConfig().n_circles, PsfConfig().uncertified_retries)  # the twin's filter
    assert filter_config(cfg, 1).uncertified_retries == 0
    for p in (cybership2(), cybership2_full_scale()):
        L, v = p.length, 0.3 * (p.length / 1.255) ** 0.5
        sized = SafetyFilter(p, config=filter_config(cfg, 1))
        twin = SafetyFilter(p, config=dataclasses.replace(filter_config(cfg, 1), n_circles=20))
        assert sized.config.n_circles == 4 and twin.config.n_circles == 20
        x = [0.0, 0.0, 0.0, v, 0.0, 0.0]
        u_L = [0.5 * twin.u_ub[0], 0.0, 0.0]
        for pos, vel in (([6 * L, 0.0], [-v, 0.0]),           # head-on
                         ([4 * L, 3 * L], [0.0, -0.75 * v])):  # crossing from starboard
            answers = []
            for f in (sized, twin):
                f.reset()
                obs = MovingObstacles.constant_velocity([pos], [vel], [0.5 * L],
                                                        N=f.config.N, dt_s=f.config.dt_s)
                answers.append(f.filter(x, u_L, obs, t_s=0.0))
            a, b = answers
            assert not (a.passed_through or b.passed_through)  # both asked their solver
            assert a.fallback == b.fallback
            assert np.all(np.abs(a.u0 - b.u0) <= 0.01 * twin.u_range), (a.u0, b.u0)


def test_filter_economy_agrees_with_the_full_rate_on_the_benchmark_question():
    """The benchmark's question (head-on at 240 s, the coaster tracked to 0.5 ship
    lengths, as ``fork_scenario`` forks it): the economy with every step on (circle
    slots, no retry QP, sibling warm starts, certified fallbacks held) against the full
    2 Hz filter (the twin's settings) on the same draws. Each collision estimate lies inside the other's 95 % interval and the
    economy's 5 % closest approach is no nearer than the full rate's less 10 % of d_safe.
    Short in CI (2 futures × 60 s); ASVTWIN_FULL=1: 6 futures × 120 s. (Measured, 6 ×
    120 s: 30 filter calls against 1,728, 2.6 against 40 CPU s; the route's closest
    approaches 298/330/388 m against 270/305/389 m, 5/50/95 %: the economy's futures pass
    ~25 m wider, as they did before this session's steps, 297/330/394 m.)"""
    import os

    full_run = os.environ.get("ASVTWIN_FULL", "") not in ("", "0")
    R, H = (6, 120.0) if full_run else (2, 60.0)
    sc = load_library("head_on")
    f = fork_scenario(sc, at_s=240.0)
    land = resolve_scene(sc).land
    alts = _alts("route", "starboard:30")
    runs = _economy_against_full_rate(f, alts, rollouts=R, seed=2, land=land, horizon_s=H)
    assert runs[False].alternatives[0].interventions > 0
    assert runs[True].timing["filter_calls"] * 10 <= runs[False].timing["filter_calls"]
