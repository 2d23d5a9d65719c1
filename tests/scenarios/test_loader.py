"""Scenario files: YAML 1.2 reading, validation messages (file, line, field, range), paths."""

from __future__ import annotations

import textwrap
from datetime import UTC, datetime

import numpy as np
import pytest

from asvtwin.errors import AsvTwinError, ScenarioError
from asvtwin.geo import default_scene
from asvtwin.scenarios import (
    GeoPosition,
    NedPosition,
    Scenario,
    default_scenario,
    load_scenario,
    parse_scenario,
    scenario_json_schema,
    top_speed_m_s,
)

BASE = textwrap.dedent(
    """\
    name: test
    own_ship:
      start: {north_m: 3000, east_m: -2000}
      heading_deg: 10
      route: [{north_m: 4000, east_m: -2000}]
    targets:
      - name: NO
        mmsi: 257000001
        start: {north_m: 3500, east_m: -1500}
        heading_deg: 270
        speed_kn: 3
    """
)


def _err(text: str, **kw) -> str:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(text, "t.yaml", **kw)
    return str(info.value)


def test_minimal_file_gets_documented_defaults():
    s = parse_scenario(BASE, "t.yaml")
    assert s.scene == "trondheim"
    assert s.start_time_utc == datetime(2024, 11, 20, 11, 0, tzinfo=UTC)
    assert s.own_ship.vessel == "cybership2_full_scale"
    assert s.own_ship.controller == "los_psf"
    assert s.ais.mode == "synthetic" and s.weather.mode == "fixture"
    assert s.targets[0].behaviour.kind == "constant_velocity"
    assert s.targets[0].ais_ship_type == 70


def test_yaml_12_keeps_norwegian_strings():
    # YAML 1.1 (PyYAML) reads NO as False and 12:30 as 750 (sexagesimal)
    s = parse_scenario(BASE.replace("name: test", "name: '12:30'").replace(
        "description", "x") + "description: 12:30\n", "t.yaml")
    assert s.targets[0].name == "NO"
    assert s.description == "12:30"


def test_error_names_file_line_field_range_and_value():
    msg = _err(BASE.replace("heading_deg: 10", "heading_deg: 400"))
    assert msg.startswith("t.yaml:4: field 'own_ship.heading_deg'")
    assert ">= 0 and < 360" in msg and "[deg]" in msg and "actually: 400" in msg


def test_error_line_points_into_lists():
    text = BASE.replace("speed_kn: 3", "speed_kn: -3")
    msg = _err(text)
    line = text.splitlines().index("    speed_kn: -3") + 1
    assert msg.startswith(f"t.yaml:{line}: field 'targets[0].speed_kn'")
    assert ">= 0" in msg and "[kn]" in msg


def test_unknown_field_lists_the_allowed_ones():
    msg = _err(BASE.replace("heading_deg: 270", "heading: 270"))
    assert "unknown field 'targets[0].heading'" in msg and "heading_deg" in msg


def test_strict_types_refuse_yaml_strings_for_bools_and_numbers():
    text = BASE.replace("  heading_deg: 10\n", "  heading_deg: 10\n  astern: 'no'\n", 1)
    assert "field 'own_ship.astern'" in _err(text)
    text = BASE.replace("heading_deg: 10", "heading_deg: '10'")
    assert "field 'own_ship.heading_deg'" in _err(text)


def test_speed_above_the_froude_scaled_top_speed_is_refused():
    top_kn = top_speed_m_s(50.0) / (1852 / 3600)
    assert top_kn == pytest.approx(0.57 * np.sqrt(50.0 / 1.255) * 3600 / 1852)
    msg = _err(BASE.replace("speed_kn: 3", f"speed_kn: {top_kn + 0.1:.2f}"))
    assert "targets[0]" in msg and f"{top_kn:.2f} kn" in msg


def test_several_errors_reported_together():
    text = BASE.replace("heading_deg: 10", "heading_deg: -1").replace("speed_kn: 3", "speed_kn: x")
    msg = _err(text)
    assert "2 problems" in msg and "own_ship.heading_deg" in msg and "targets[0].speed_kn" in msg


