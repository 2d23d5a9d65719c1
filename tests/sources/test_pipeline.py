"""AIS decoding pipeline: real sentences, the round trip, and every kind of bad input."""

from __future__ import annotations

import logging
import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyais.encode import encode_dict

from asvtwin.geo import GeoBounds, LocalFrame, default_scene
from asvtwin.sources.ais import (
    AisPipeline,
    AisStatic,
    ErrorKind,
    TargetRegistry,
    encode_static,
    tag_block,
)
from asvtwin.units import KNOT_M_S

from .conftest import LAT, LON, T0, line, report

KYSTVERKET = r"\s:2573555,c:1707873398*05\!BSVDM,1,1,,A,13mB7d001E1dDH0`KlKBjB?<0490,0*34"
EVER_DIADEM = ("!AIVDM,2,1,1,A,55?MbV02;H;s<HtKR20EHE:0@T4@Dn2222222216L961O5Gf0NSQEp6ClRp8,0*1C",
               "!AIVDM,2,2,1,A,88888888880,2*25")


def _xor(text: str) -> int:
    cs = 0
    for ch in text.encode():
        cs ^= ch
    return cs


def errors(p: AisPipeline) -> dict[str, int]:
    return dict(p.stats.errors)


# ----------------------------------------------------------------------------- real data
def test_real_coastal_administration_sentence_decodes_in_its_own_scene() -> None:
    """A line of the Norwegian Coastal Administration open AIS feed: MMSI 257198000 off Hammerfest, 8.5 kn, COG 71.3, heading 71."""
    hammerfest = SimpleNamespace(bounds=GeoBounds(70.0, 71.0, 23.0, 24.0),
                                 frame=LocalFrame(70.66, 23.66))
    p = AisPipeline(hammerfest)  # type: ignore[arg-type]
    (r,) = p.feed(KYSTVERKET).reports()
    assert (r.mmsi, r.msg_type, r.station, r.t_unix_s) == (257198000, 1, "2573555", 1707873398.0)
    assert (r.lat_deg, r.lon_deg) == (70.664715, 23.662507)
    assert r.sog_m_s == pytest.approx(8.5 * 1852 / 3600)
    assert math.degrees(r.cog_rad) == pytest.approx(71.3)
    assert math.degrees(r.heading_rad) == pytest.approx(71.0)
    assert r.rot_rad_s == 0.0 and r.nav_status == 0
    north, east = hammerfest.frame.to_ned(70.664715, 23.662507)
    assert (r.north_m, r.east_m) == pytest.approx((float(north), float(east)), abs=1e-9)


def test_same_sentence_is_outside_the_trondheim_scene(pipeline: AisPipeline) -> None:
    assert len(pipeline.feed(KYSTVERKET)) == 0
    assert errors(pipeline) == {"outside_scene": 1}
    assert pipeline.stats.messages_by_type == {1: 1}


def test_type5_two_fragments_static_data(pipeline: AisPipeline) -> None:
    """pyais's documentation example: EVER DIADEM, 225+70 m by 1+31 m, draught 12.2 m."""
    batch = pipeline.feed_batch(EVER_DIADEM, recv_time_s=T0)
    (s,) = batch.static
    assert (s.mmsi, s.name, s.callsign, s.ship_type, s.imo) == (
        351759000, "EVER DIADEM", "3FOF8", 70, 9134270)
    assert (s.to_bow_m, s.to_stern_m, s.to_port_m, s.to_starboard_m) == (225, 70, 1, 31)
    assert (s.length_m, s.beam_m, s.draught_m, s.destination) == (295.0, 32.0, 12.2, "NEW YORK")


@settings(max_examples=60, deadline=None)
@given(lat=st.floats(63.42, 63.68), lon=st.floats(9.85, 10.75), sog_kn=st.floats(0, 40),
       cog=st.floats(0, 359.8), hdg=st.integers(0, 359), rot=st.floats(-0.05, 0.05))
