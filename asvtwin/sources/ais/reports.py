"""Validated AIS reports: the plain values an AIS source hands to the twin.

Two kinds of message leave the decoding pipeline:

- :class:`AisReport`, a *dynamic* report (position, speed, course, heading, rate of turn) from
  message types 1, 2, 3 (class A) and 18, 19 (class B), in the scene's NED frame;
- :class:`AisStatic`, *static* data (name, call sign, ship type, dimensions A/B/C/D, draught,
  destination) from types 5 (class A), 24 part A/B and 19 (class B).

Units sit in the names (``sog_m_s``, ``cog_rad``, ``t_unix_s``). Angles follow the NED
convention (from north, clockwise), wrapped to [-pi, pi). AIS "not available" values (lat 91,
lon 181, SOG 102.3 kn, COG 360, heading 511, ROT -128) never become numbers: in a report they
are ``None``; in the columnar :class:`ReportBatch` of the hot path they are NaN.

The hot path produces a :class:`ReportBatch` (one numpy array per field); a source expands it
into :class:`AisReport` objects with :meth:`ReportBatch.reports` when it hands messages out one
at a time.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8

if TYPE_CHECKING:
    from asvtwin.geo import LocalFrame

__all__ = [
    "CLASS_B_TYPES",
    "AisMessage",
    "AisReport",
    "AisStatic",
    "ReportBatch",
]

#: Message types of class B dynamic reports (the rest, 1/2/3, are class A).
CLASS_B_TYPES = frozenset({18, 19})



def _opt(value: float) -> float | None:
    """NaN (not available) -> None, anything else -> float."""
    return None if math.isnan(value) else float(value)


@dataclass(frozen=True, slots=True)
class AisReport:
    """One validated dynamic AIS report, in the scene's NED frame.

    Attributes
    ----------
    mmsi : int
        Maritime Mobile Service Identity, 1 ... 999 999 999.
    t_unix_s : float
        Receive time [s since 1970-01-01 UTC] (tag block ``c:`` or the source's clock).
    msg_type : int
        AIS message type (1, 2, 3, 18 or 19).
    north_m, east_m : float
        Position in the scene's local NED frame [m].
    lat_deg, lon_deg : float
        The reported WGS84 position [deg] (kept for the history and the viewer).
    sog_m_s : float or None
        Speed over ground [m/s]; None when not available.
    cog_rad : float or None
        Course over ground [rad], from north clockwise, in [-pi, pi); None when not available.
    heading_rad : float or None
        True heading [rad], same convention; None when not available.
    rot_rad_s : float or None
        Rate of turn [rad/s], positive to starboard (clockwise); None when not available or
        only "turning faster than 5 deg per 30 s" is known (class A only).
    nav_status : int or None
        Navigational status (0 under way using engine, 1 at anchor, 5 moored, ...); None for
        class B and for 15 (not defined).
    station : str or None
        Receiving base station (tag block ``s:``), if known.
    """

    mmsi: int
    t_unix_s: float
    msg_type: int
    north_m: float
    east_m: float
    lat_deg: float
    lon_deg: float
    sog_m_s: float | None = None
    cog_rad: float | None = None
    heading_rad: float | None = None
    rot_rad_s: float | None = None
    nav_status: int | None = None
    station: str | None = None

    @property
    def is_class_b(self) -> bool:
        """True for class B reports (types 18 and 19)."""
        return self.msg_type in CLASS_B_TYPES

    @property
    def velocity_m_s(self) -> tuple[float, float] | None:
        """Velocity over ground ``(north, east)`` [m/s], or None if SOG or COG is unknown."""
        if self.sog_m_s is None or self.cog_rad is None:
            return None
        return (self.sog_m_s * math.cos(self.cog_rad), self.sog_m_s * math.sin(self.cog_rad))


@dataclass(frozen=True, slots=True)
class AisStatic:
    """Static and voyage data of one vessel (types 5, 19, 24A, 24B); None = not available.

    Attributes
    ----------
    mmsi : int
        Maritime Mobile Service Identity.
    t_unix_s : float
        Receive time [s since 1970-01-01 UTC].
    msg_type : int
        5, 19 or 24 (the last message merged in).
    name, callsign, destination : str or None
        Texts with the AIS padding (``@`` and trailing blanks) removed.
    ship_type : int or None
        AIS ship and cargo type (30 fishing, 37 pleasure craft, 60-69 passenger, ...).
    imo : int or None
        IMO number.
    to_bow_m, to_stern_m, to_port_m, to_starboard_m : int or None
        Dimensions A, B, C, D from the position reference point [m].
    draught_m : float or None
        Static draught [m].
    """

    mmsi: int
    t_unix_s: float
    msg_type: int
    name: str | None = None
    callsign: str | None = None
    ship_type: int | None = None
    imo: int | None = None
    to_bow_m: int | None = None
    to_stern_m: int | None = None
    to_port_m: int | None = None
    to_starboard_m: int | None = None
    draught_m: float | None = None
    destination: str | None = None

    @property
    def length_m(self) -> float | None:
        """Overall length A + B [m], or None when either is unknown."""
        if self.to_bow_m is None or self.to_stern_m is None:
            return None
        return float(self.to_bow_m + self.to_stern_m)

    @property
    def beam_m(self) -> float | None:
        """Beam C + D [m], or None when either is unknown."""
        if self.to_port_m is None or self.to_starboard_m is None:
            return None
        return float(self.to_port_m + self.to_starboard_m)

    def merged(self, newer: AisStatic) -> AisStatic:
        """Combine with a newer partial record (24A carries the name, 24B the rest).

        Fields the newer record knows win; fields it lacks keep their old value.
        """
        if newer.mmsi != self.mmsi:
            raise ValueError(f"cannot merge static data of MMSI {newer.mmsi} into {self.mmsi}")
        changes: dict[str, Any] = {
            f.name: getattr(newer, f.name)
            for f in dataclasses.fields(newer)
            if getattr(newer, f.name) is not None
        }
        return dataclasses.replace(self, **changes)


#: What an AIS source yields.
AisMessage = AisReport | AisStatic


@dataclass(frozen=True)
class ReportBatch:
    """Columnar dynamic reports of one pipeline call, plus the static records.

    Every array has shape (n,). NaN marks "not available" in ``sog_m_s``, ``cog_rad``,
    ``heading_rad`` and ``rot_rad_s``; ``nav_status`` is -1 when not available.
    ``station`` holds the receiving station per row (None if unknown). ``frame`` is the
    local frame ``north_m``/``east_m`` are in (None when unknown, e.g. built from reports).
    """

    mmsi: NDArray[np.int64]
    t_unix_s: _F8
    msg_type: NDArray[np.int64]
    north_m: _F8
    east_m: _F8
    lat_deg: _F8
    lon_deg: _F8
    sog_m_s: _F8
    cog_rad: _F8
    heading_rad: _F8
    rot_rad_s: _F8
    nav_status: NDArray[np.int64]
    station: tuple[str | None, ...]
    static: tuple[AisStatic, ...] = ()
    frame: LocalFrame | None = None

    def __len__(self) -> int:
        return int(self.mmsi.shape[0])

    @classmethod
    def empty(cls, static: tuple[AisStatic, ...] = ()) -> ReportBatch:
        """A batch without dynamic reports (optionally with static records)."""
        f = np.empty(0, dtype=np.float64)
        i = np.empty(0, dtype=np.int64)
        return cls(i, f, i, f, f, f, f, f, f, f, f, i, (), static)

    @classmethod
    def from_reports(cls, reports: list[AisReport] | tuple[AisReport, ...],
                     static: tuple[AisStatic, ...] = (), *,
                     frame: LocalFrame | None = None) -> ReportBatch:
        """Build a batch from report objects (None -> NaN / -1); ``frame``: the frame their
        ``north_m``/``east_m`` are in, if known."""
        if not reports:
            return dataclasses.replace(cls.empty(static), frame=frame)
        nan = math.nan

        def col(name: str) -> _F8:
            return np.array([nan if (v := getattr(r, name)) is None else v for r in reports],
                            dtype=np.float64)

        return cls(
            mmsi=np.array([r.mmsi for r in reports], dtype=np.int64),
            t_unix_s=col("t_unix_s"),
            msg_type=np.array([r.msg_type for r in reports], dtype=np.int64),
            north_m=col("north_m"), east_m=col("east_m"),
            lat_deg=col("lat_deg"), lon_deg=col("lon_deg"),
            sog_m_s=col("sog_m_s"), cog_rad=col("cog_rad"),
            heading_rad=col("heading_rad"), rot_rad_s=col("rot_rad_s"),
            nav_status=np.array([-1 if r.nav_status is None else r.nav_status for r in reports],
                                dtype=np.int64),
            station=tuple(r.station for r in reports),
            static=static, frame=frame,
        )

    def reports(self) -> list[AisReport]:
        """The rows as :class:`AisReport` objects (NaN -> None), in input order."""
        cols = zip(
            self.mmsi.tolist(), self.t_unix_s.tolist(), self.msg_type.tolist(),
            self.north_m.tolist(), self.east_m.tolist(), self.lat_deg.tolist(),
            self.lon_deg.tolist(), self.sog_m_s.tolist(), self.cog_rad.tolist(),
            self.heading_rad.tolist(), self.rot_rad_s.tolist(), self.nav_status.tolist(),
            self.station,
        )
        return [
            AisReport(m, t, k, n, e, la, lo, _opt(s), _opt(c), _opt(h), _opt(r),
                      None if ns < 0 else ns, st)
            for m, t, k, n, e, la, lo, s, c, h, r, ns, st in cols
        ]
