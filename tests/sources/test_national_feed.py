"""The national feed's conventions: group tag blocks checksummed over ``c:`` alone, whole-log
summaries, untagged logs (issue items 1-3). The lines are built here from the description of
the Norwegian Coastal Administration's feed (group tag ``g:1-2-id`` with the checksum over
``c:`` only), encoded with pyais."""

from __future__ import annotations

import json
import logging

import pytest

from asvtwin.cli import main
from asvtwin.sources.ais import AisPipeline, AisStatic, encode_report, encode_static
from asvtwin.sources.ais.tagblock import TagBlockError, parse_tag_block

from .conftest import LAT, LON, T0, national_group, report, tagged, xor

FERRY = AisStatic(mmsi=257_123_450, t_unix_s=T0, msg_type=5, name="TRONDHEIMSFJORD II",
                  callsign="LLVT", ship_type=60, imo=9_123_456, to_bow_m=40, to_stern_m=20,
                  to_port_m=8, to_starboard_m=8, draught_m=4.2, destination="VANVIKAN")


def type5_lines(static: AisStatic = FERRY, t: float = T0, gid: int = 9999) -> list[str]:
    (sentences,) = encode_static(static, talker="BS", seq_id=gid % 10)
    return national_group(sentences, t, gid)


def test_the_documented_example_tag_checksums_over_c_alone() -> None:
    tb = parse_tag_block(b"g:1-2-9999,c:1565218798*53")
    assert (tb.t_unix_s, tb.group, tb.checksum_over) == (1565218798.0, (1, 2, 9999), "c")
    assert parse_tag_block(b"s:2573555,c:1707873398*05").checksum_over == "tag"
    with pytest.raises(TagBlockError, match=r"0x54 in the tag, 0x.. computed over the whole "
                                            r"tag, 0x53 over c: alone"):
        parse_tag_block(b"g:1-2-9999,c:1565218798*54")


def test_type5_of_the_national_feed_is_decoded_and_the_convention_counted(caplog) -> None:
    """Before the fix every such line was rejected as bad_tag_block: no ship names at all."""
    p = AisPipeline()
    with caplog.at_level(logging.WARNING, logger="asvtwin.sources.ais"):
        batch = p.feed_batch(type5_lines())
    (s,) = batch.static
    assert (s.mmsi, s.name, s.destination, s.length_m, s.beam_m) == (
        FERRY.mmsi, "TRONDHEIMSFJORD II", "VANVIKAN", 60.0, 16.0)
    assert p.stats.errors == {}
    assert p.stats.notices == {"tag_checksum_c_only": 2}  # counted, so an operator sees it
    assert "tag_checksum_c_only" in caplog.text  # logged once, as accepted-with-a-quirk


def test_tags_matching_neither_convention_are_still_rejected_saying_which_check(caplog) -> None:
    good = type5_lines()
    c = f"c:{int(T0)}"
    wrong = good[0].replace(f"*{xor(c):02X}\\", f"*{xor(c) ^ 1:02X}\\")  # neither tag nor c:
    p = AisPipeline()
    with caplog.at_level(logging.WARNING, logger="asvtwin.sources.ais"):
        p.feed_batch([wrong, good[1]])
    assert p.stats.errors == {"bad_tag_checksum": 1, "orphan_fragment": 1}
    assert "computed over the whole tag" in caplog.text and "over c: alone" in caplog.text
    # a malformed field is its own reason
    p.feed(f"\\g:1-2,c:{int(T0)}*{xor(c):02X}\\" + good[0].split("\\")[-1])
    assert p.stats.errors["bad_tag_block"] == 1


def _national_log(tmp_path, *, out_of_scene: int = 10) -> tuple[str, int]:
    """A national-feed-style log: many vessels far from Trondheim, one in the fjord, type 5s."""
    lines = []
    for k in range(out_of_scene):  # along the coast, 68..70 N: outside the Trondheim box
        r = report(mmsi=257_200_000 + k, t=T0 + k, lat=68.0 + 0.2 * k, lon=14.0 + 0.3 * k)
        lines.append(tagged(encode_report(r, talker="BS"), T0 + k))
        st = AisStatic(mmsi=r.mmsi, t_unix_s=T0 + k, msg_type=5, name=f"COASTER {k}",
                       destination="BODO")
        lines += type5_lines(st, T0 + k, gid=1000 + k)
    inside = report(mmsi=257_100_001, t=T0 + 20.0, lat=LAT, lon=LON)
    lines.append(tagged(encode_report(inside, talker="BS"), T0 + 20.0))
    path = tmp_path / "national.nmea"
    path.write_text("\n".join(lines) + "\n")
    return str(path), out_of_scene + 1


def test_stats_summarises_the_whole_log_with_the_scene_as_a_separate_count(tmp_path,
                                                                           capsys) -> None:
    path, n_vessels = _national_log(tmp_path)
    assert main(["ais", "stats", path, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mmsis"] == n_vessels  # all of them, not only the one in the box
    assert out["reports"] == n_vessels and out["statics"] == n_vessels - 1
    assert out["time_span"]["seconds"] == 20.0
    assert out["scene"] == {"name": "trondheim", "box": out["scene"]["box"],
                            "filter_applied": False, "position_reports_in_scene": 1,
                            "position_reports_outside_scene": n_vessels - 1}
    assert "outside_scene" not in out["errors"] and out["errors"] == {}
    # --scene applies the filter as the twin does, still a labelled count
    assert main(["ais", "stats", path, "--json", "--scene"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["errors"]["outside_scene"] == n_vessels - 1 and out["reports"] == 1
    assert out["mmsis"] == n_vessels  # the census still counts every MMSI
    assert main(["ais", "stats", path]) == 0
    text = " ".join(capsys.readouterr().out.split())  # rich wraps at the terminal width
    assert "1 position reports inside, 10 outside" in text and "11 MMSIs" in text


def test_untagged_log_is_counted_by_stats_and_stamped_by_listen(tmp_path, capsys) -> None:
    rs = [report(mmsi=257_300_000 + k, lat=LAT + 0.001 * k) for k in range(5)]
    path = tmp_path / "untagged.nmea"
    path.write_text("\n".join(encode_report(r) for r in rs) + "\n")
    assert main(["ais", "stats", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["reports"], out["mmsis"], out["untimed_lines"]) == (5, 5, 5)
    assert "missing_time" not in out["errors"] and out["notices"] == {"untimed": 5}
    assert main(["ais", "listen", str(path), "--speed", "0", "--no-live"]) == 0
    text = capsys.readouterr().out
    assert "reports 5 " in text and "missing_time" not in text
    assert "receive_time 5 (lines without a tag-block time, stamped with the receive clock)" \
        in " ".join(text.split())
