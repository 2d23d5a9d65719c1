"""The scenario schema: what a scenario file may say, with units and allowed ranges.

A scenario is one YAML file (see :mod:`asvtwin.scenarios.loader` and ``docs/scenarios.md``)
validated by these pydantic v2 models. Every model is frozen and forbids unknown fields, so
a typo (``heading: 90`` for ``heading_deg``) is an error, never silently ignored. Fields carry
their unit in the name (``_deg``, ``_kn``, ``_m``, ``_m_s``, ``_s``, ``_hz``) and their allowed
range in the model, so the exported JSON Schema (:func:`scenario_json_schema`) lets an editor
check a file as it is typed.

Validation is strict: a YAML string is never coerced into a number or a boolean
(``astern: "no"`` is an error, not ``False``).

Positions are either geographic ``{lat, lon}`` [deg, WGS84] or scene-frame ``{north_m,
east_m}`` [m, local NED at the scene origin]; :meth:`GeoPosition.to_ned` and
:meth:`NedPosition.to_ned` map both to the scene frame.

The speed limits come from the vessel model: every vessel is CyberShip II (Skjetne, Fossen
and Kokotović 2004) Froude-scaled to its length, whose top speed is about
:math:`0.57\\sqrt{L / 1.255\\,\\mathrm{m}}` m/s (:func:`top_speed_m_s`); a scenario asking a
9 m leisure boat for 20 kn is refused rather than run with a speed it can never reach.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
    model_validator,
)

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ScenarioError
from asvtwin.geo import LocalFrame
from asvtwin.units import KNOT_M_S

__all__ = [
    "AIS_SHIP_TYPE",
    "CONTROLLERS",
    "MODEL_LENGTH_M",
    "SCENARIO_FORMAT",
    "VESSELS",
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
    "course_keeping_speed_m_s",
    "scenario_json_schema",
    "top_speed_m_s",
]

#: Value of the optional ``format`` field understood by this version.
SCENARIO_FORMAT = "asvtwin.scenario/1"
#: Own-ship vessel models (``asvtwin.vessel.cybership2`` and ``cybership2_full_scale``).
VESSELS = ("cybership2", "cybership2_full_scale")
#: Own-ship controllers (``asvtwin.twin.controllers`` registry names).
Controller = Literal["manual", "los", "los_psf", "rl", "rl_psf"]
CONTROLLERS: tuple[str, ...] = get_args(Controller)
#: Length of CyberShip II [m], the hull every vessel is scaled from.
MODEL_LENGTH_M = 1.255
#: Length of each own-ship vessel [m] (the full-scale one is CyberShip II x 70).
VESSEL_LENGTH_M = {"cybership2": MODEL_LENGTH_M, "cybership2_full_scale": 70.0 * MODEL_LENGTH_M}
#: Top speed of CyberShip II at model scale [m/s] (steady surge under full thrust, ~0.57 m/s).
_MODEL_TOP_SPEED_M_S = 0.57
#: Fastest course-keeping speed of CyberShip II under the LOS autopilot [m/s] (model scale).
_COURSE_KEEPING_M_S = 0.30
#: AIS "type of ship and cargo" (ITU-R M.1371-5, table 53) for each target vessel type.
AIS_SHIP_TYPE = {
    "fishing": 30,
    "tug": 52,
    "sailing": 36,
    "pleasure": 37,
    "hsc": 40,
    "passenger": 60,
    "ferry": 60,
    "cargo": 70,
    "tanker": 80,
    "other": 90,
}

VesselType = Literal[
    "fishing", "tug", "sailing", "pleasure", "hsc", "passenger", "ferry", "cargo", "tanker",
    "other",
]



def course_keeping_speed_m_s(length_m: float) -> float:
    r"""Fastest speed [m/s] at which the own ship's autopilot holds a course, for a hull of
    ``length_m`` [m] with CyberShip II's own yaw actuator.

    Above about half its top speed the published CyberShip II model is course-unstable and
    its 0.15 N m yaw thruster cannot check a swing; the LOS autopilot holds a path up to
    :math:`0.30\sqrt{L/1.255}` m/s (0.30 m/s model scale, 2.5 m/s = 4.9 kn for the 88 m
    ship), measured in ``tests/guidance``.
    """
    return _COURSE_KEEPING_M_S * math.sqrt(length_m / MODEL_LENGTH_M)


def top_speed_m_s(length_m: float) -> float:
    """Top speed [m/s] of CyberShip II Froude-scaled to a hull of ``length_m`` [m].

    Froude similarity keeps :math:`U/\\sqrt{gL}`: :math:`U_{max} = 0.57\\sqrt{L/1.255}` m/s.
    """
    return _MODEL_TOP_SPEED_M_S * math.sqrt(length_m / MODEL_LENGTH_M)


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


Deg360 = Annotated[float, Field(ge=0.0, lt=360.0)]


# --------------------------------------------------------------------------- positions


class GeoPosition(_Model):
    """A WGS84 position: latitude and longitude [deg]."""

    lat: float = Field(ge=-89.9, le=89.9, description="geodetic latitude [deg]")
    lon: float = Field(ge=-180.0, le=180.0, description="longitude [deg]")

    def to_ned(self, frame: LocalFrame) -> _F8:
        """The position in the scene's local NED frame, ``[north_m, east_m]``, shape (2,)."""
        north, east = frame.to_ned(self.lat, self.lon)
        return np.array([float(north), float(east)])