def test_decode_of_encode_is_identity_to_ais_resolution(lat: float, lon: float, sog_kn: float,
                                                        cog: float, hdg: int, rot: float) -> None:
    truth = report(lat=lat, lon=lon, sog_m_s=sog_kn * KNOT_M_S, cog_deg=cog, heading_deg=hdg,
                   rot_rad_s=rot)
    (r,) = AisPipeline().feed(line(truth)).reports()
    assert abs(r.lat_deg - lat) <= 1.0 / 600_000 and abs(r.lon_deg - lon) <= 1.0 / 600_000
    # 1/10000 minute of arc: 0.19 m north, 0.08 m east at 63.5 N
    assert math.hypot(r.north_m - truth.north_m, r.east_m - truth.east_m) < 0.25
    assert abs(r.sog_m_s - truth.sog_m_s) <= 0.05 * KNOT_M_S + 1e-12
    assert abs(math.remainder(r.cog_rad - truth.cog_rad, 2 * math.pi)) <= math.radians(0.05) + 1e-12
    assert abs(math.remainder(r.heading_rad - math.radians(hdg), 2 * math.pi)) < 1e-12
    assert -math.pi <= r.heading_rad < math.pi and -math.pi <= r.cog_rad < math.pi
    # ROT travels as round(4.733 sqrt(deg/min)): coarse, sign kept
    assert r.rot_rad_s is not None
    if abs(rot) > 1e-3:
        assert math.copysign(1, r.rot_rad_s) == math.copysign(1, rot)


# ----------------------------------------------------------------------------- bad input
def test_wrong_checksum_counted_logged_once_and_skipped(pipeline: AisPipeline, caplog) -> None:
    good = line(report())
    bad = good[:-2] + ("00" if good[-2:] != "00" else "01")
    with caplog.at_level(logging.DEBUG, logger="asvtwin.sources.ais"):
        out = pipeline.feed_batch([bad, bad, good])
    assert len(out) == 1
    assert errors(pipeline) == {"bad_checksum": 2}
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "bad_checksum" in warnings[0].getMessage()
    assert bad in warnings[0].getMessage()


@pytest.mark.parametrize("cut", [10, 40, -5, -3])
def test_truncated_sentence(pipeline: AisPipeline, cut: int) -> None:
    text = line(report())
    tagged_end = text.index("!")
    if 0 < cut < tagged_end:
        expected = "truncated"  # inside the tag block: it is never closed
    else:
        expected = "truncated"
    assert len(pipeline.feed(text[:cut])) == 0
    assert errors(pipeline) == {expected: 1}


def test_truncated_payload_with_valid_checksum_is_short(pipeline: AisPipeline) -> None:
    body = "!AIVDM,1,1,,A,13mB7d001E1dDH0,0"
    cs = 0
    for ch in body[1:].encode():
        cs ^= ch
    pipeline.feed(f"{tag_block(station='1', t_unix_s=T0)}{body}*{cs:02X}")
    assert errors(pipeline) == {"short_payload": 1}


def test_non_ascii_bytes(pipeline: AisPipeline) -> None:
    good = line(report()).encode()
    assert len(pipeline.feed_batch([good[:30] + "ø".encode() + good[30:],
                                    good[:20] + b"\xff\xfe" + good[20:]])) == 0
    # the first is broken inside the sentence; in the second the bytes broke the tag block
    # only: the sentence after it is kept (resynced) but has no time left
    assert errors(pipeline) == {"non_ascii": 1, "missing_time": 1}
    assert pipeline.stats.notices == {"resynced": 1}


def test_lone_and_out_of_order_fragments() -> None:
    p = AisPipeline()
    f1, f2 = EVER_DIADEM
    tb = tag_block(station="2573555", t_unix_s=T0)
    out = p.feed_batch([tb + f2])  # fragment 2 without 1
    assert errors(p) == {"orphan_fragment": 1} and not out.static
    # three fragments arriving 1, 3: fragment 2 missing
    body = ["!AIVDM,3,1,7,B,55?MbV02;H;s<HtKR20EHE:0@T4@Dn22222222,0",
            "!AIVDM,3,3,7,B,88888888880,2"]
    sentences = []
    for b in body:
        cs = 0
        for ch in b[1:].encode():
            cs ^= ch
        sentences.append(f"{tb}{b}*{cs:02X}")
    p.feed_batch(sentences)
    assert errors(p) == {"orphan_fragment": 1, "out_of_order_fragment": 1}
    # 1 then 1 again: the first message never completes
    p.feed_batch([tb + f1, tb + f1, tb + f2])
    assert errors(p)["incomplete_fragment"] == 1
    assert p.stats.statics == 1


