"""The twin's snapshot: one immutable tree of plain values per tick, one encoder, one schema.

Every consumer reads the same thing: the recorder writes it to MCAP, the server pushes it
over the WebSocket, the viewer draws it, a what-if fork starts from it. The tree is made of
frozen dataclasses whose leaves are floats, ints, strings, bools, tuples and read-only,
C-contiguous numpy arrays; :func:`encode` turns it into JSON bytes with orjson (NaN becomes
``null``: "not available" is explicit, never a number) and :func:`json_schema` gives the
JSON Schema of the encoded message, versioned by :data:`SCHEMA_ID`.

Frames and units: positions are NED metres in the scene's tangent plane (x north,
y east), angles radians clockwise from north, speeds m/s, forces N and moments Nm, times
seconds of simulation time. Latitude/longitude appear only where a field says so.

Examples
--------
>>> import numpy as np
>>> s = empty_snapshot(t_s=1.5, seq=3)
>>> msg = decode(encode(s))
>>> msg["schema"], msg["t_s"], msg["own"]["state"]
('asvtwin.snapshot/1', 1.5, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
>>> json_schema()["properties"]["filter"]["properties"]["fallback"]["type"]
'string'
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import orjson
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "SCHEMA_ID",
    "AisTargets",
    "ClockState",
    "ComponentHealth",
    "Ellipses",
    "FilterState",
    "GroundTruth",
    "LidarFrame",
    "ObserverState",
    "OwnShip",
    "Snapshot",
    "Tracks",
    "WeatherState",
    "decode",
    "empty_snapshot",
    "encode",
    "json_schema",
    "ro",
]

#: Name and version of the snapshot schema (bumped on any incompatible change).
SCHEMA_ID = "asvtwin.snapshot/1"

F8 = NDArray[np.float64]
I8 = NDArray[np.int64]
B1 = NDArray[np.bool_]


def ro(a: ArrayLike, dtype: Any = np.float64, shape: tuple[int, ...] | None = None) -> NDArray[Any]:
    """A read-only, C-contiguous copy of ``a`` (reshaped to ``shape`` when given; ``-1`` ok)."""
    out = np.array(a, dtype=dtype, copy=True, order="C")
    if shape is not None:
        out = out.reshape(shape)
    out.flags.writeable = False
    return out


def _f(shape: tuple[int, ...]) -> Any:
    return field(default_factory=lambda: ro(np.zeros(shape)))


def _i(n: int = 0) -> Any:
    return field(default_factory=lambda: ro(np.zeros(n, np.int64), np.int64))


def _b(n: int = 0) -> Any:
    return field(default_factory=lambda: ro(np.zeros(n, bool), np.bool_))


@dataclass(frozen=True, eq=False)
class ClockState:
    """The runtime's clock: ``mode`` is ``realtime``, ``scaled``, ``max`` or ``step``."""

    mode: str = "max"
    speed: float = 1.0
    paused: bool = False
    wall_utc: str | None = None  # the scenario's wall-clock time of ``t_s`` (ISO 8601, UTC)


@dataclass(frozen=True, eq=False)
class OwnShip:
    """The own ship as the twin knows it (navigation state) and what it was told to do.

    ``state`` is ``[x_m, y_m, psi_rad, u_m_s, v_m_s, r_rad_s]``; ``tau_cmd`` the input the
    filter let through (u_0) and ``tau_applied`` what the thrusters delivered [N, N, Nm];
    ``route`` the waypoints (k, 2) [m]; ``past_track`` recent positions (m, 2) [m], oldest
    first; ``cte_m`` the cross-track error to the active leg [m], positive to starboard.
    """

    name: str = "own ship"
    vessel: str = "cybership2_full_scale"
    length_m: float = 0.0
    beam_m: float = 0.0
    state: F8 = _f((6,))
    lat_deg: float = float("nan")
    lon_deg: float = float("nan")
    sog_m_s: float = 0.0
    cog_rad: float = 0.0
    tau_cmd: F8 = _f((3,))
    tau_applied: F8 = _f((3,))
    route: F8 = _f((0, 2))
    waypoint_index: int = 0
    cte_m: float = float("nan")
    controller: str = "los_psf"
    goal_reached: bool = False
    past_track: F8 = _f((0, 2))


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """The simulated world's targets (for scoring and the viewer's truth layer only; the
    twin never decides on it). Row ``i`` is one vessel; ``mmsi`` −1 when it has no AIS."""

    ids: I8 = _i()
    names: tuple[str, ...] = ()
    mmsi: I8 = _i()
    state: F8 = _f((0, 6))
    length_m: F8 = _f((0,))
    beam_m: F8 = _f((0,))


