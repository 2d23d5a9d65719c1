"""The shipped scenario library: real geometry (checked against the coast with shapely, not
the project's land mask), real encounters (classified by the COLREG module) and, once the
runtime runs them, each scenario's expected outcome."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point

from asvtwin.control.colreg import EncounterLimits, classify_encounters
from asvtwin.geo import default_scene
from asvtwin.scenarios import (
    ConstantVelocity,
    Scenario,
    Waypoints,
    default_scenario,
    library_names,
    library_path,
    load_library,
    resolve_scene,
)
from asvtwin.units import KNOT_M_S
from tests.conftest import full_run

NAMES = library_names()
REQUIRED = {
    "default", "head_on", "crossing_give_way", "crossing_stand_on", "overtaking",
    "being_overtaken", "multi_vessel", "restricted_water", "trondheim_harbour_approach",
    "trondheim_ferry_crossing", "trondheim_fjord_transit", "model_scale_crossing",
}
#: The encounter each classic scenario stages, by the COLREG classifier's geometry at t = 0.
ENCOUNTER = {
    "head_on": ["head_on"],
    "crossing_give_way": ["crossing_give_way"],
    "crossing_stand_on": ["crossing_stand_on"],
    "overtaking": ["overtaking"],
    "being_overtaken": ["overtaken"],
    "multi_vessel": ["head_on", "crossing_give_way", "overtaking"],
    "model_scale_crossing": ["crossing_give_way"],
    "trondheim_ferry_crossing": ["crossing_stand_on"],
    "restricted_water": ["head_on"],
}
MUNKHOLMEN = (63.4515, 10.3836)  # lat, lon [deg]


@pytest.fixture(scope="module")
def scene():
    return default_scene()


def _lonlat(scene, s: Scenario, pos) -> tuple[float, float]:
    n, e = pos.to_ned(scene.frame)
    lat, lon = scene.frame.to_wgs84(n, e)
    return float(lon), float(lat)


def test_library_has_every_required_scenario():
    assert REQUIRED <= set(NAMES)
    assert library_path("head_on").name == "head_on.yaml"


@pytest.mark.parametrize("name", NAMES)
def test_each_scenario_states_its_expected_outcome(name):
    s = load_library(name)
    assert s.name == name
    assert "Expected" in s.description or name == "default"
    c = s.criteria
    assert c.min_distance_targets_m > 0 and c.min_distance_land_m > 0
    if name != "default":
        assert c.goal_reached
        route = [s.own_ship.start, *s.own_ship.route]
        frame = resolve_scene(s).frame
        pts = np.array([p.to_ned(frame) for p in route])
        length = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
        # the route can be sailed in the time given, with >= 10 % to spare for avoiding
        assert length / (s.own_ship.cruise_speed_kn * KNOT_M_S) < s.duration_s / 1.1


@pytest.mark.parametrize("name", NAMES)
def test_geometry_is_on_water_by_an_independent_coast_test(scene, name):
    """Starts, waypoints and legs in lon/lat against the scene's coast polygons (shapely)."""
    s = load_library(name)
    land = scene.land_lonlat
    box = scene.bounds.polygon()

    def check_route(points, what):
        ll = [_lonlat(scene, s, p) for p in points]
        for k, q in enumerate(ll):
            assert box.contains(Point(q)), f"{what}[{k}] outside the scene"
            assert not land.contains(Point(q)), f"{what}[{k}] on land"
        if len(ll) > 1:
            assert not LineString(ll).intersects(land), f"{what} crosses land"

    check_route([s.own_ship.start, *s.own_ship.route], "own ship")
    for t in s.targets:
        b = t.behaviour
        route = list(b.route) if isinstance(b, Waypoints) else []
        check_route([t.start, *route], t.name)
        if isinstance(b, ConstantVelocity):
            p0 = t.start.to_ned(scene.frame)
            psi = math.radians(t.heading_deg)
            p1 = p0 + t.speed_kn * KNOT_M_S * s.duration_s * np.array([math.cos(psi),
                                                                         math.sin(psi)])
            track = shapely.transform(LineString([p0, p1]), scene.frame.points_to_lonlat)
            assert not track.intersects(land), f"{t.name} runs aground within the run"