def test_position_forms_and_conversion():
    frame = default_scene().frame
    geo = GeoPosition(lat=63.4515, lon=10.3836)
    n, e = frame.to_ned(63.4515, 10.3836)
    np.testing.assert_allclose(geo.to_ned(frame), [float(n), float(e)], atol=1e-9)
    assert NedPosition(north_m=1.0, east_m=2.0).to_ned(frame).tolist() == [1.0, 2.0]
    msg = _err(BASE.replace("{north_m: 4000, east_m: -2000}", "{lat: 63.5, east_m: 3}"))
    assert "own_ship.route[0]" in msg


def test_geometry_on_land_is_refused_with_line():
    # Munkholmen (63.4515 N, 10.3836 E) is an island of the scene
    text = BASE.replace("{north_m: 3000, east_m: -2000}", "{lat: 63.4515, lon: 10.3836}")
    msg = _err(text)
    assert "t.yaml:3: field 'own_ship.start': position (north 613 m, east -319 m) is on land" in msg
    parse_scenario(text, "t.yaml", check_scene=False)  # the schema alone accepts it


def test_leg_across_land_and_target_running_aground():
    text = BASE.replace("{north_m: 4000, east_m: -2000}", "{north_m: -1200, east_m: -2000}")
    assert "crosses land" in _err(text)
    text = BASE.replace("heading_deg: 270", "heading_deg: 180") + "duration_s: 6000\n"
    msg = _err(text)
    assert "targets[0].heading_deg" in msg and "reaches land" in msg


def test_relative_paths_start_from_the_file(tmp_path):
    (tmp_path / "log.nmea").write_text("")
    f = tmp_path / "s.yaml"
    f.write_text(BASE + "ais: {mode: file, path: log.nmea}\n")
    s = load_scenario(f)
    assert s.ais.path == str(tmp_path / "log.nmea")


def test_unreadable_and_empty_files(tmp_path):
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.yaml")
    (tmp_path / "e.yaml").write_text("")
    with pytest.raises(ScenarioError, match="must be a YAML mapping"):
        load_scenario(tmp_path / "e.yaml")
    with pytest.raises(ScenarioError, match=r"x.yaml:2: not valid YAML"):
        parse_scenario("name: a\nname: b\n", "x.yaml")


def test_scenario_error_is_a_value_error():
    assert issubclass(ScenarioError, AsvTwinError) and issubclass(ScenarioError, ValueError)


def test_models_are_frozen():
    s = parse_scenario(BASE, "t.yaml")
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="frozen"):
        s.seed = 3  # type: ignore[misc]


def test_json_schema_validates_what_pydantic_validates():
    jsonschema = pytest.importorskip("jsonschema")
    from ruamel.yaml import YAML

    schema = scenario_json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    v = jsonschema.Draft202012Validator(schema)
    doc = YAML(typ="safe").load(BASE)
    assert not list(v.iter_errors(doc))
    bad = YAML(typ="safe").load(BASE.replace("heading_deg: 10", "heading_deg: 400"))
    assert list(v.iter_errors(bad))
    bad = YAML(typ="safe").load(BASE.replace("heading_deg: 270", "colour: red"))
    assert list(v.iter_errors(bad))


def test_default_scenario_is_the_embedded_default():
    s = default_scenario()
    assert isinstance(s, Scenario)
    assert s.scene == "trondheim" and s.ais.mode == "synthetic" and s.weather.mode == "fixture"
    assert s.own_ship.vessel == "cybership2_full_scale" and s.own_ship.controller == "rl_psf"


def test_missing_files_are_named_with_their_line(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text(BASE + "ais: {mode: file, path: missing.nmea}\n"
                 "weather: {mode: file, path: forecast.json}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(f)
    msg = str(info.value)
    lines = f.read_text().splitlines()
    ais_line = next(i for i, t in enumerate(lines, 1) if t.startswith("ais:"))
    assert f"s.yaml:{ais_line}: field 'ais.path': no such file: {tmp_path / 'missing.nmea'}" in msg
    assert "field 'weather.path': no such file" in msg