class NedPosition(_Model):
    """A position in the scene's local NED frame [m] (x north, y east of the scene origin)."""

    north_m: float = Field(ge=-1e6, le=1e6, description="north of the scene origin [m]")
    east_m: float = Field(ge=-1e6, le=1e6, description="east of the scene origin [m]")

    def to_ned(self, frame: LocalFrame | None = None) -> _F8:
        """The position ``[north_m, east_m]``, shape (2,) (``frame`` is not needed)."""
        return np.array([self.north_m, self.east_m])


def _position_kind(v: Any) -> str | None:
    if isinstance(v, dict):
        if "lat" in v or "lon" in v:
            return "geo"
        if "north_m" in v or "east_m" in v:
            return "ned"
        return None
    if isinstance(v, GeoPosition):
        return "geo"
    if isinstance(v, NedPosition):
        return "ned"
    return None


#: ``{lat, lon}`` [deg] or ``{north_m, east_m}`` [m, scene NED].
Position = Annotated[
    Annotated[GeoPosition, Tag("geo")] | Annotated[NedPosition, Tag("ned")],
    Discriminator(
        _position_kind,
        custom_error_type="position",
        custom_error_message="a position must be {lat, lon} [deg] or {north_m, east_m} [m]",
    ),
]


# --------------------------------------------------------------------------- own ship


class OwnShipSpec(_Model):
    """The own ship: hull, start state, route and controller."""

    vessel: Literal["cybership2", "cybership2_full_scale"] = Field(
        default="cybership2_full_scale",
        description="hull: CyberShip II at model scale (1.255 m) or x70 (88 m supply vessel)",
    )
    start: Position = Field(description="start position")
    heading_deg: Deg360 = Field(default=0.0, description="initial heading, clockwise from north [deg]")
    speed_kn: float = Field(default=0.0, ge=0.0, description="initial surge speed [kn]")
    route: list[Position] = Field(
        default_factory=list, description="waypoints after the start, in order (may be empty)"
    )
    controller: Controller = Field(
        default="los_psf",
        description="manual (held thrust, set by the operator), los (LOS + autopilot), "
        "los_psf (LOS through the safety filter), rl, rl_psf (the trained policy)",
    )
    astern: bool = Field(default=False, description="whether astern (negative surge) thrust is allowed")
    cruise_speed_kn: float = Field(
        default=4.5, gt=0.0, description="speed along the route [kn]; for los/los_psf at most "
        "0.30 sqrt(L/1.255 m) m/s (4.88 kn full scale, 0.58 kn model scale)"
    )
    lookahead_m: float | None = Field(
        default=None, gt=0.0, description="LOS lookahead distance [m]; None: 2.5 ship lengths"
    )
    acceptance_radius_m: float | None = Field(
        default=None, gt=0.0, description="waypoint acceptance circle [m]; None: 2 ship lengths"
    )

    @property
    def length_m(self) -> float:
        """Hull length [m]."""
        return VESSEL_LENGTH_M[self.vessel]

    @property
    def lookahead(self) -> float:
        """The LOS lookahead distance in use [m]."""
        return self.lookahead_m if self.lookahead_m is not None else 2.5 * self.length_m

    @property
    def acceptance_radius(self) -> float:
        """The waypoint acceptance radius in use [m]."""
        if self.acceptance_radius_m is not None:
            return self.acceptance_radius_m
        return 2.0 * self.length_m

    @model_validator(mode="after")
    def _check(self) -> OwnShipSpec:
        top_kn = top_speed_m_s(self.length_m) / KNOT_M_S
        for name in ("speed_kn", "cruise_speed_kn"):
            value = getattr(self, name)
            if value > top_kn:
                raise ValueError(
                    f"{name} must be <= {top_kn:.2f} kn (top speed of {self.vessel}), "
                    f"actually: {value}"
                )
        if self.controller in ("los", "los_psf"):
            if not self.route:
                raise ValueError(f"controller {self.controller!r} needs a route of >= 1 waypoint")
            keep_kn = course_keeping_speed_m_s(self.length_m) / KNOT_M_S
            if self.cruise_speed_kn > keep_kn + 1e-9:
                raise ValueError(
                    f"cruise_speed_kn must be <= {keep_kn:.2f} kn for controller "
                    f"{self.controller!r}: above it {self.vessel} cannot hold a course with its "
                    f"own yaw thruster (the model is course-unstable), actually: "
                    f"{self.cruise_speed_kn}"
                )
        return self