def test_munkholmen_is_in_the_scene_and_the_approach_passes_east_of_it(scene):
    lat, lon = MUNKHOLMEN
    assert scene.land_lonlat.contains(Point(lon, lat))  # the island is land in the scene
    s = load_library("trondheim_harbour_approach")
    m = np.array(scene.frame.to_ned(lat, lon), dtype=float)
    pts = np.array([p.to_ned(scene.frame) for p in [s.own_ship.start, *s.own_ship.route]])
    path = LineString(pts)
    assert 300.0 < path.distance(Point(m)) < 1000.0  # passes it, well clear
    # the leg abreast of the island lies east of it
    k = int(np.argmin(np.abs(pts[:, 0] - m[0])))
    assert pts[k, 1] > m[1]


@pytest.mark.parametrize("name", sorted(ENCOUNTER))
def test_encounters_are_the_ones_named(name):
    """The COLREG classifier sees the named situation at t = 0, and left alone (own ship
    on its route at cruise speed, targets on their course) the ships would come closer
    than the scenario's criterion: the encounter demands action."""
    s = load_library(name)
    frame = resolve_scene(s).frame
    own = s.own_ship
    p0 = own.start.to_ned(frame)
    w1 = own.route[0].to_ned(frame)
    chi = math.atan2(*(w1 - p0)[::-1])
    U = own.cruise_speed_kn * KNOT_M_S
    x = np.array([p0[0], p0[1], chi, U, 0.0, 0.0])
    pos = np.array([t.start.to_ned(frame) for t in s.targets])
    vel = np.array([t.speed_kn * KNOT_M_S * np.array([math.cos(math.radians(t.heading_deg)),
                                                     math.sin(math.radians(t.heading_deg))])
                    for t in s.targets])
    enc = classify_encounters(x, pos, vel, limits=EncounterLimits.for_length(own.length_m))
    assert sorted(enc.geometry) == sorted(ENCOUNTER[name])
    assert enc.cpa_m.min() < s.criteria.min_distance_targets_m
    assert (enc.tcpa_s > 0).all()


def test_default_is_the_documented_embedded_default():
    s = default_scenario()
    assert s.scene == "trondheim" and s.ais.mode == "synthetic" and s.weather.mode == "fixture"
    assert s.own_ship.vessel == "cybership2_full_scale" and s.own_ship.controller == "rl_psf"
    assert len(s.targets) >= 2


# --------------------------------------------------------------------------- outcomes

HAVE_RUNTIME = importlib.util.find_spec("asvtwin.twin.runtime") is not None
needs_runtime = pytest.mark.skipif(not HAVE_RUNTIME,
                                   reason="asvtwin.twin.runtime is not available yet")


@needs_runtime
def test_model_scale_crossing_gives_way_and_completes_its_route():
    """Short real version (default; about 20 s of CPU): the model-scale crossing run whole
    through the twin. The own ship gives way to the model crossing from starboard, keeps
    the distance criterion, returns to its 20 m route and reaches its end (it wandered
    23 m off before the tracker was Froude-scaled and the give-way layer added)."""
    from asvtwin.twin.runtime import run_scenario

    s = load_library("model_scale_crossing")
    summary = run_scenario(s, seed=s.seed, record=False)
    text = summary.text()
    assert summary.collisions == 0 and summary.groundings == 0, text
    for key, crit in summary.criteria.items():
        assert crit["pass"], f"model_scale_crossing: criterion {key} failed\n{text}"
    assert summary.max_cte_m < 10.0, text  # 8 L: it gives way to starboard, then returns


@needs_runtime
@pytest.mark.parametrize("name", ["default", "model_scale_crossing"])
def test_the_trained_policy_behind_the_filter_passes(name):
    """The embedded default runs the shipped PPO policy through the safety filter (rl_psf);
    it, and the model-scale crossing under rl_psf, pass every criterion over the whole
    run with no contact (the library comparison with los_psf: docs/rl.md)."""
    from asvtwin.twin.runtime import run_scenario

    s = load_library(name).with_controller("rl_psf")
    summary = run_scenario(s, seed=s.seed, record=False)
    text = summary.text()
    assert summary.controller == "rl_psf", text
    assert summary.collisions == 0 and summary.groundings == 0, text
    for key, crit in summary.criteria.items():
        assert crit["pass"], f"{name} under rl_psf: criterion {key} failed\n{text}"
    assert summary.filter_calls > 0 and summary.interventions > 0, text  # the filter acted


