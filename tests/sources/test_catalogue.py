"""A catalogue of bad input, mixed into a valid stream (issue, "what must be shown").

Each entry makes one kind of corruption, at a given stream time, for a vessel of its own (a
"poison" MMSI placed in the fjord, so that anything let through would show in the picture),
and says how the pipeline must count it. The tests check, for every entry alone, that it is
counted exactly under its reason(s); and, for all of them mixed into one synthetic stream,
that nothing crashes, nothing of theirs reaches the accepted reports or the registry, the
valid stream is accepted exactly as without them, and every count is the same for any batch
size.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from functools import partial

import numpy as np
import pytest
from pyais.encode import encode_dict

from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    AisStatic,
    SyntheticTraffic,
    TargetRegistry,
    encode_report,
    encode_static,
)

from .conftest import LAT, LON, T0, national_group, report, xor

POISON = 990_000_000  #: poison MMSIs are POISON + k


def _tag(t: float, station: str = "2573555", extra: str = "") -> str:
    body = f"{extra}s:{station},c:{int(t)}"
    return f"\\{body}*{xor(body):02X}\\"


def _raw_tag(body: str) -> str:
    return f"\\{body}*{xor(body):02X}\\"


def _cs(sentence_without_star: str) -> str:
    return f"{sentence_without_star}*{xor(sentence_without_star[1:]):02X}"


def _poison(t: float, k: int, **kw: object) -> AisReport:
    return report(mmsi=POISON + k, t=t, lat=kw.pop("lat", LAT + 1e-3 * (k % 50)),  # type: ignore[arg-type]
                  lon=kw.pop("lon", LON), **kw)  # type: ignore[arg-type]


def _sentence(t: float, k: int, **kw: object) -> str:
    return encode_report(_poison(t, k, **kw))


def _parts(sentence: str) -> tuple[str, str, str]:
    """``("!AIVDM,1,1,,A", payload, fill)`` of a one-fragment sentence."""
    head, payload, fill = sentence.split("*")[0].rsplit(",", 2)
    return head, payload, fill


def _payload_swap(t: float, k: int, ch: str, *, fix_checksum: bool) -> list[str]:
    head, payload, fill = _parts(_sentence(t, k))
    bad = f"{head},{payload[:10]}{ch}{payload[11:]},{fill}"
    s = _cs(bad) if fix_checksum else bad + _sentence(t, k)[-3:]
    return [_tag(t) + s]


def _swap_fixed(ch: str, t: float, k: int) -> list[str]:
    return _payload_swap(t, k, ch, fix_checksum=True)


def _dict_sentence(t: float, k: int, **fields: object) -> str:
    data = {"type": 1, "mmsi": POISON + k, "lat": LAT, "lon": LON, "speed": 5.0,
            "course": 45.0} | fields
    return _tag(t) + encode_dict(data, talker_id="AI", sentence_type="VDM")[0]


def _static(k: int, dest: str = "TRONDHEIM") -> AisStatic:
    return AisStatic(mmsi=POISON + k, t_unix_s=T0, msg_type=5, name=f"POISON {k}",
                     destination=dest)


def _frags(k: int, seq: int = 7, dest: str = "TRONDHEIM") -> list[str]:
    (f,) = encode_static(_static(k, dest), seq_id=seq)
    return f


def _good(t: float, k: int) -> str:
    return _tag(t) + _sentence(t, k)


Gen = Callable[[float, int], list[str]]
E = dict[str, int]

CATALOGUE: list[tuple[str, E, Gen]] = [
    # ---------------------------------------------------------------- bytes and framing
    ("utf8_in_payload", {"non_ascii": 1}, lambda t, k: [_good(t, k)[:50] + "é" + _good(t, k)[51:]]),
    ("latin1_at_end", {"non_ascii": 1}, lambda t, k: [_good(t, k) + "\xff"]),
    ("non_ascii_in_checksum", {"non_ascii": 1}, lambda t, k: [_good(t, k)[:-1] + "ø"]),
    ("nul_in_payload", {"bad_checksum": 1}, lambda t, k: _payload_swap(t, k, "\x00", fix_checksum=False)),
    ("nul_in_payload_fixed_checksum", {"decode_error": 1}, lambda t, k: _payload_swap(t, k, "\x00", fix_checksum=True)),
    ("cr_in_payload", {"bad_checksum": 1}, lambda t, k: _payload_swap(t, k, "\r", fix_checksum=False)),
    ("printable_garbage", {"truncated": 1}, lambda t, k: ["hello world, this is not NMEA"]),
    ("garbage_then_bang", {"truncated": 1}, lambda t, k: ["xx!yy and more garbage"]),
    ("cut_inside_tag", {"truncated": 1}, lambda t, k: [_good(t, k)[:12]]),
    ("cut_after_tag", {"tag_block_without_payload": 1}, lambda t, k: [_tag(t)]),
    ("cut_after_talker", {"truncated": 1}, lambda t, k: [_tag(t) + "!AIVDM"]),
    ("cut_mid_payload", {"truncated": 1}, lambda t, k: [_good(t, k)[:60]]),
    ("cut_one_checksum_digit", {"truncated": 1}, lambda t, k: [_good(t, k)[:-1]]),
    ("cut_whole_checksum", {"truncated": 1}, lambda t, k: [_good(t, k)[:-3]]),
    ("checksum_not_hex", {"truncated": 1}, lambda t, k: [_good(t, k)[:-2] + "ZZ"]),
    ("checksum_off_by_one", {"bad_checksum": 1}, lambda t, k: [_good(t, k)[:-2] + f"{(int(_good(t, k)[-2:], 16) + 1) % 256:02X}"]),
    ("checksum_including_bang", {"bad_checksum": 1}, lambda t, k: [_tag(t) + _sentence(t, k).split("*")[0] + f"*{xor(_sentence(t, k).split('*')[0]):02X}"]),
    ("payload_char_flipped", {"bad_checksum": 1}, lambda t, k: _payload_swap(t, k, "0" if _parts(_sentence(t, k))[1][10] != "0" else "1", fix_checksum=False)),
    ("two_sentences_on_one_line", {"bad_checksum": 1}, lambda t, k: [_good(t, k) + _sentence(t, k + 1)]),
    # ---------------------------------------------------------------- tag blocks
    ("tag_checksum_wrong", {"bad_tag_checksum": 1}, lambda t, k: [_good(t, k).replace(_tag(t), _tag(t)[:-3] + f"{(xor(f's:2573555,c:{int(t)}') ^ 0x21):02X}\\")]),
    ("tag_without_checksum", {"bad_tag_block": 1}, lambda t, k: [f"\\s:2573555,c:{int(t)}\\" + _sentence(t, k)]),
    ("tag_checksum_not_hex", {"bad_tag_block": 1}, lambda t, k: [f"\\s:2573555,c:{int(t)}*G1\\" + _sentence(t, k)]),
    ("tag_time_letters", {"bad_tag_block": 1}, lambda t, k: [_raw_tag("s:1,c:17abc") + _sentence(t, k)]),
    ("tag_time_inf", {"bad_tag_block": 1}, lambda t, k: [_raw_tag("s:1,c:inf") + _sentence(t, k)]),
    ("tag_time_nan", {"bad_tag_block": 1}, lambda t, k: [_raw_tag("s:1,c:nan") + _sentence(t, k)]),
    ("tag_time_negative", {"bad_tag_block": 1}, lambda t, k: [_raw_tag(f"s:1,c:-{int(t)}") + _sentence(t, k)]),
    ("tag_time_exponent", {"bad_tag_block": 1}, lambda t, k: [_raw_tag("s:1,c:1.7e9") + _sentence(t, k)]),
    ("tag_time_too_many_digits", {"bad_tag_block": 1}, lambda t, k: [_raw_tag("s:1,c:12345678901234567") + _sentence(t, k)]),
    ("tag_two_times", {"bad_tag_block": 1}, lambda t, k: [_raw_tag(f"c:{int(t)},c:{int(t)}") + _sentence(t, k)]),
    ("tag_group_short", {"bad_tag_block": 1}, lambda t, k: [_raw_tag(f"g:1-2,c:{int(t)}") + _sentence(t, k)]),
    ("tag_group_n_above_m", {"bad_tag_block": 1}, lambda t, k: [_raw_tag(f"g:3-2-5,c:{int(t)}") + _sentence(t, k)]),
    ("tag_field_without_colon", {"bad_tag_block": 1}, lambda t, k: [_raw_tag(f"xyz,c:{int(t)}") + _sentence(t, k)]),
    ("tag_empty", {"bad_tag_block": 1}, lambda t, k: ["\\*00\\" + _sentence(t, k)]),
    ("tag_not_closed", {"truncated": 1}, lambda t, k: [f"\\s:2573555,c:{int(t)}" + _sentence(t, k)]),
    ("tag_c_only_convention_wrong", {"bad_tag_checksum": 1}, lambda t, k: [f"\\g:1-1-5,c:{int(t)}*{xor(f'c:{int(t)}') ^ 4:02X}\\" + _sentence(t, k)]),
    # ---------------------------------------------------------------- time
    ("time_1970", {"invalid_time": 1}, lambda t, k: [_tag(0) + _sentence(t, k)]),
    ("time_1999", {"invalid_time": 1}, lambda t, k: [_tag(946_000_000) + _sentence(t, k)]),
    ("time_2150", {"invalid_time": 1}, lambda t, k: [_tag(5_680_000_000) + _sentence(t, k)]),
    ("time_ms_2150", {"invalid_time": 1}, lambda t, k: [_tag(5_680_000_000_000) + _sentence(t, k)]),
    ("time_plus_3_hours", {"time_future": 1}, lambda t, k: [_tag(t + 10_800) + _sentence(t, k)]),
    ("time_2099", {"time_future": 1}, lambda t, k: [_tag(4_070_908_800) + _sentence(t, k)]),
    ("time_plus_3_hours_class_b", {"time_future": 1}, lambda t, k: [_tag(t + 10_800) + _sentence(t, k, msg_type=18)]),
    ("no_time_at_all", {"missing_time": 1}, lambda t, k: [_sentence(t, k)]),
    ("tag_without_time", {"missing_time": 1}, lambda t, k: [_raw_tag("s:2573555") + _sentence(t, k)]),
    # ---------------------------------------------------------------- sentence fields
    ("gga_not_ais", {"not_ais": 1}, lambda t, k: [_tag(t) + _cs("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")]),
    ("unknown_sentence", {"not_ais": 1}, lambda t, k: [_tag(t) + _cs("$GPXYZ,1,2,3")]),
    ("own_ship_vdo", {"own_ship": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0].replace("VDM", "VDO"))]),
    ("own_ship_vdo_class_b", {"own_ship": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k, msg_type=18).split("*")[0].replace("VDM", "VDO"))]),
    ("fragment_count_zero", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0].replace("VDM,1,1", "VDM,0,1"))]),
    ("fragment_number_above_count", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0].replace("VDM,1,1", "VDM,1,2"))]),
    ("fragment_count_letters", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0].replace("VDM,1,1", "VDM,x,1"))]),
    ("sequence_id_letters", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0].replace("VDM,1,1,,", "VDM,1,1,q,"))]),
    ("fill_bits_6", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0][:-1] + "6")]),
    ("fill_bits_letter", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0][:-1] + "x")]),
    ("fill_bits_missing", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0][:-2])]),
    ("fill_bits_two_digits", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0] + "0")]),
    ("extra_field", {"malformed": 1}, lambda t, k: [_tag(t) + _cs(_sentence(t, k).split("*")[0] + ",extra")]),
    ("missing_fields", {"malformed": 1}, lambda t, k: [_tag(t) + _cs("!AIVDM,1,1,A")]),
    ("payload_too_long", {"malformed": 1}, lambda t, k: [_tag(t) + _cs("!AIVDM,1,1,,A," + "1" * 400 + ",0")]),
    # ---------------------------------------------------------------- payload
    *[(f"armour_{name}", {"decode_error": 1}, partial(_swap_fixed, ch))
      for name, ch in (("X", "X"), ("Z", "Z"), ("bracket", "["), ("backslash_like", "^"),
                       ("underscore", "_"), ("x", "x"), ("brace", "{"), ("pipe", "|"),
                       ("tilde", "~"), ("space", " "), ("bang", "!"), ("quote", '"'),
                       ("hash", "#"), ("slash", "/"), ("paren", "("))],
    ("empty_payload", {"short_payload": 1}, lambda t, k: [_tag(t) + _cs("!AIVDM,1,1,,A,,0")]),
    ("payload_one_char_short", {"short_payload": 1}, lambda t, k: [_tag(t) + _cs(f"{_parts(_sentence(t, k))[0]},{_parts(_sentence(t, k))[1][:-1]},0")]),
    ("payload_half", {"short_payload": 1}, lambda t, k: [_tag(t) + _cs(f"{_parts(_sentence(t, k))[0]},{_parts(_sentence(t, k))[1][:14]},0")]),
    ("type5_single_fragment", {"short_payload": 1}, lambda t, k: [_tag(t) + _cs(f"!AIVDM,1,1,,A,{_frags(k)[0].split(',')[5]},0")]),
    ("class_b_short", {"short_payload": 1}, lambda t, k: [_tag(t) + _cs(f"{_parts(_sentence(t, k, msg_type=18))[0]},{_parts(_sentence(t, k, msg_type=18))[1][:20]},0")]),
    ("mmsi_zero", {"invalid_mmsi": 1}, lambda t, k: [_dict_sentence(t, k, mmsi=0)]),
    ("mmsi_too_large", {"invalid_mmsi": 1}, lambda t, k: [_dict_sentence(t, k, mmsi=1_073_741_823)]),
    ("lat_91", {"position_unavailable": 1}, lambda t, k: [_dict_sentence(t, k, lat=91.0)]),
    ("lon_181", {"position_unavailable": 1}, lambda t, k: [_dict_sentence(t, k, lon=181.0)]),
    ("class_b_lat_91", {"position_unavailable": 1}, lambda t, k: [_dict_sentence(t, k, type=18, lat=91.0)]),
    ("lat_95", {"invalid_position": 1}, lambda t, k: [_dict_sentence(t, k, lat=95.0)]),
    ("lon_minus_200", {"invalid_position": 1}, lambda t, k: [_dict_sentence(t, k, lon=-200.0)]),
    ("oslo", {"outside_scene": 1}, lambda t, k: [_dict_sentence(t, k, lat=59.91, lon=10.75)]),
    ("class_b_equator", {"outside_scene": 1}, lambda t, k: [_dict_sentence(t, k, type=18, lat=0.0, lon=0.0)]),
    # ---------------------------------------------------------------- fragments
    ("orphan_second_fragment", {"orphan_fragment": 1}, lambda t, k: [_tag(t) + _frags(k)[1]]),
    ("never_completed", {"incomplete_fragment": 1}, lambda t, k: [_tag(t) + _frags(k)[0]]),
    ("second_fragment_late", {"incomplete_fragment": 1, "orphan_fragment": 1},
     lambda t, k: [_tag(t) + _frags(k)[0], _tag(t + 15) + _frags(k)[1]]),
    ("chimera", {"incomplete_fragment": 1, "orphan_fragment": 1},
     lambda t, k: [_tag(t) + _frags(k, dest="A")[0], _tag(t + 12) + _frags(k + 1, dest="B")[1]]),
    ("first_fragment_twice", {"incomplete_fragment": 2},
     lambda t, k: [_tag(t) + _frags(k)[0], _tag(t) + _frags(k + 1)[0]]),
    ("second_fragment_bad_checksum", {"bad_checksum": 1, "incomplete_fragment": 1},
     lambda t, k: [_tag(t) + _frags(k)[0], _tag(t) + _frags(k)[1][:-2] + "00"]),
    ("fragments_out_of_order", {"out_of_order_fragment": 1},
     lambda t, k: [_tag(t) + _cs("!AIVDM,3,1,4,A,53m,0"), _tag(t) + _cs("!AIVDM,3,3,4,A,000,2")]),
    ("national_group_bad_c_checksum", {"bad_tag_checksum": 2},
     lambda t, k: [x.replace(f"*{xor(f'c:{int(t)}'):02X}\\", f"*{xor(f'c:{int(t)}') ^ 2:02X}\\")
                   for x in national_group(_frags(k), t, 4000 + k)]),
    ("national_group_armour", {"decode_error": 1, "incomplete_fragment": 1},
     lambda t, k: national_group([_frags(k)[0], _cs("{},x{},{}".format(*_parts(_frags(k)[1])))],
                                 t, 5000 + k)),
]


def _base() -> list[str]:
    traffic = SyntheticTraffic(rng=np.random.default_rng(5), start_unix_s=T0)
    return [x.line for x in traffic.run(1500.0)]


@pytest.fixture(scope="module")
def base() -> list[str]:
    return _base()


def _insertion_points(base: list[str], n: int) -> list[int]:
    """n places spread over the stream, never between two fragments of one message."""
    ok = [i for i in range(40, len(base) - 40) if ",2,1," not in base[i - 1]]
    return [ok[int(j * (len(ok) - 1) / max(n - 1, 1))] for j in range(n)]


def _time(line: str) -> float:
    return float(line.split("c:")[1].split("*")[0].split(",")[0])


def _run(lines: list[str], batch: int) -> tuple[AisPipeline, list[tuple[object, ...]],
                                                TargetRegistry]:
    p = AisPipeline()
    reg = TargetRegistry(epoch_unix_s=T0)
    rows: list[tuple[object, ...]] = []
    statics: list[tuple[object, ...]] = []
    for i in range(0, len(lines), batch):
        b = p.feed_batch(lines[i:i + batch])
        reg.update_batch(b)
        rows += [(r.mmsi, r.t_unix_s, r.lat_deg, r.lon_deg, r.sog_m_s) for r in b.reports()]
        statics += [(s.mmsi, s.t_unix_s, s.name, s.destination) for s in b.static]
    p.finish()
    return p, rows + statics, reg


def test_the_catalogue_holds_more_than_80_kinds() -> None:
    names = [name for name, _, _ in CATALOGUE]
    assert len(names) == len(set(names)) and len(names) >= 80


def test_each_corruption_alone_is_counted_under_its_own_reason(base) -> None:
    head, tail = base[:300], base[300:340]
    ref, _, _ = _run(head + tail, 64)
    t = _time(head[-1])
    wrong = {}
    for k, (name, expected, make) in enumerate(CATALOGUE):
        p, rows, _ = _run(head + make(t, 10 * k) + tail, 64)
        delta = Counter(p.stats.errors)
        delta.subtract(ref.stats.errors)
        got = {kind: n for kind, n in delta.items() if n}
        if got != expected or any(isinstance(r[0], int) and r[0] >= POISON for r in rows):
            wrong[name] = got
    assert not wrong, f"counted differently than catalogued: {wrong}"


def test_all_of_them_mixed_in_change_nothing_valid_and_no_batch_size_matters(base) -> None:
    clean, clean_rows, _ = _run(base, 256)
    assert clean.stats.errors == {} and clean.stats.reports > 500
    lines = list(base)
    points = _insertion_points(base, len(CATALOGUE))
    for k, ((_, _, make), i) in reversed(list(enumerate(zip(CATALOGUE, points)))):
        lines[i:i] = make(_time(base[i - 1]), 10 * k)
    expected = Counter()
    for _, e, _ in CATALOGUE:
        expected.update(e)
    results = [_run(lines, b) for b in (1, 7, 64, 500, len(lines))]
    first, first_rows, first_reg = results[0]
    assert dict(first.stats.errors) == dict(expected)
    assert first_rows == clean_rows  # the valid stream is accepted exactly as without them
    snap = first_reg.extrapolate(_time(base[-1]) - T0)
    assert not (snap.mmsi >= POISON).any() and len(snap) == len(default_mmsis(base))
    for p, rows, _ in results[1:]:
        assert p.stats == first.stats and rows == first_rows


def default_mmsis(lines: list[str]) -> set[int]:
    _, rows, _ = _run(lines, 512)
    return {int(r[0]) for r in rows if not math.isnan(float(r[1]))}  # type: ignore[arg-type]


def test_the_example_lines_of_the_docs_table_are_counted_as_documented() -> None:
    """docs/sources.md lists every rejection reason with an example line: each example that
    stands alone (no stream around it) is fed to a pipeline and must give its reason."""
    from pathlib import Path

    doc = (Path(__file__).parents[2] / "docs" / "sources.md").read_text(encoding="utf-8")
    table = doc.split("### Rejection reasons")[1].split("\n\n")[2]
    checked = 0
    for row in table.splitlines()[2:]:
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        reason = cells[0].strip("`")
        example = cells[2]
        code = example.split("`` ")[1].split(" ``")[0] if example.startswith("``") \
            else example.split("`")[1] if example.startswith("`") else None
        if code is None or not code.startswith(("\\", "!", "hello")) or " then " in example \
                or " in a stream" in example:
            continue
        p = AisPipeline()
        p.feed(code)
        p.finish()
        assert dict(p.stats.errors) == {reason: 1}, (reason, code, p.stats.errors)
        checked += 1
    assert checked >= 18