@dataclass(frozen=True, eq=False)
class AisTargets:
    """AIS targets, dead-reckoned to ``t_s``. Unavailable values are NaN (``null`` on the
    wire): ``sog_m_s``, ``cog_rad``, ``heading_rad``, ``length_m``, ``beam_m``."""

    mmsi: I8 = _i()
    names: tuple[str, ...] = ()
    position_m: F8 = _f((0, 2))
    lat_deg: F8 = _f((0,))
    lon_deg: F8 = _f((0,))
    sog_m_s: F8 = _f((0,))
    cog_rad: F8 = _f((0,))
    heading_rad: F8 = _f((0,))
    age_s: F8 = _f((0,))
    stale: B1 = _b()
    length_m: F8 = _f((0,))
    beam_m: F8 = _f((0,))


@dataclass(frozen=True, eq=False)
class LidarFrame:
    """The latest LiDAR scan: ``points`` are the returns (m, 2) in NED [m], ``coast`` marks
    returns from land; ``origin`` is the sensor position [m]."""

    t_s: float = float("nan")
    origin: F8 = _f((2,))
    range_m: float = 0.0
    n_rays: int = 0
    points: F8 = _f((0, 2))
    coast: B1 = _b()


@dataclass(frozen=True, eq=False)
class Ellipses:
    """Ellipses fitted to the scan's clusters: centre (k, 2) [m], semi-axes (k, 2) [m],
    ``angle_rad`` of the major axis from north, ``ok`` whether the fit succeeded."""

    centre: F8 = _f((0, 2))
    semi_axes_m: F8 = _f((0, 2))
    angle_rad: F8 = _f((0,))
    ok: B1 = _b()


@dataclass(frozen=True, eq=False)
class Tracks:
    """Tracks with their predictions (the "green broadening path").

    ``mean`` (n, 4) ``[x, y, v_x, v_y]`` [m, m/s]; ``cov`` (n, 4, 4); ``mmsi`` −1 when not
    tied to AIS; ``source`` per track: ``lidar``, ``ais`` or ``fused``; ``status``:
    ``tentative``, ``confirmed`` or ``coasting``. The prediction at ``pred_times_s`` (h,)
    [s ahead]: ``pred_mean`` (n, h, 2) [m] and ``pred_radius_m`` (n, h), the radius of the
    2-σ circle (the cone); ``cpa_m`` and ``tcpa_s`` relative to the own ship (NaN when
    they do not close)."""

    ids: I8 = _i()
    mmsi: I8 = _i()
    status: tuple[str, ...] = ()
    source: tuple[str, ...] = ()
    mean: F8 = _f((0, 4))
    cov: F8 = _f((0, 4, 4))
    pred_times_s: F8 = _f((0,))
    pred_mean: F8 = _f((0, 0, 2))
    pred_radius_m: F8 = _f((0, 0))
    cpa_m: F8 = _f((0,))
    tcpa_s: F8 = _f((0,))


@dataclass(frozen=True, eq=False)
class ObserverState:
    """The disturbance estimate d̂ of τ_d [N, N, Nm] in the body frame, the true τ_d (for
    scoring), and the fault detector's verdict."""

    d_hat: F8 = _f((3,))
    d_true: F8 = _f((3,))
    fault: bool = False
    fault_kind: str | None = None
    fault_channel: str | None = None
    fault_confidence: float = 0.0
    valid: bool = True


@dataclass(frozen=True, eq=False)
class FilterState:
    """The predictive safety filter's answer at its last call.

    ``t_s`` the simulation time of that call [s] (the snapshot's own time before the
    first call; the answer and its u_0 are held until the next call, every
    ``1 / rates.filter_hz`` s); ``u_L`` the learner's / controller's latest proposal and
    ``u_0`` the input let through [N, N, Nm]; ``plan`` the planned positions (N+1, 2) [m]
    with ``plan_margin_m`` per stage [m] (≥ 0 safe) and ``critical_stages`` the stages
    drawn red; ``plan_times_s`` the stage times after ``t_s`` [s]; ``period_s`` the
    time between the filter's calls [s] (``1 / rates.filter_hz``); ``fallback``:
    ``none``, or the kind of checked fallback used; ``explanation``: a sentence a
    navigator reads."""

    enabled: bool = True
    t_s: float = float("nan")
    u_L: F8 = _f((3,))
    u_0: F8 = _f((3,))
    intervened: bool = False
    certified: bool = True
    fallback: str = "none"
    status: str = ""
    explanation: str = ""
    plan: F8 = _f((0, 2))
    plan_times_s: F8 = _f((0,))
    plan_margin_m: F8 = _f((0,))
    critical_stages: I8 = _i()
    solve_ms: float = 0.0
    interventions: int = 0
    fallbacks: int = 0
    calls: int = 0
    period_s: float = float("nan")