#: Library scenarios measured to miss one criterion with the twin's guidance as it stands
#: (docs/scenarios.md: the studies of 2026-11-30, and why the twin does not use the
#: 2026-12-01 options): name -> (the criterion or criteria missed, reason). Pinned as strict expected
#: failures of the full run: each must miss only that criterion, with no contact; a fix
#: turns the xfail into a failure, to be updated here.
KNOWN_MISSES: dict[str, tuple[str | tuple[str, ...], str]] = {
    # "multi_vessel" (LOS through the filter) misses its route in its 1,400 s: the stage-N
    # braking clearance (the plan must end d_safe plus the braking distance, up to ~600 m,
    # clear of each track's 95 % circle) turns the own ship away from the fishing boat
    # and the coaster while their CPA is still 400-700 m, and LOS, pointing back at the
    # route, meets the filter again. Pinned 2026-12-02, passed at seed 15 from the
    # velocity slacks (2026-12-03 morning; 942 m off the route at t = 1,380 s), pinned
    # again with the twin's HPIPM mode SPEED_ABS (missed at seeds 15 and 11; the
    # default controller, rl_psf, completes it at both); docs/scenarios.md
    "multi_vessel": ("goal_reached", ("LOS and the filter's braking clearance circle "
                                      "the slow vessel ahead: the route is not completed "
                                      "in 1,400 s")),
}


def _outcome_params():
    out = []
    for n in NAMES:
        if n == "default":
            continue
        if n in KNOWN_MISSES:
            out.append(pytest.param(n, marks=pytest.mark.xfail(
                strict=True, raises=AssertionError, reason=KNOWN_MISSES[n][1])))
        else:
            out.append(n)
    return out


@needs_runtime
@pytest.mark.slow
@pytest.mark.parametrize("name", _outcome_params())
def test_expected_outcome(name):
    """Run the scenario through the twin for its whole duration and check every criterion
    it states (ASVTWIN_FULL=1). A scenario of KNOWN_MISSES must have no contact and miss
    only its pinned criterion."""
    if not full_run():
        pytest.skip("full scenario runs: set ASVTWIN_FULL=1")
    from asvtwin.twin.runtime import run_scenario

    s = load_library(name)
    summary = run_scenario(s, seed=s.seed, record=False)
    text = summary.text()
    if summary.collisions or summary.groundings:  # pytest.fail: never an expected failure
        pytest.fail(f"{name}: {summary.collisions} collisions, {summary.groundings} "
                    f"groundings\n{text}")
    if name in KNOWN_MISSES:  # everything but the pinned criteria holds (not an xfail)
        missed = KNOWN_MISSES[name][0]
        missed = (missed,) if isinstance(missed, str) else missed
        for key, crit in summary.criteria.items():
            if key not in missed and not crit["pass"]:
                pytest.fail(f"{name}: criterion {key} failed\n{text}")
    for key, crit in summary.criteria.items():
        assert crit["pass"], f"{name}: criterion {key} failed\n{text}"
    assert summary.passed, text


def test_every_library_file_validates_against_the_exported_json_schema():
    """What an editor sees: the JSON Schema accepts every shipped file (an independent
    validator, jsonschema, on the same files)."""
    jsonschema = pytest.importorskip("jsonschema")
    import datetime as dt

    from ruamel.yaml import YAML

    from asvtwin.scenarios import scenario_json_schema

    def jsonable(v):
        if isinstance(v, dict):
            return {k: jsonable(x) for k, x in v.items()}
        if isinstance(v, list):
            return [jsonable(x) for x in v]
        return v.isoformat() if isinstance(v, dt.datetime) else v

    validator = jsonschema.Draft202012Validator(scenario_json_schema())
    for name in NAMES:
        doc = jsonable(YAML(typ="safe").load(library_path(name).read_text()))
        errors = [e.message for e in validator.iter_errors(doc)]
        assert not errors, f"{name}: {errors}"
