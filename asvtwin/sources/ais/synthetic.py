"""Synthetic AIS: simulated fjord traffic encoded to NMEA with pyais, as a live feed would send.

:class:`SyntheticTraffic` steps :class:`~asvtwin.sources.ais.traffic.FjordTraffic` and, at each
vessel's reporting time, encodes what its transponder would broadcast:

- class A: type 1 (type 3 every fourth report) every 10 s under way below 14 kn, 6 s up to
  23 kn, 2 s above, a third of that while turning, 3 min when moored; type 5 (two fragments)
  every 6 min;
- class B: type 18 every 30 s (3 min below 2 kn); type 24 parts A and B every 6 min;

each line behind an IEC 61162-450 tag block ``\\s:station,c:unix_time*hh\\`` like the
Norwegian Coastal Administration's feed. The lines go through the same
:class:`~asvtwin.sources.ais.pipeline.AisPipeline` as live data, so the default run exercises
the real decoding path. Every line comes with its ground truth (the exact simulated values,
before AIS quantisation) for tests.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from pyais.encode import encode_dict

from asvtwin.errors import ParameterError
from asvtwin.geo import Scene
from asvtwin.sources.ais.reports import AisReport, AisStatic
from asvtwin.sources.ais.traffic import FjordTraffic, TrafficVessel, default_fleet
from asvtwin.units import KNOT_M_S

__all__ = ["SyntheticLine", "SyntheticTraffic", "encode_report", "encode_static", "tag_block"]

_STATIC_INTERVAL_S = 360.0


def tag_block(*, station: str, t_unix_s: float) -> str:
    """IEC 61162-450 tag block ``\\s:<station>,c:<unix s>*hh\\`` with a two-digit checksum."""
    body = f"s:{station},c:{int(t_unix_s)}"
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return f"\\{body}*{cs:02X}\\"


def encode_report(report: AisReport, *, talker: str = "AB", channel: str = "A",
                  second: int | None = None) -> str:
    """Encode a dynamic report as one NMEA sentence (type 1/2/3 or 18); no tag block.

    ``None`` fields are sent as AIS "not available" (SOG 102.3, COG 360, heading 511, ROT -128).
    """
    sog = 102.3 if report.sog_m_s is None else min(report.sog_m_s / KNOT_M_S, 102.2)
    cog = 360.0 if report.cog_rad is None else math.degrees(report.cog_rad) % 360.0
    cog = 0.0 if cog >= 359.95 and report.cog_rad is not None else cog
    hdg = 511 if report.heading_rad is None else round(math.degrees(report.heading_rad)) % 360
    sec = int(report.t_unix_s) % 60 if second is None else second
    data: dict[str, Any] = {
        "type": report.msg_type, "mmsi": report.mmsi, "lat": report.lat_deg,
        "lon": report.lon_deg, "speed": round(sog, 1), "course": round(cog, 1),
        "heading": hdg, "second": sec, "accuracy": 1,
    }
    if report.msg_type in (1, 2, 3):
        rot = -128.0 if report.rot_rad_s is None else \
            max(-708.0, min(708.0, math.degrees(report.rot_rad_s) * 60.0))
        data["turn"] = rot
        data["status"] = 15 if report.nav_status is None else report.nav_status
    else:
        data["cs"] = 1
    return encode_dict(data, talker_id=talker, sentence_type="VDM", radio_channel=channel)[0]


def encode_static(static: AisStatic, *, talker: str = "AB", channel: str = "A",
                  seq_id: int = 0) -> list[list[str]]:
    """Encode static data: type 5 (two fragments) or type 24 parts A and B.

    Returns a list of messages, each a list of sentences (fragments).
    """
    dims = {"to_bow": static.to_bow_m or 0, "to_stern": static.to_stern_m or 0,
            "to_port": static.to_port_m or 0, "to_starboard": static.to_starboard_m or 0}
    if static.msg_type == 5:
        data: dict[str, Any] = {"type": 5, "mmsi": static.mmsi, "shipname": static.name or "",
                "callsign": static.callsign or "", "ship_type": static.ship_type or 0,
                "imo": static.imo or 0, "draught": static.draught_m or 0.0,
                "destination": static.destination or "", "ais_version": 2, **dims}
        return [encode_dict(data, talker_id=talker, sentence_type="VDM", radio_channel=channel,
                            seq_id=seq_id)]
    part_a: dict[str, Any] = {"type": 24, "partno": 0, "mmsi": static.mmsi, "shipname": static.name or ""}
    part_b: dict[str, Any] = {"type": 24, "partno": 1, "mmsi": static.mmsi, "ship_type": static.ship_type or 0,
              "callsign": static.callsign or "", **dims}
    return [encode_dict(d, talker_id=talker, sentence_type="VDM", radio_channel=channel)
            for d in (part_a, part_b)]


@dataclass(frozen=True, slots=True)
class SyntheticLine:
    """One NMEA line of the synthetic feed and the ground truth it encodes.

    ``truth`` is the exact simulated report (or the static data) for the message this line
    belongs to; the fragments of a type 5 share it.
    """

    t_unix_s: float
    line: str
    truth: AisReport | AisStatic


class SyntheticTraffic:
    """Simulated fjord traffic as a stream of tagged NMEA lines (deterministic per seed).

    Parameters
    ----------
    fleet : sequence of TrafficVessel, optional
        The vessels; :func:`~asvtwin.sources.ais.traffic.default_fleet` when omitted.
    rng : numpy.random.Generator
        Draws the reporting phases and channels (and duplicate receptions).
    start_unix_s : float
        UNIX time of the first step [s].
    scene : Scene, optional
        Frame of the routes; the default scene when omitted.
    dt_s : float
        Simulation step [s]; reports fall on whole seconds.
    stations : tuple of str
        Receiving base stations (tag block ``s:``); with two or more, each message is also
        received by a second station with probability ``duplicate_probability``.
    duplicate_probability : float
        Chance that a message is heard twice (the pipeline must drop the copy).
    talker : str
        NMEA talker of the lines (``AB`` like the coastal administration's base stations).
    """

    def __init__(self, fleet: tuple[TrafficVessel, ...] | list[TrafficVessel] | None = None, *,
                 rng: np.random.Generator, start_unix_s: float, scene: Scene | None = None,
                 dt_s: float = 0.5, stations: tuple[str, ...] = ("2579001", "2579002"),
                 duplicate_probability: float = 0.0, talker: str = "AB") -> None:
        if not 0.0 <= duplicate_probability <= 1.0:
            raise ParameterError("duplicate_probability must be in [0, 1], actually: "
                                 f"{duplicate_probability}")
        if not stations:
            raise ParameterError("SyntheticTraffic needs at least one station, actually: none")
        self.traffic = FjordTraffic(default_fleet() if fleet is None else fleet,
                                    scene=scene, dt_s=dt_s)
        self.rng = rng
        self.start_unix_s = float(math.floor(start_unix_s))  # tag block times are whole seconds
        self.stations = tuple(stations)
        self.duplicate_probability = float(duplicate_probability)
        self.talker = talker
        n = len(self.traffic.fleet)
        self._next = np.floor(rng.uniform(0.0, 10.0, n))
        self._next_static = np.floor(rng.uniform(0.0, 30.0, n))
        self._count = np.zeros(n, dtype=np.int64)
        self._seq = 0

    @property
    def fleet(self) -> tuple[TrafficVessel, ...]:
        """The simulated vessels."""
        return self.traffic.fleet

    def static_data(self, i: int, t_unix_s: float) -> AisStatic:
        """Static data vessel ``i`` broadcasts (dimensions from its scaled hull)."""
        v = self.fleet[i]
        length, beam = 1.255 * v.scale, 0.29 * v.scale
        return AisStatic(
            mmsi=v.mmsi, t_unix_s=t_unix_s, msg_type=5 if v.ais_class == "A" else 24,
            name=v.name, callsign=v.callsign, ship_type=v.ship_type,
            imo=9_000_000 + v.mmsi % 1_000_000 if v.ais_class == "A" else None,
            to_bow_m=round(0.6 * length), to_stern_m=round(0.4 * length),
            to_port_m=round(beam / 2), to_starboard_m=round(beam / 2),
            draught_m=round(0.07 * v.scale, 1) if v.ais_class == "A" else None,
            destination="TRONDHEIM" if v.ais_class == "A" else None)

    def _interval_s(self, i: int, sog: float, rot: float, moored: bool) -> float:
        v = self.fleet[i]
        kn = sog / KNOT_M_S
        if v.ais_class == "B":
            return 30.0 if kn > 2.0 else 180.0
        if moored:
            return 180.0
        base = 2.0 if kn > 23 else 6.0 if kn > 14 else 10.0
        return max(2.0, math.floor(base / 3.0)) if abs(rot) > math.radians(0.3) else base

    def _emit(self, t: float, lines: list[str], truth: AisReport | AisStatic
              ) -> list[SyntheticLine]:
        station = self.stations[int(self.rng.integers(len(self.stations)))]
        out = [SyntheticLine(t, tag_block(station=station, t_unix_s=t) + s, truth) for s in lines]
        if len(self.stations) > 1 and self.rng.random() < self.duplicate_probability:
            other = self.stations[(self.stations.index(station) + 1) % len(self.stations)]
            out += [SyntheticLine(t, tag_block(station=other, t_unix_s=t) + s, truth)
                    for s in lines]
        return out

    def run(self, duration_s: float) -> Iterator[SyntheticLine]:
        """Simulate ``duration_s`` more seconds and yield the lines in time order."""
        tr = self.traffic
        frame = tr.scene.frame
        t_end = tr.t_s + duration_s
        while tr.t_s < t_end - 1e-9:
            t_rel = tr.t_s
            due = np.flatnonzero(self._next <= t_rel + 1e-9)
            due_static = np.flatnonzero(self._next_static <= t_rel + 1e-9)
            if len(due) or len(due_static):
                t = self.start_unix_s + t_rel
                pos, sog, cog, hdg, rot = tr.kinematics()
                lat, lon = frame.to_wgs84(pos[:, 0], pos[:, 1])
                for i in due.tolist():
                    v = self.fleet[i]
                    moored = bool(tr.nav_status[i] == 5)
                    msg_type = (3 if self._count[i] % 4 == 3 else 1) if v.ais_class == "A" else 18
                    truth = AisReport(
                        mmsi=v.mmsi, t_unix_s=t, msg_type=msg_type, north_m=float(pos[i, 0]),
                        east_m=float(pos[i, 1]), lat_deg=float(lat[i]), lon_deg=float(lon[i]),
                        sog_m_s=float(sog[i]), cog_rad=float(cog[i]),
                        heading_rad=float(hdg[i]),
                        rot_rad_s=float(rot[i]) if v.ais_class == "A" else None,
                        nav_status=int(tr.nav_status[i]) if v.ais_class == "A" else None)
                    channel = "AB"[int(self.rng.integers(2))]
                    yield from self._emit(t, [encode_report(truth, talker=self.talker,
                                                            channel=channel)], truth)
                    self._count[i] += 1
                    self._next[i] = t_rel + self._interval_s(i, float(sog[i]), float(rot[i]),
                                                             moored)
                for i in due_static.tolist():
                    st = self.static_data(i, t)
                    for msg in encode_static(st, talker=self.talker, seq_id=self._seq % 10,
                                             channel="AB"[int(self.rng.integers(2))]):
                        yield from self._emit(t, msg, st)
                    self._seq += 1
                    self._next_static[i] = t_rel + _STATIC_INTERVAL_S
            tr.step()

    def lines(self, duration_s: float) -> Iterator[str]:
        """Only the NMEA lines of :meth:`run`."""
        for item in self.run(duration_s):
            yield item.line
