"""Stage 6 of the AIS pipeline: decoded values -> SI units, "not available" -> NaN/None,
positions projected into the scene's NED frame, all at once per batch.

Dynamic reports are collected as column arrays (from the vectorised decoder,
:mod:`~asvtwin.sources.ais.positions`, and from pyais for the other types) and converted here
in one pass: SOG knots -> m/s (102.3 kn = not available), COG and heading degrees -> radians
from north wrapped to [-pi, pi) (360 and 511 = not available), rate of turn deg/min -> rad/s
(pyais's ``TurnRate`` values 127, -127, -128 = no value), navigational status 15 -> -1.
Static records (types 5, 19, 24) become :class:`~asvtwin.sources.ais.reports.AisStatic`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from asvtwin.geo import LocalFrame
from asvtwin.sources.ais.reports import AisStatic, ReportBatch
from asvtwin.units import KNOT_M_S

__all__ = ["COLUMNS", "pyais_row", "report_batch", "static_record"]

_TWO_PI = 2.0 * math.pi
_DEG = math.pi / 180.0
_ROT_DEG_MIN = math.pi / 180.0 / 60.0  # deg/min -> rad/s

#: The decoded columns, in the order of :func:`report_batch`'s ``cols``.
COLUMNS = ("msg_type", "mmsi", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg",
           "rot_deg_min", "nav_status")


def _angle(deg: np.ndarray, unavailable: float) -> np.ndarray:
    return np.where(deg >= unavailable, np.nan, (deg * _DEG + np.pi) % _TWO_PI - np.pi)


def report_batch(cols: dict[str, np.ndarray], t_unix_s: list[float],
                 station: list[str | None], static: tuple[AisStatic, ...],
                 frame: LocalFrame) -> ReportBatch:
    """Columns of accepted reports (as decoded, :data:`COLUMNS`) -> a :class:`ReportBatch`."""
    lat = np.asarray(cols["lat_deg"], np.float64)
    lon = np.asarray(cols["lon_deg"], np.float64)
    north, east = frame.to_ned(lat, lon)
    sog = np.asarray(cols["sog_kn"], np.float64)
    rot = np.asarray(cols["rot_deg_min"], np.float64)
    nav = np.asarray(cols["nav_status"], np.int64)
    return ReportBatch(
        mmsi=np.asarray(cols["mmsi"], np.int64), t_unix_s=np.array(t_unix_s, np.float64),
        msg_type=np.asarray(cols["msg_type"], np.int64), north_m=north, east_m=east,
        lat_deg=lat, lon_deg=lon,
        sog_m_s=np.where(sog >= 102.3, np.nan, sog * KNOT_M_S),
        cog_rad=_angle(np.asarray(cols["cog_deg"], np.float64), 360.0),
        heading_rad=_angle(np.asarray(cols["heading_deg"], np.float64), 360.0),
        # decoded ROT is round((k / 4.733)^2) deg/min (k <= 126), never 127 or 128: those
        # are pyais's TurnRate values for "no turn information" / "turning, no value"
        rot_rad_s=np.where(np.isin(np.abs(rot), (127.0, 128.0)), np.nan, rot * _ROT_DEG_MIN),
        nav_status=np.where(nav == 15, -1, nav), station=tuple(station),
        static=static, frame=frame,
    )


def pyais_row(m: Any, ais_id: int) -> tuple[Any, ...]:
    """The :data:`COLUMNS` of a position report decoded by pyais."""
    if ais_id <= 3:  # TurnRate ±127/-128 (no value) as such; mapped to NaN above
        return (ais_id, m.mmsi, m.lat, m.lon, m.speed, m.course, m.heading, float(m.turn),
                int(m.status))
    return ais_id, m.mmsi, m.lat, m.lon, m.speed, m.course, m.heading, math.nan, 15


def _text(value: object) -> str | None:
    """AIS 6-bit text without the ``@`` padding and blanks; None when empty."""
    if not isinstance(value, str):
        return None
    s = value.replace("@", " ").strip()
    return s or None


def _positive_or_none(value: object) -> int | None:
    return int(value) if isinstance(value, int) and value > 0 else None


def static_record(m: Any, ais_id: int, t: float) -> AisStatic:
    """An :class:`AisStatic` from a decoded type 5, 19 or 24 message received at ``t``."""
    draught = m.draught if ais_id == 5 else None
    has_dims = hasattr(m, "to_bow")
    ship_type = getattr(m, "ship_type", None)
    return AisStatic(
        mmsi=int(m.mmsi), t_unix_s=t, msg_type=ais_id,
        name=_text(getattr(m, "shipname", None)),
        callsign=_text(getattr(m, "callsign", None)),
        ship_type=_positive_or_none(int(ship_type)) if ship_type is not None else None,
        imo=_positive_or_none(m.imo) if ais_id == 5 else None,
        to_bow_m=_positive_or_none(m.to_bow) if has_dims else None,
        to_stern_m=_positive_or_none(m.to_stern) if has_dims else None,
        to_port_m=_positive_or_none(m.to_port) if has_dims else None,
        to_starboard_m=_positive_or_none(m.to_starboard) if has_dims else None,
        draught_m=float(draught) if draught else None,
        destination=_text(getattr(m, "destination", None)),
    )