# --------------------------------------------------------------------------- targets


class ConstantVelocity(_Model):
    """Hold the start heading and speed."""

    kind: Literal["constant_velocity"] = "constant_velocity"


class Waypoints(_Model):
    """Follow a route with LOS guidance at the target's speed."""

    kind: Literal["waypoints"] = "waypoints"
    route: list[Position] = Field(min_length=1, description="waypoints after the start")
    loop: bool = Field(default=False, description="go back to the first waypoint after the last")


class AisReplay(_Model):
    """Replay one vessel from an AIS log (NMEA lines, optionally with tag blocks)."""

    kind: Literal["ais_replay"] = "ais_replay"
    file: str = Field(min_length=1, description="AIS log; relative paths are from the scenario file")
    mmsi: int = Field(ge=100_000_000, le=999_999_999, description="the vessel to replay")


class Colreg(_Model):
    """A COLREG-minded target (rules 13-17): hold course, or give way to starboard."""

    kind: Literal["colreg"] = "colreg"
    role: Literal["give_way", "stand_on", "auto"] = Field(
        default="auto", description="give_way, stand_on, or auto (from the encounter geometry)"
    )
    route: list[Position] = Field(
        default_factory=list, description="waypoints to resume after the encounter (may be empty)"
    )


Behaviour = Annotated[ConstantVelocity | Waypoints | AisReplay | Colreg, Field(discriminator="kind")]


class TargetSpec(_Model):
    """Another vessel in the world."""

    name: str = Field(min_length=1, max_length=20, description="name (AIS allows 20 characters)")
    mmsi: int | None = Field(
        default=None, ge=100_000_000, le=999_999_999, description="9-digit MMSI, None: none"
    )
    ais_class: Literal["A", "B"] | None = Field(
        default="A", description="AIS transponder class; None: the vessel sends no AIS"
    )
    vessel_type: VesselType = Field(default="cargo", description="type of ship")
    length_m: float = Field(default=50.0, ge=1.0, le=400.0, description="length overall [m]")
    beam_m: float = Field(default=10.0, gt=0.0, le=70.0, description="beam [m]")
    start: Position | None = Field(
        default=None, description="start position (not used by ais_replay, required otherwise)"
    )
    heading_deg: Deg360 = Field(default=0.0, description="initial heading [deg]")
    speed_kn: float = Field(default=0.0, ge=0.0, description="speed [kn]")
    behaviour: Behaviour = Field(default_factory=ConstantVelocity, description="how it moves")

    @property
    def ais_ship_type(self) -> int:
        """AIS type of ship and cargo (ITU-R M.1371, table 53)."""
        return AIS_SHIP_TYPE[self.vessel_type]

    @model_validator(mode="after")
    def _check(self) -> TargetSpec:
        if self.beam_m >= self.length_m:
            raise ValueError(
                f"beam_m must be < length_m = {self.length_m}, actually: {self.beam_m}"
            )
        if self.ais_class is not None and self.mmsi is None:
            raise ValueError("mmsi is required when ais_class is set (the vessel sends AIS)")
        if self.behaviour.kind == "ais_replay":
            return self
        if self.start is None:
            raise ValueError(f"start is required for behaviour {self.behaviour.kind!r}")
        top_kn = top_speed_m_s(self.length_m) / KNOT_M_S
        if self.speed_kn > top_kn:
            raise ValueError(
                f"speed_kn must be <= {top_kn:.2f} kn (top speed of a {self.length_m:g} m hull), "
                f"actually: {self.speed_kn}"
            )
        return self


# --------------------------------------------------------------------------- inputs