@dataclass(frozen=True, eq=False)
class WeatherState:
    """Weather at the own ship: wind speed [m/s] and the direction it comes from [rad from
    north], air temperature [°C], pressure [hPa], the current (x, y) [m/s]; ``source``
    names where it came from (``fixture (synthetic)``, a file, or the live service)."""

    source: str = ""
    wind_speed_m_s: float = float("nan")
    wind_from_rad: float = float("nan")
    air_temperature_c: float = float("nan")
    pressure_hpa: float = float("nan")
    current_m_s: F8 = _f((2,))
    age_s: float = float("nan")


@dataclass(frozen=True, eq=False)
class ComponentHealth:
    """One component's health: its period [s], time per call [ms], counts and last error.
    ``status``: ``ok``, ``degraded`` (errors or overruns seen) or ``failed`` (disabled)."""

    name: str = ""
    period_s: float = 0.0
    calls: int = 0
    errors: int = 0
    overruns: int = 0
    last_ms: float = 0.0
    mean_ms: float = 0.0
    max_ms: float = 0.0
    last_error: str | None = None
    status: str = "ok"


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything the twin knows at one tick (see the module docstring for frames/units)."""

    schema: str = SCHEMA_ID
    seq: int = 0
    t_s: float = 0.0
    scenario: str = ""
    clock: ClockState = field(default_factory=ClockState)
    own: OwnShip = field(default_factory=OwnShip)
    truth: GroundTruth = field(default_factory=GroundTruth)
    ais: AisTargets = field(default_factory=AisTargets)
    lidar: LidarFrame = field(default_factory=LidarFrame)
    ellipses: Ellipses = field(default_factory=Ellipses)
    tracks: Tracks = field(default_factory=Tracks)
    observer: ObserverState = field(default_factory=ObserverState)
    filter: FilterState = field(default_factory=FilterState)
    weather: WeatherState = field(default_factory=WeatherState)
    health: tuple[ComponentHealth, ...] = ()
    events: tuple[str, ...] = ()
    counters: Mapping[str, int] = field(default_factory=dict)


def empty_snapshot(**fields: Any) -> Snapshot:
    """A snapshot with every part empty (fields given override)."""
    return Snapshot(**fields)


_OPTS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def encode(snapshot: Snapshot) -> bytes:
    """The snapshot as JSON bytes (orjson; NaN and inf become ``null``)."""
    return orjson.dumps(snapshot, option=_OPTS)


def decode(data: bytes | str) -> dict[str, Any]:
    """A JSON message back to plain Python (dicts and lists; ``null`` is None)."""
    out: dict[str, Any] = orjson.loads(data)
    return out


# --- JSON Schema of the encoded message -------------------------------------------------

_NUM = {"type": ["number", "null"]}


def _schema_of(tp: Any, array_dims: int = 1) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is float:
        return dict(_NUM)
    if tp is int:
        return {"type": "integer"}
    if tp is bool:
        return {"type": "boolean"}
    if tp is str:
        return {"type": "string"}
    if origin in (types.UnionType, typing.Union):
        inner = [_schema_of(a) for a in args if a is not type(None)]
        if len(inner) == 1 and "type" in inner[0] and isinstance(inner[0]["type"], str):
            return {"type": [inner[0]["type"], "null"]}
        return {"anyOf": [*inner, {"type": "null"}]}
    if origin is tuple:
        return {"type": "array", "items": _schema_of(args[0])}
    if origin in (Mapping, dict) or tp in (Mapping, dict):
        return {"type": "object", "additionalProperties": {"type": "integer"}}
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):  # a dataclass type, not an instance
        hints = typing.get_type_hints(tp)
        props = {f.name: _schema_of(hints[f.name], _array_dims(tp, f.name))
                 for f in dataclasses.fields(tp)}
        doc = (tp.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
        return {"type": "object", "title": tp.__name__, "description": doc,
                "properties": props, "required": list(props)}
    if origin is np.ndarray:
        scalar = typing.get_args(args[1])[0]  # NDArray[X] is ndarray[shape, dtype[X]]
        leaf: dict[str, Any] = (
            {"type": "boolean"} if scalar is np.bool_
            else {"type": "integer"} if np.issubdtype(scalar, np.integer) else dict(_NUM)
        )
        for _ in range(array_dims):
            leaf = {"type": "array", "items": leaf}
        return leaf
    raise TypeError(f"no JSON Schema for {tp!r}")


def _array_dims(cls: type, name: str) -> int:
    default = next(f for f in dataclasses.fields(cls) if f.name == name)
    if default.default_factory is dataclasses.MISSING:  # type: ignore[misc]
        return 1
    value = default.default_factory()  # type: ignore[misc]
    return int(np.ndim(value)) if isinstance(value, np.ndarray) else 1


def json_schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of an encoded :class:`Snapshot` message."""
    s = _schema_of(Snapshot)
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = SCHEMA_ID
    return s
