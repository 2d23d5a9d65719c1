"""Fragments and payloads (issue items 7-9): the fragment timeout on every line, no chimeras,
the AIS 6-bit alphabet, resync after garbage, one count per over-long TCP line, own-ship VDO."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from pyais.encode import encode_dict

from asvtwin.sources.ais import AisPipeline, AisStatic, TcpAisSource, encode_report, encode_static

from .conftest import LAT, LON, T0, report, tagged, with_checksum


def _type5(mmsi: int, dest: str, seq: int = 3) -> list[str]:
    st = AisStatic(mmsi=mmsi, t_unix_s=T0, msg_type=5, name=f"SHIP {mmsi % 1000}",
                   destination=dest)
    (frags,) = encode_static(st, seq_id=seq)
    return frags


def test_a_second_fragment_60_s_late_is_not_assembled() -> None:
    f1, f2 = _type5(257_000_010, "ORKANGER")
    p = AisPipeline()
    out = p.feed_batch([tagged(f1, T0), tagged(f2, T0 + 60)])
    assert not out.static
    assert p.stats.errors == {"incomplete_fragment": 1, "orphan_fragment": 1}


def test_halves_of_two_vessels_are_never_joined_into_a_chimera() -> None:
    """Vessel A's second fragment and vessel B's first are lost; B's second half arrives a
    minute later with the same sequence id. Before: A1 + B2 made one message (A's name,
    B's destination)."""
    a1, _ = _type5(257_000_011, "TRONDHEIM")
    _, b2 = _type5(257_000_012, "STJORDAL")
    p = AisPipeline()
    filler = [tagged(encode_report(report(t=T0 + k)), T0 + k) for k in range(1, 60, 10)]
    out = p.feed_batch([tagged(a1, T0), *filler, tagged(b2, T0 + 61)])
    assert not out.static
    assert p.stats.errors == {"incomplete_fragment": 1, "orphan_fragment": 1}


def test_a_message_whose_last_fragment_never_comes_is_counted() -> None:
    f1, _ = _type5(257_000_013, "HOMMELVIK")
    p = AisPipeline()
    p.feed_batch([tagged(f1, T0)])
    assert p.stats.pending_fragments == 1 and p.stats.errors == {}
    # expired by the time of any later line, whatever it is ...
    p.feed_batch([tagged(encode_report(report(t=T0 + 11)), T0 + 11)])
    assert p.stats.errors == {"incomplete_fragment": 1} and p.stats.pending_fragments == 0
    # ... or at the end of the stream
    p.feed_batch([tagged(f1, T0 + 20)])
    assert p.finish() == 1 and p.stats.errors == {"incomplete_fragment": 2}


def test_characters_outside_the_six_bit_alphabet_are_a_decode_error() -> None:
    """Before: 'X' (beyond 'W') with a valid checksum decoded to a longitude 0.13 deg off."""
    good = encode_report(report())
    head, payload, fill = good.split("*")[0].rsplit(",", 2)  # "!ABVDM,1,1,,A", payload, "0"
    assert AisPipeline().feed(tagged(good, T0)).lon_deg[0] == pytest.approx(LON, abs=1e-5)
    for bad_char in "XYZ[\\]^_xyz{|}~ ":
        corrupt = payload[:12] + bad_char + payload[13:]
        line = with_checksum(f"{head},{corrupt},{fill}")
        p = AisPipeline()
        assert len(p.feed(tagged(line, T0))) == 0, bad_char
        assert p.stats.errors == {"decode_error": 1}


@pytest.mark.parametrize("prefix", [b"\x00", b"\x00\x00\x00", b"garbage", b"\xff\xfe", b"%$%"])
def test_a_garbage_prefix_does_not_lose_the_sentence(prefix: bytes) -> None:
    p = AisPipeline()
    line = tagged(encode_report(report()), T0).encode()
    (r,) = p.feed(prefix + line).reports()
    assert r.mmsi == 257_000_001 and p.stats.notices == {"resynced": 1}
    assert p.stats.errors == {}


def test_empty_payload_fill_bits_and_own_ship() -> None:
    p = AisPipeline()
    empty = with_checksum("!AIVDM,1,1,,A,,0")
    good = encode_report(report())
    bad_fill = with_checksum(good.split("*")[0][:-1] + "x")
    vdo = with_checksum(encode_report(report(mmsi=257_999_999)).split("*")[0].replace(
        "VDM", "VDO"))
    out = p.feed_batch([tagged(x, T0) for x in (empty, bad_fill, vdo)])
    assert len(out) == 0
    assert p.stats.errors == {"short_payload": 1, "malformed": 1, "own_ship": 1}
    assert 0 not in p.stats.messages_by_type  # an empty payload is no message type 0


def test_an_over_long_tcp_line_is_counted_once_and_the_feed_goes_on() -> None:
    """Before: a 70 kB line was counted 17 times and its tail decoded as garbage."""
    good = [tagged(encode_report(report(mmsi=257_000_001 + k, t=T0 + k)), T0 + k)
            for k in range(5)]

    async def run() -> tuple[int, dict[str, int]]:
        async def handle(reader, writer):
            writer.write((good[0] + "\n").encode())
            for _ in range(70):  # 70 kB without a newline, in pieces
                writer.write(b"A" * 1000)
                await writer.drain()
            writer.write(("\n" + "\n".join(good[1:]) + "\n").encode())
            await writer.drain()
            writer.close()

        srv = await asyncio.start_server(handle, "127.0.0.1", 0)
        port = srv.sockets[0].getsockname()[1]
        src = TcpAisSource("127.0.0.1", port, max_reconnects=0)
        n = sum([len(b) async for b in src.batches()])
        srv.close()
        return n, dict(src.pipeline.stats.errors)

    n, errors = asyncio.run(asyncio.wait_for(run(), 10.0))
    assert n == 5
    assert errors == {"line_too_long": 1, "disconnected": 1}


def test_other_talkers_are_accepted_only_as_vdm() -> None:
    data = {"type": 1, "mmsi": 257_000_001, "lat": LAT, "lon": LON, "speed": 5.0}
    lines = [tagged(s, T0) for talker in ("AI", "AB", "BS")
             for s in encode_dict(data, talker_id=talker, sentence_type="VDM")]
    p = AisPipeline()
    assert len(p.feed_batch(lines)) == 1 and p.stats.errors == {"duplicate": 2}
    assert np.isfinite(p.stream_time_unix_s)
