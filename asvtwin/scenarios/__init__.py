"""Scenarios: the YAML format (pydantic-validated), its loader and the shipped library.

Examples
--------
>>> from asvtwin.scenarios import library_names, load_library
>>> "head_on" in library_names()
True
>>> s = load_library("head_on", check_scene=False)
>>> s.own_ship.controller, len(s.targets)
('los_psf', 1)
"""

from __future__ import annotations

from asvtwin.scenarios.loader import (
    DEFAULT_SCENE,
    check_geometry,
    default_scenario,
    file_problems,
    geometry_problems,
    library_names,
    library_path,
    load_any,
    load_library,
    load_scenario,
    parse_scenario,
    resolve_scene,
)
from asvtwin.scenarios.schema import (
    AIS_SHIP_TYPE,
    CONTROLLERS,
    SCENARIO_FORMAT,
    AisReplay,
    AisSpec,
    Colreg,
    ConstantVelocity,
    CriteriaSpec,
    EnvironmentSpec,
    GeoPosition,
    NedPosition,
    OwnShipSpec,
    Position,
    RatesSpec,
    Scenario,
    SensorSpec,
    TargetSpec,
    Waypoints,
    WeatherSpec,
    course_keeping_speed_m_s,
    scenario_json_schema,
    top_speed_m_s,
)

__all__ = [
    "AIS_SHIP_TYPE",
    "CONTROLLERS",
    "DEFAULT_SCENE",
    "SCENARIO_FORMAT",
    "AisReplay",
    "AisSpec",
    "Colreg",
    "ConstantVelocity",
    "CriteriaSpec",
    "EnvironmentSpec",
    "GeoPosition",
    "NedPosition",
    "OwnShipSpec",
    "Position",
    "RatesSpec",
    "Scenario",
    "SensorSpec",
    "TargetSpec",
    "Waypoints",
    "WeatherSpec",
    "check_geometry",
    "course_keeping_speed_m_s",
    "default_scenario",
    "file_problems",
    "geometry_problems",
    "library_names",
    "library_path",
    "load_any",
    "load_library",
    "load_scenario",
    "parse_scenario",
    "resolve_scene",
    "scenario_json_schema",
    "top_speed_m_s",
]
