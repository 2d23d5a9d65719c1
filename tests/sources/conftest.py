"""Shared helpers of the sources tests: tagged NMEA made from ground truth with pyais."""

from __future__ import annotations

import math

import pytest

from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisPipeline, AisReport, encode_report, tag_block

T0 = 1_732_100_400.0  # 2024-11-20 11:00:00 UTC
#: A point in the fjord off Trondheim harbour, on water.
LAT, LON = 63.4600, 10.4000


def report(mmsi: int = 257_000_001, t: float = T0, *, lat: float = LAT, lon: float = LON,
           sog_m_s: float | None = 5.0, cog_deg: float | None = 45.0,
           heading_deg: float | None = 44.0, rot_rad_s: float | None = 0.0,
           msg_type: int = 1, nav_status: int | None = 0) -> AisReport:
    """Ground truth report (NED filled from the default scene)."""
    north, east = default_scene().frame.to_ned(lat, lon)
    return AisReport(mmsi=mmsi, t_unix_s=t, msg_type=msg_type, north_m=float(north),
                     east_m=float(east), lat_deg=lat, lon_deg=lon, sog_m_s=sog_m_s,
                     cog_rad=None if cog_deg is None else math.radians(cog_deg),
                     heading_rad=None if heading_deg is None else math.radians(heading_deg),
                     rot_rad_s=rot_rad_s if msg_type <= 3 else None,
                     nav_status=nav_status if msg_type <= 3 else None)


def line(r: AisReport, station: str = "2573555", channel: str = "A") -> str:
    """The tagged NMEA line a base station would send for ``r``."""
    return tag_block(station=station, t_unix_s=r.t_unix_s) + encode_report(r, channel=channel)


@pytest.fixture
def pipeline() -> AisPipeline:
    return AisPipeline(default_scene())


def xor(text: str) -> int:
    """NMEA checksum of a text (XOR of its bytes)."""
    cs = 0
    for ch in text.encode("ascii"):
        cs ^= ch
    return cs


def national_group(sentences: list[str], t: float, group_id: int = 9999) -> list[str]:
    """The lines of one multi-sentence message as the national feed writes them: a group tag
    block ``\\g:n-m-id,c:time*hh\\`` whose checksum covers only the ``c:`` field."""
    m = len(sentences)
    c = f"c:{int(t)}"
    return [f"\\g:{n}-{m}-{group_id},{c}*{xor(c):02X}\\{s}" for n, s in enumerate(sentences, 1)]


def tagged(sentence: str, t: float, station: str = "2573555") -> str:
    """A sentence behind a standard tag block (checksum over the whole tag)."""
    body = f"s:{station},c:{int(t)}"
    return f"\\{body}*{xor(body):02X}\\{sentence}"


def with_checksum(sentence_without_star: str) -> str:
    """``!AIVDM,...`` plus its correct ``*hh`` (for corrupt payloads that must pass it)."""
    return f"{sentence_without_star}*{xor(sentence_without_star[1:]):02X}"
