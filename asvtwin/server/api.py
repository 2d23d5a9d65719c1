"""The control requests the server accepts, as pydantic models (validated at the edge).

Every model forbids unknown fields and bounds every number, so a malformed request is
refused with HTTP 422 and a reason that names the field, before it reaches the twin.
Positions are scene NED metres ``[north_m, east_m]`` or ``{"lat": .., "lon": ..}`` degrees.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

__all__ = ["CONTROL_MODELS", "MAX_BODY_BYTES", "ClientOptions"]

#: Largest control request body [bytes]; larger ones are refused with 413.
MAX_BODY_BYTES = 64 * 1024

_Finite = Annotated[float, Field(allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Empty(_Strict):
    """No parameters (pause, resume)."""


class Speed(_Strict):
    """Clock speed: a factor of real time in (0, 1000], or ``"max"`` (as fast as it runs)."""

    factor: Annotated[float, Field(gt=0.0, le=1000.0, allow_inf_nan=False)] | Literal["max"]


class Step(_Strict):
    """Advance this many ticks, then stay paused."""

    n_ticks: Annotated[int, Field(ge=1, le=10_000)] = 1


class Filter(_Strict):
    """Switch the predictive safety filter on or off."""

    enabled: bool


class LatLon(_Strict):
    lat: Annotated[float, Field(ge=-90.0, le=90.0, allow_inf_nan=False)]
    lon: Annotated[float, Field(ge=-180.0, le=180.0, allow_inf_nan=False)]


class NorthEast(_Strict):
    north_m: Annotated[float, Field(ge=-1e6, le=1e6, allow_inf_nan=False)]
    east_m: Annotated[float, Field(ge=-1e6, le=1e6, allow_inf_nan=False)]


class Route(_Strict):
    """The own ship's new route: 1-200 waypoints in scene NED metres ``[north, east]``."""

    waypoints_ned: Annotated[list[tuple[_Finite, _Finite]], Field(min_length=1, max_length=200)]

    @field_validator("waypoints_ned")
    @classmethod
    def _in_range(cls, v: list[tuple[float, float]]) -> list[tuple[float, float]]:
        for k, (n, e) in enumerate(v):
            if abs(n) > 1e6 or abs(e) > 1e6:
                raise ValueError(f"waypoint {k} = ({n}, {e}) m is outside ±1000 km of the origin")
        return v


class VesselSpec(_Strict):
    """A vessel to inject (the scenario schema's ``TargetSpec``, constant velocity)."""

    name: Annotated[str, Field(min_length=1, max_length=20)]
    mmsi: Annotated[int, Field(ge=100_000_000, le=999_999_999)] | None = None
    ais_class: Literal["A", "B"] | None = None  # None with an MMSI means class A
    vessel_type: Literal["fishing", "tug", "sailing", "pleasure", "hsc", "passenger", "ferry",
                         "cargo", "tanker", "other"] = "cargo"
    length_m: Annotated[float, Field(ge=3.0, le=400.0)] = 30.0
    beam_m: Annotated[float, Field(gt=0.0, le=70.0)] = 8.0
    start: LatLon | NorthEast
    heading_deg: Annotated[float, Field(ge=0.0, lt=360.0)]
    speed_kn: Annotated[float, Field(ge=0.0, le=50.0)]

    def to_target_spec(self) -> dict[str, Any]:
        """As the scenario schema's ``TargetSpec`` fields (constant-velocity behaviour)."""
        d = self.model_dump()
        if d["mmsi"] is not None and d["ais_class"] is None:
            d["ais_class"] = "A"
        d["behaviour"] = {"kind": "constant_velocity"}
        return d


class Inject(_Strict):
    spec: VesselSpec


class Wind(_Strict):
    """Mean wind: speed [m/s] in [0, 60] and the direction it comes from [deg] in [0, 360)."""

    speed_m_s: Annotated[float, Field(ge=0.0, le=60.0, allow_inf_nan=False)]
    from_deg: Annotated[float, Field(ge=0.0, lt=360.0, allow_inf_nan=False)]


class Seek(_Strict):
    """Replay: jump to simulation time ``t_s`` [s]."""

    t_s: Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


#: action name -> request model
CONTROL_MODELS: dict[str, type[BaseModel]] = {
    "pause": Empty, "resume": Empty, "speed": Speed, "step": Step, "filter": Filter,
    "route": Route, "inject": Inject, "wind": Wind, "seek": Seek,
}


class ClientOptions(_Strict):
    """A WebSocket client's options (query string ``?rate_hz=..&format=..&ack=1``, or a JSON
    text message ``{"rate_hz": ..}`` later): snapshots per second, the encoding, and whether
    the client acknowledges each snapshot (``{"ack": seq}``) before it gets the next one.

    With ``ack`` a client that is slow to process (a browser tab on a busy machine) gets
    fewer, always fresh snapshots instead of filling the socket until it is dropped."""

    rate_hz: Annotated[float, Field(ge=0.1, le=60.0, allow_inf_nan=False)] = 10.0
    format: Literal["json", "msgpack"] = "json"
    ack: bool = False