class AisSpec(_Model):
    """Where AIS comes from."""

    mode: Literal["synthetic", "file", "live", "off"] = Field(
        default="synthetic",
        description="synthetic (the targets' own transmissions through the NMEA decoder), "
        "file (an NMEA log), live (tcp:// or udp:// feed), off",
    )
    path: str | None = Field(default=None, description="NMEA log for mode file")
    url: str | None = Field(default=None, description="tcp://host:port or udp://host:port for live")
    gnss_position_std_m: float | None = Field(
        default=None, ge=0.0, le=100.0,
        description="synthetic mode: GNSS position error of each transponder's fix, per axis, "
        "1 sigma [m] (white, seeded); null: 4 m for a full-scale own ship (95 % within "
        "ITU-R M.1371's 10 m 'high accuracy'), Froude-scaled for a model-scale one",
    )
    gnss_velocity_std_m_s: float | None = Field(
        default=None, ge=0.0, le=5.0,
        description="synthetic mode: GNSS velocity error per axis, 1 sigma [m/s] (SOG and COG "
        "are computed from the noisy velocity); null: 0.05 m/s at full scale, Froude-scaled",
    )

    @model_validator(mode="after")
    def _check(self) -> AisSpec:
        if self.mode == "file" and not self.path:
            raise ValueError("path is required when mode is 'file'")
        if self.mode == "live":
            if not self.url:
                raise ValueError("url is required when mode is 'live'")
            scheme, _, rest = self.url.partition("://")
            host, _, port = rest.rpartition(":")
            if scheme not in ("tcp", "udp") or not host or not port.isdigit():
                raise ValueError(
                    f"url must be tcp://host:port or udp://host:port, actually: {self.url!r}"
                )
            if not 1 <= int(port) <= 65535:
                raise ValueError(f"url port must be in [1, 65535], actually: {port}")
        return self


class WeatherSpec(_Model):
    """Where the weather comes from."""

    mode: Literal["fixture", "file", "live"] = Field(
        default="fixture",
        description="fixture (the bundled synthetic Trondheim forecast, authored for asvtwin: not "
        "MET Norway data), file "
        "(a locationforecast JSON), live (api.met.no)",
    )
    path: str | None = Field(default=None, description="forecast JSON for mode file")

    @model_validator(mode="after")
    def _check(self) -> WeatherSpec:
        if self.mode == "file" and not self.path:
            raise ValueError("path is required when mode is 'file'")
        return self


class EnvironmentSpec(_Model):
    """Current, wind and waves acting on the vessels."""

    current_speed_m_s: float = Field(default=0.0, ge=0.0, le=5.0, description="current speed [m/s]")
    current_to_deg: Deg360 = Field(default=0.0, description="direction the current sets to [deg]")
    wind_speed_m_s: float | None = Field(
        default=None, ge=0.0, le=60.0, description="wind speed [m/s]; None: from the weather"
    )
    wind_from_deg: Deg360 | None = Field(
        default=None, description="direction the wind blows from [deg]; None: from the weather"
    )
    waves: bool = Field(default=False, description="slowly varying wave drift on or off")

    @model_validator(mode="after")
    def _check(self) -> EnvironmentSpec:
        if (self.wind_speed_m_s is None) != (self.wind_from_deg is None):
            raise ValueError("wind_speed_m_s and wind_from_deg are set together or both left out")
        return self


class SensorSpec(_Model):
    """The own ship's LiDAR."""

    lidar_rays: int = Field(default=360, ge=8, le=3600, description="rays per scan")
    lidar_range_m: float = Field(default=500.0, gt=0.0, le=5000.0, description="maximum range [m]")
    lidar_noise_m: float = Field(default=0.05, ge=0.0, le=10.0, description="range noise std [m]")
    lidar_rate_hz: float = Field(default=10.0, gt=0.0, le=50.0, description="scan rate [Hz]")


class RatesSpec(_Model):
    """How often each component runs [Hz]; none may run faster than the simulation."""

    sim_hz: float = Field(default=20.0, ge=1.0, le=200.0, description="world simulation step rate")
    tracker_hz: float = Field(default=10.0, gt=0.0, le=200.0, description="tracker update rate")
    observer_hz: float = Field(default=10.0, gt=0.0, le=200.0, description="observer rate")
    controller_hz: float = Field(default=10.0, gt=0.0, le=200.0, description="controller rate")
    filter_hz: float = Field(default=2.0, gt=0.0, le=200.0, description="safety filter rate")
    snapshot_hz: float = Field(default=5.0, gt=0.0, le=200.0, description="snapshot rate")

    @model_validator(mode="after")
    def _check(self) -> RatesSpec:
        for name in ("tracker_hz", "observer_hz", "controller_hz", "filter_hz", "snapshot_hz"):
            value = getattr(self, name)
            if value > self.sim_hz:
                raise ValueError(f"{name} must be <= sim_hz = {self.sim_hz}, actually: {value}")
        return self