def test_fragment_timeout_expires_pending_message() -> None:
    p = AisPipeline(fragment_timeout_s=10.0)
    f1, _ = EVER_DIADEM
    p.feed(tag_block(station="1", t_unix_s=T0) + f1)
    other = encode_static(AisStatic(mmsi=257000009, t_unix_s=T0, msg_type=5, name="X"), seq_id=2)
    p.feed(tag_block(station="1", t_unix_s=T0 + 60) + other[0][0])
    assert errors(p) == {"incomplete_fragment": 1}


def test_interleaved_multifragment_messages_from_two_stations() -> None:
    """Same sequence id and channel, fragments interleaved: the station keeps them apart."""
    a = AisStatic(mmsi=257000001, t_unix_s=T0, msg_type=5, name="ALFA", callsign="LA1",
                  ship_type=60, to_bow_m=50, to_stern_m=30, to_port_m=8, to_starboard_m=8)
    b = AisStatic(mmsi=257000002, t_unix_s=T0, msg_type=5, name="BRAVO", callsign="LB2",
                  ship_type=30, to_bow_m=12, to_stern_m=8, to_port_m=3, to_starboard_m=3)
    (fa,) = encode_static(a, seq_id=3)
    (fb,) = encode_static(b, seq_id=3)
    ta, tb = tag_block(station="2573555", t_unix_s=T0), tag_block(station="2573250", t_unix_s=T0)
    p = AisPipeline()
    out = p.feed_batch([ta + fa[0], tb + fb[0], ta + fa[1], tb + fb[1]])
    got = {s.mmsi: s for s in out.static}
    assert (got[257000001].name, got[257000001].length_m) == ("ALFA", 80.0)
    assert (got[257000002].name, got[257000002].length_m) == ("BRAVO", 20.0)
    assert errors(p) == {}


def test_tag_block_without_payload_and_bad_tag_block(pipeline: AisPipeline) -> None:
    tb = tag_block(station="2573555", t_unix_s=T0)
    good = line(report())
    body = good[good.index("!"):]
    broken_tag = "\\s:2573555,c:1732100400*F8\\" + body  # wrong tag block checksum
    pipeline.feed_batch([tb, tb + "   ", "\\s:2573555,c:1707873398*05", broken_tag,
                         f"\\s:1,c:17x*{_xor('s:1,c:17x'):02X}\\" + body])  # c: not a number
    e = errors(pipeline)
    assert e["tag_block_without_payload"] == 2
    assert e["truncated"] == 1  # tag block never closed
    assert e["bad_tag_checksum"] == 1 and e["bad_tag_block"] == 1


def test_not_available_values_never_become_numbers() -> None:
    truth = report(sog_m_s=None, cog_deg=None, heading_deg=None, rot_rad_s=None,
                   nav_status=None)
    p = AisPipeline()
    batch = p.feed(line(truth))
    (r,) = batch.reports()
    assert (r.sog_m_s, r.cog_rad, r.heading_rad, r.rot_rad_s, r.nav_status) == (None,) * 5
    assert r.velocity_m_s is None
    reg = TargetRegistry(epoch_unix_s=T0)
    reg.update_batch(batch)
    snap = reg.extrapolate(30.0)
    for arr in (snap.position_m, snap.velocity_m_s, snap.heading_rad, snap.age_s):
        assert np.all(np.isfinite(arr))
    assert not snap.velocity_known[0]
    assert tuple(snap.position_m[0]) == pytest.approx((truth.north_m, truth.east_m), abs=0.25)


def test_position_not_available_and_invalid() -> None:
    p = AisPipeline()
    tb = tag_block(station="1", t_unix_s=T0)
    for lat, lon in ((91.0, 181.0), (91.0, 10.4)):
        s = encode_dict({"type": 1, "mmsi": 257000001, "lat": lat, "lon": lon, "speed": 3.0},
                        talker_id="AB", sentence_type="VDM")[0]
        p.feed(tb + s)
    s = encode_dict({"type": 18, "mmsi": 257000001, "lat": -95.0, "lon": 10.4},
                    talker_id="AB", sentence_type="VDM")[0]
    p.feed(tb + s)
    assert errors(p) == {"position_unavailable": 2, "invalid_position": 1}


