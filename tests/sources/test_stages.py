"""The AIS pipeline's stages one by one: framing and checks (``sentence``), duplicates,
validation, records. The whole pipeline is tested in ``test_pipeline.py`` and the catalogue;
these pin each stage's own contract with hand-made input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pyais.messages import AISSentence

from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisReport, encode_report
from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind
from asvtwin.sources.ais.duplicates import DuplicateFilter
from asvtwin.sources.ais.records import COLUMNS, report_batch
from asvtwin.sources.ais.sentence import TagCache, check_ais, prefix_xor, resync
from asvtwin.sources.ais.tagblock import xor_checksum
from asvtwin.sources.ais.timebase import StreamClock
from asvtwin.sources.ais.validation import ReportValidator, TimeReference
from asvtwin.units import KNOT_M_S

from .conftest import LAT, LON, T0, report, with_checksum, xor

SENTENCE = encode_report(report())


# ------------------------------------------------------------------ 1. sentence
@pytest.mark.parametrize(("raw", "start"), [
    (b"!AIVDM,1,1", 0),
    (b"\x00\x00!AIVDM,1,1", 2),
    (b"\xff\xfe\\s:1,c:2*00\\!AIVDM", 2),  # the tag block is kept after non-ASCII garbage
    (b"c:1700000000*05\\!AIVDM", 16),  # a tag block cut at its start: its end is skipped
    (b"xx$GPGGA,1", 2),
    (b"no sentence here", -1),
    (b"\xff!\xfe", -1),  # "!" before the last non-ASCII byte does not count
])
def test_resync_finds_the_sentence_after_garbage(raw, start) -> None:
    assert resync(raw) == start


def test_prefix_xor_gives_every_checksum_of_a_batch() -> None:
    rng = np.random.default_rng(2)
    data = bytes(rng.integers(32, 127, 500).tolist())
    P = prefix_xor(data)
    for a, b in rng.integers(1, 500, (50, 2)):
        a, b = sorted((int(a), int(b)))
        assert P[b - 1] ^ P[a - 1] == xor_checksum(data[a:b])
    assert prefix_xor(b"") == b""


def _tag_line(body: str, cs: int | None = None) -> bytes:
    return f"\\{body}*{(xor(body) if cs is None else cs):02X}\\{SENTENCE}".encode()


def test_the_tag_cache_parses_once_and_keeps_the_offset_apart() -> None:
    cache = TagCache(size=4)
    raw = _tag_line(f"s:2573555,c:{int(T0)}")
    tag = raw[1:raw.index(b"\\", 1)]
    assert cache.get(tag) is None
    assert cache.parse(tag, prefix_xor(raw), 0) == (T0, "2573555", False)
    assert cache.get(tag) == (T0, "2573555", False)
    cache.set_offset(100.0)  # file replay's second pass: times move, the cache forgets them
    assert cache.get(tag) is None
    assert cache.parse(tag, prefix_xor(raw), 0)[0] == T0 + 100.0


def test_the_tag_cache_keeps_rejections_with_what_was_computed() -> None:
    cache = TagCache()
    raw = _tag_line(f"s:2573555,c:{int(T0)}", cs=0)
    tag = raw[1:raw.index(b"\\", 1)]
    kind, detail = cache.parse(tag, prefix_xor(raw), 0)
    assert kind is ErrorKind.BAD_TAG_CHECKSUM and "0x00 in the tag" in detail
    assert cache.get(tag) == (kind, detail)
    raw = _tag_line("s:2573555,c:12ab")
    assert cache.parse(raw[1:raw.index(b"\\", 1)], prefix_xor(raw), 0)[0] \
        is ErrorKind.BAD_TAG_BLOCK


def test_the_national_group_convention_is_parsed_and_flagged() -> None:
    c = f"c:{int(T0)}"
    raw = f"\\g:1-2-9999,{c}*{xor(c):02X}\\{SENTENCE}".encode()
    tag = raw[1:raw.index(b"\\", 1)]
    assert TagCache().parse(tag, prefix_xor(raw), 0) == (T0, None, True)


@pytest.mark.parametrize(("sentence", "kind"), [
    (SENTENCE, None),
    (SENTENCE[:3] + "VDO" + SENTENCE[6:], ErrorKind.OWN_SHIP),
    (SENTENCE[:-4] + "x", ErrorKind.MALFORMED),  # fill bits "x"
    (SENTENCE.split(",")[0] + ",1,1,,A," + "1" * 20 + "y" + "1" * 7 + ",0", ErrorKind.DECODE_ERROR),
    ("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", ErrorKind.NOT_AIS),
    ("!AIVDM,x,1,,A,13m62@@01QPgVp0TCvH1hQH1P000,0", ErrorKind.MALFORMED),  # count "x"
])
def test_check_ais_gives_the_sentence_or_why_not(sentence, kind) -> None:
    body = (sentence if kind is None else with_checksum(sentence.split("*")[0])).encode()
    got = check_ais(body, body.rfind(b"*"))
    if kind is None:
        assert isinstance(got, AISSentence) and got.decode().mmsi == 257_000_001
    else:
        assert isinstance(got, tuple) and got[0] is kind, got


# ------------------------------------------------------------------ 3. duplicates
def test_a_second_reception_within_the_window_is_a_duplicate() -> None:
    d = DuplicateFilter(30.0)
    assert d.is_duplicate(b"P1", T0, None) is None
    assert d.is_duplicate(b"P1", T0 + 30.0, T0) == T0  # at the window's edge: still one
    assert d.is_duplicate(b"P1", T0 + 30.5, T0) is None  # a new transmission, remembered
    assert d.is_duplicate(b"P1", T0 + 40.0, T0 + 30.5) == T0 + 30.5


def test_the_duplicate_memory_is_bounded_and_ignores_what_it_would_forget() -> None:
    d = DuplicateFilter(30.0)
    for k in range(100):
        d.is_duplicate(b"P%d" % k, T0 + k, T0 + k)
    d.trim(T0 + 99.0)
    assert len(d) == 61  # payloads of the last 2 windows (t >= T0 + 39)
    # a payload older than 2 windows behind the latest report is not a duplicate even if
    # it is still remembered (so that the result does not depend on when trim ran)
    d2 = DuplicateFilter(30.0)
    d2.is_duplicate(b"Q", T0, None)
    assert d2.is_duplicate(b"Q", T0 + 10.0, T0 + 61.0) is None


# ------------------------------------------------------------------ 5. validation
def _validator(**kw: object) -> tuple[ReportValidator, ErrorCounter, ErrorCounter]:
    errors, notices = ErrorCounter(), ErrorCounter()
    stream = StreamClock()
    stream.prime([T0])  # the stream's robust time: T0
    v = ReportValidator(default_scene().bounds, errors, notices, stream,
                        bounds=kw.get("bounds", True), require_time=kw.get("require_time", True),
                        max_tracked_mmsi=int(kw.get("max_tracked", 1000)))  # type: ignore[call-overload]
    return v, errors, notices


@pytest.mark.parametrize(("mmsi", "t", "kind"), [
    (257_000_001, T0, None), (0, T0, "invalid_mmsi"), (1_000_000_000, T0, "invalid_mmsi"),
    (257_000_001, None, "missing_time"), (257_000_001, 100.0, "invalid_time"),
    (257_000_001, 5e9, "invalid_time"),
])
def test_identity_and_time(mmsi, t, kind) -> None:
    v, errors, _ = _validator()
    got = v.identity_and_time(b"line", mmsi, t)
    assert (got == t) if kind is None else (got is None and dict(errors.counts) == {kind: 1})


def test_an_untimed_report_is_kept_when_no_time_is_required() -> None:
    v, _, notices = _validator(require_time=False)
    assert math.isnan(v.identity_and_time(b"line", 257_000_001, None))  # type: ignore[arg-type]
    assert notices["untimed"] == 1


@pytest.mark.parametrize(("lat", "lon", "t", "kind"), [
    (LAT, LON, T0, None),
    (91.0, LON, T0, "position_unavailable"), (LAT, 181.0, T0, "position_unavailable"),
    (-95.0, LON, T0, "invalid_position"), (69.0, 16.0, T0, "outside_scene"),
    (LAT, LON, T0 + 601.0, "time_future"),  # stream time T0, lead 600 s
])
def test_position_and_time_order(lat, lon, t, kind) -> None:
    v, errors, _ = _validator()
    run = TimeReference(None, T0, 600.0, -math.inf, None)
    assert v.position(run, b"line", 257_000_001, t, lat, lon) is (kind is None)
    assert dict(errors.counts) == ({} if kind is None else {kind: 1})
    assert run.hwm == (t if kind is None else None)


def test_time_order_per_vessel_and_a_lagging_receive_clock() -> None:
    v, errors, notices = _validator()
    run = TimeReference(T0 + 3600.0, T0 + 3600.0, 60.0, T0 + 3000.0, None)  # 1 h behind
    assert v.position(run, b"a", 257_000_001, T0 + 10.0, LAT, LON)
    assert not v.position(run, b"b", 257_000_001, T0 + 5.0, LAT, LON)  # behind its last
    assert v.position(run, b"c", 257_000_002, T0 + 5.0, LAT, LON)  # another vessel: fine
    assert errors["time_backwards"] == 1 and notices["feed_clock_lags"] == 2
    assert run.hwm == T0 + 10.0


def test_outside_the_scene_is_kept_with_a_notice_without_bounds() -> None:
    v, errors, notices = _validator(bounds=False)
    run = TimeReference(None, None, 600.0, -math.inf, None)
    assert v.position(run, b"line", 257_000_001, T0, 69.0, 16.0)
    assert not errors.counts and notices["outside_scene_kept"] == 1


def test_the_validator_forgets_the_longest_silent_vessels_beyond_its_limit() -> None:
    v, _, _ = _validator(max_tracked=10)
    run = TimeReference(None, None, 600.0, -math.inf, None)
    for k in range(11):
        v.position(run, b"line", 257_000_000 + k, T0 + k, LAT, LON)
    v.trim()
    assert sorted(v.last_t) == [257_000_000 + k for k in range(5, 11)]


# ------------------------------------------------------------------ 6. records
def test_report_columns_become_si_ned_and_not_available_becomes_nan() -> None:
    frame = default_scene().frame
    rows = [  # type, mmsi, lat, lon, sog kn, cog deg, heading deg, rot deg/min, status
        (1, 257_000_001, LAT, LON, 10.0, 359.9, 180.0, 127.0, 0),
        (1, 257_000_002, LAT, LON, 102.3, 360.0, 511.0, -128.0, 15),
        (18, 257_000_003, LAT, LON, 0.1, 90.0, 90.0, math.nan, 15),
        (3, 257_000_004, LAT, LON, 3.0, 180.0, 0.0, 4.0, 5),
    ]
    cols = {k: np.array([r[c] for r in rows]) for c, k in enumerate(COLUMNS)}
    b = report_batch(cols, [T0] * 4, ["s", None, "s", "s"], (), frame)
    north, east = frame.to_ned(LAT, LON)
    assert np.allclose(b.north_m, north) and np.allclose(b.east_m, east)
    assert b.sog_m_s[0] == pytest.approx(10.0 * KNOT_M_S) and math.isnan(b.sog_m_s[1])
    assert b.cog_rad[0] == pytest.approx(math.radians(-0.1))  # wrapped to [-pi, pi)
    assert b.cog_rad[3] == pytest.approx(-math.pi)
    assert math.isnan(b.cog_rad[1]) and math.isnan(b.heading_rad[1])
    assert b.heading_rad[0] == pytest.approx(-math.pi)
    assert np.isnan(b.rot_rad_s[:3]).all()  # 127 / -128: no value; class B: none
    assert b.rot_rad_s[3] == pytest.approx(math.radians(4.0) / 60.0)
    assert b.nav_status.tolist() == [0, -1, -1, 5] and b.msg_type.tolist() == [1, 1, 18, 3]
    r = b.reports()[1]
    assert isinstance(r, AisReport) and r.sog_m_s is None and r.cog_rad is None
    assert b.station == ("s", None, "s", "s") and b.frame is frame