class CriteriaSpec(_Model):
    """What counts as success; the runtime's summary reports each as pass or fail."""

    min_distance_targets_m: float = Field(
        default=0.0, ge=0.0, description="least allowed distance, own ship to any target, "
        "centre to centre [m]"
    )
    min_distance_land_m: float = Field(
        default=0.0, ge=0.0, description="least allowed distance, own ship centre to land [m]"
    )
    goal_reached: bool = Field(
        default=True, description="the own ship must end within its acceptance radius of the "
        "last waypoint"
    )
    max_cte_m: float | None = Field(
        default=None, gt=0.0, description="largest allowed cross-track error [m]; None: unchecked"
    )


# --------------------------------------------------------------------------- scenario


class Scenario(_Model):
    """One scenario: scene, own ship, targets, inputs, rates, duration, seed and criteria."""

    format: Literal["asvtwin.scenario/1"] = Field(
        default="asvtwin.scenario/1", description="format version"
    )
    name: str = Field(min_length=1, max_length=80, description="short name")
    description: str = Field(default="", description="what happens and what is expected")
    scene: str = Field(
        default="trondheim", min_length=1,
        description="'trondheim' (the bundled fjord) or a scene file (relative to the scenario)",
    )
    start_time_utc: Annotated[datetime, Field(strict=False)] = Field(
        default=datetime(2024, 11, 20, 11, 0, tzinfo=UTC),
        description="UTC time at t = 0 (ISO 8601 with a zone); the weather fixture covers "
        "2024-11-20 11:00Z onwards",
    )
    duration_s: float = Field(default=600.0, gt=0.0, le=86_400.0, description="run length [s]")
    seed: int = Field(default=0, ge=0, le=2**63 - 1, description="seed of every random draw")
    own_ship: OwnShipSpec
    targets: list[TargetSpec] = Field(default_factory=list, description="other vessels")
    ais: AisSpec = Field(default_factory=AisSpec)
    weather: WeatherSpec = Field(default_factory=WeatherSpec)
    environment: EnvironmentSpec = Field(default_factory=EnvironmentSpec)
    sensors: SensorSpec = Field(default_factory=SensorSpec)
    rates: RatesSpec = Field(default_factory=RatesSpec)
    criteria: CriteriaSpec = Field(default_factory=CriteriaSpec)

    @field_validator("start_time_utc")
    @classmethod
    def _utc(cls, v: datetime) -> datetime:
        if v.tzinfo is None or v.utcoffset() is None:
            raise ValueError("start_time_utc needs a time zone (e.g. 2024-11-20T11:00:00Z)")
        return v.astimezone(UTC)

    @model_validator(mode="after")
    def _check(self) -> Scenario:
        names = [t.name for t in self.targets]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"target names must be unique, repeated: {dup}")
        mmsis = [t.mmsi for t in self.targets if t.mmsi is not None]
        dup_m = sorted({m for m in mmsis if mmsis.count(m) > 1})
        if dup_m:
            raise ValueError(f"target MMSIs must be unique, repeated: {dup_m}")
        if self.sensors.lidar_rate_hz > self.rates.sim_hz:
            raise ValueError(
                f"sensors.lidar_rate_hz must be <= rates.sim_hz = {self.rates.sim_hz}, "
                f"actually: {self.sensors.lidar_rate_hz}"
            )
        if self.criteria.goal_reached and not self.own_ship.route:
            raise ValueError("criteria.goal_reached needs own_ship.route (there is no goal)")
        return self

    def with_controller(self, controller: str) -> Scenario:
        """This scenario with the own ship under ``controller``, validated as a file
        would be (``los``/``los_psf`` need a route and a course-keeping speed); a
        :class:`~asvtwin.errors.ScenarioError` says why not."""
        if controller == self.own_ship.controller:
            return self
        data = self.model_dump()
        data["own_ship"]["controller"] = controller
        try:
            return type(self).model_validate(data)
        except ValidationError as exc:
            errs = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())
            raise ScenarioError(f"scenario {self.name!r} cannot run under controller "
                                f"{controller!r}: {errs}") from None


def scenario_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file, for editors and validators."""
    schema = Scenario.model_json_schema(mode="validation")
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["$id"] = SCENARIO_FORMAT
    return schema
