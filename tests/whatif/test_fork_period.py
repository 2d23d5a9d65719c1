"""A fork carries the twin's filter period, and the rollouts filter at it: a what-if
asked of the default scene (filter every 4 s, once per plan stage of the 88 m hull)
rolls its futures out with the filter the twin has, not at the schema's 2 Hz."""

from __future__ import annotations

import math

import pytest

from asvtwin.scenarios import default_scenario, load_library, resolve_scene
from asvtwin.twin import Twin
from asvtwin.whatif import RolloutConfig, ask, fork, fork_scenario, parse_alternative


def test_a_fork_of_the_default_twin_rolls_out_with_its_filter_period() -> None:
    sc = default_scenario()
    twin = Twin(sc, record_path=None)
    for _ in range(30):
        twin.step()
    data = twin.latest_bytes()
    assert data is not None
    f = fork(data)
    assert f.filter_period_s == pytest.approx(1.0 / sc.rates.filter_hz) == pytest.approx(4.0)
    # the rollouts take it unless the config sets one; without it, 0.5 s (at least dt)
    L = f.params.length
    assert RolloutConfig().resolved(L, f.filter_period_s)[1] == pytest.approx(4.0)
    assert RolloutConfig(filter_period_s=1.0).resolved(L, f.filter_period_s)[1] == 1.0
    dt, fp = RolloutConfig().resolved(L)
    assert fp == pytest.approx(max(0.5, dt))
    ans = ask(f, [parse_alternative("route")], rollouts=2, seed=0,
              config=RolloutConfig(horizon_s=20.0), land=resolve_scene(sc).land)
    assert ans.timing["filter_period_s"] == pytest.approx(4.0)


def test_a_fork_of_a_library_scenario_takes_its_2_hz() -> None:
    f = fork_scenario(load_library("head_on"))
    assert f.filter_period_s == pytest.approx(0.5)
    g = fork_scenario(load_library("model_scale_crossing"))
    assert g.filter_period_s == pytest.approx(0.5)
    # a fork built without it (or from a snapshot recorded before the field) says NaN,
    # and the rollouts use their own default
    h = type(g)(t_s=0.0, vessel="cybership2", own_state=g.own_state, route=g.route,
                cruise_speed_m_s=1.0)
    assert math.isnan(h.filter_period_s)
    assert RolloutConfig().resolved(1.255, h.filter_period_s)[1] == pytest.approx(0.5)