def test_time_backwards_and_far_future() -> None:
    now = T0 + 5.0
    p = AisPipeline(clock=lambda: now, max_future_s=60.0)
    r1, r0 = report(t=T0), report(t=T0 - 10.0, lat=LAT + 0.001)
    out = p.feed_batch([line(r1), line(r0), line(report(t=T0 + 3600.0, lat=LAT + 0.002))])
    assert len(out) == 1
    assert errors(p) == {"time_backwards": 1, "time_future": 1}
    # without a clock: a jump beyond max_jump_s over the stream is the future
    q = AisPipeline(max_jump_s=3600.0)
    q.feed_batch([line(r1), line(report(mmsi=257000002, t=T0 + 86_400.0))])
    assert errors(q) == {"time_future": 1}
    # a time before 2000 is invalid
    q.feed(line(report(mmsi=257000003, t=100.0)))
    assert errors(q)["invalid_time"] == 1


def test_missing_time_and_receive_time_from_the_caller() -> None:
    r = report()
    bare = line(r)[line(r).index("!"):]
    p = AisPipeline()
    assert len(p.feed(bare)) == 0
    assert errors(p) == {"missing_time": 1}
    (got,) = p.feed(bare, recv_time_s=T0 + 7.0).reports()
    assert got.t_unix_s == T0 + 7.0 and got.station is None


def test_tag_block_time_in_milliseconds(pipeline: AisPipeline) -> None:
    r = report()
    body = line(r)[line(r).index("!"):]
    tb = f"s:x,c:{int(T0 * 1000 + 250)}"
    cs = 0
    for ch in tb.encode():
        cs ^= ch
    (got,) = pipeline.feed(f"\\{tb}*{cs:02X}\\{body}").reports()
    assert got.t_unix_s == pytest.approx(T0 + 0.25)


def test_duplicate_report_from_two_base_stations(pipeline: AisPipeline) -> None:
    r = report()
    out = pipeline.feed_batch([line(r, station="2573555"), line(r, station="2573250"),
                               line(report(t=T0 + 10, lat=LAT + 0.001))])
    assert len(out) == 2
    assert errors(pipeline) == {"duplicate": 1}


def test_other_sentences_types_and_mmsi(pipeline: AisPipeline) -> None:
    gga = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
    cs = 0
    for ch in gga[1:].encode():
        cs ^= ch
    tb = tag_block(station="1", t_unix_s=T0)
    base_station = encode_dict({"type": 4, "mmsi": 2573555, "lat": LAT, "lon": LON},
                               talker_id="AB", sentence_type="VDM")[0]
    zero = encode_dict({"type": 1, "mmsi": 0, "lat": LAT, "lon": LON},
                       talker_id="AB", sentence_type="VDM")[0]
    pipeline.feed_batch([f"{gga}*{cs:02X}", tb + base_station, tb + zero, "", "  \r\n"])
    assert errors(pipeline) == {"not_ais": 1, "invalid_mmsi": 1}
    assert pipeline.stats.messages_by_type == {4: 1, 1: 1}
    assert pipeline.stats.lines == 3  # blank lines are not input


def test_class_b_report_and_static_24(pipeline: AisPipeline) -> None:
    truth = report(msg_type=18, heading_deg=None)
    s = AisStatic(mmsi=truth.mmsi, t_unix_s=T0, msg_type=24, name="SJOBLIKK",
                  callsign="LM1234", ship_type=37, to_bow_m=7, to_stern_m=5, to_port_m=1,
                  to_starboard_m=1)
    tb = tag_block(station="1", t_unix_s=T0)
    lines = [line(truth)] + [tb + m[0] for m in encode_static(s)]
    batch = pipeline.feed_batch(lines)
    (r,) = batch.reports()
    assert r.is_class_b and r.rot_rad_s is None and r.nav_status is None and r.heading_rad is None
    reg = TargetRegistry()
    reg.update_batch(batch)
    merged = reg.static(truth.mmsi)
    assert (merged.name, merged.ship_type, merged.length_m, merged.beam_m) == (
        "SJOBLIKK", 37, 12.0, 2.0)


def test_default_scene_bounds_are_the_filter() -> None:
    b = default_scene().bounds
    p = AisPipeline()
    inside = report(lat=b.lat_max_deg - 0.001, lon=b.lon_min_deg + 0.001)
    outside = report(mmsi=257000002, lat=b.lat_max_deg + 0.01, lon=10.4)
    assert len(p.feed_batch([line(inside), line(outside)])) == 1
    assert errors(p) == {"outside_scene": 1}
    assert ErrorKind("outside_scene") is ErrorKind.OUTSIDE_SCENE
