"""The batch decoder of position reports against pyais, and the pipeline with and without it.

pyais is the oracle: every field of every payload must equal what ``decode()`` gives, for
random payloads of the four types and for each field at its limits and its "not available"
value; and the pipeline must accept, reject and count exactly the same with the batch decoder
as with pyais alone, for valid, mutated and random lines in any batch size.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyais.encode import encode_dict
from pyais.messages import NMEASentenceFactory

from asvtwin.sources.ais import AisPipeline, SyntheticTraffic
from asvtwin.sources.ais.positions import decode_positions, scan_fast_lines
from asvtwin.sources.ais.sentence import ARMOUR, prefix_xor
from asvtwin.sources.ais.tagblock import xor_checksum

from .conftest import T0, tagged, with_checksum

_TYPE_CHAR = {1: b"1", 2: b"2", 3: b"3", 18: b"B"}


def _pyais(payload: bytes, fill: int = 0) -> tuple[float, ...]:
    """What pyais decodes, as the batch decoder's columns."""
    m = NMEASentenceFactory.produce(b"!AIVDM,1,1,,A," + payload + b",%d*00" % fill).decode()
    a = m.msg_type <= 3
    return (m.msg_type, m.mmsi, m.lat, m.lon, m.speed, m.course, float(m.heading),
            float(m.turn) if a else math.nan, int(m.status) if a else 15)


def _ours(payloads: list[bytes]) -> list[tuple[float, ...]]:
    c = decode_positions(payloads)
    cols = (c.msg_type, c.mmsi, c.lat_deg, c.lon_deg, c.sog_kn, c.cog_deg, c.heading_deg,
            c.rot_deg_min, c.nav_status)
    return [tuple(x.item() for x in row) for row in zip(*cols)]


def _same(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a, b))


def test_random_payloads_of_the_four_types_decode_as_pyais_does() -> None:
    rng = np.random.default_rng(1)
    alphabet = list(ARMOUR)
    payloads = []
    for k in range(4000):
        n = 28 if k % 3 else int(rng.integers(29, 40))  # longer ones: only 168 bits are read
        first = _TYPE_CHAR[(1, 2, 3, 18)[k % 4]]
        payloads.append(first + bytes(rng.choice(alphabet, n - 1).tolist()))
    ours = _ours(payloads)
    wrong = [p for p, o in zip(payloads, ours) if not _same(o, _pyais(p))]
    assert not wrong, wrong[:3]
    assert {o[0] for o in ours} == {1, 2, 3, 18}


@pytest.mark.parametrize("msg_type", [1, 2, 3, 18])
@pytest.mark.parametrize("fields", [
    {"lat": 91.0, "lon": 181.0, "speed": 102.3, "course": 360.0, "heading": 511},  # n/a
    {"lat": -90.0, "lon": -180.0, "speed": 102.2, "course": 359.9, "heading": 359},
    {"lat": 63.4389, "lon": 10.3951, "speed": 12.3, "course": 72.4, "heading": 71},
    {"lat": -0.000001, "lon": -0.000002, "speed": 0.0, "course": 0.0, "heading": 0},
    {"mmsi": 0}, {"mmsi": 2**30 - 1}, {"turn": 127}, {"turn": -127}, {"turn": -128},
    {"turn": 0}, {"turn": 126}, {"turn": -5}, {"status": 15}, {"status": 5},
])
def test_every_field_at_its_limits_decodes_as_pyais_does(msg_type, fields) -> None:
    d = {"type": msg_type, "mmsi": 257_000_001} | fields
    if msg_type == 18:
        d = {k: v for k, v in d.items() if k not in ("turn", "status")}
    sentence = encode_dict(d, talker_id="AI")[0]
    payload = sentence.split(",")[5].encode()
    fill = int(sentence.split(",")[6][0])
    assert _same(_ours([payload])[0], _pyais(payload, fill))


def test_every_rate_of_turn_value_decodes_as_pyais_does() -> None:
    payloads = [encode_dict({"type": 1, "mmsi": 1, "turn": 0}, talker_id="AI")[0]]
    base = payloads[0].split(",")[5].encode()
    bits = "".join(f"{(c - 48 - 8 * (c > 87)):06b}" for c in base)
    chars = []
    for raw in range(256):  # bits 42..49: the raw two's-complement ROT
        b = bits[:42] + f"{raw:08b}" + bits[50:]
        chars.append(bytes(ARMOUR[int(b[i:i + 6], 2)] for i in range(0, 168, 6)))
    assert all(_same(o, _pyais(p)) for o, p in zip(_ours(chars), chars))


@pytest.mark.parametrize(("sentence", "batch"), [
    ("!AIVDM,1,1,,A,{p},0", True),
    ("!BSVDM,1,1,3,B,{p},0", True),  # talker BS, sequence id 3
    ("!AIVDM,1,1,,,{p},0", True),  # no channel
    ("!AIVDO,1,1,,A,{p},0", False),  # own ship: counted apart by pyais's path
    ("!AIVDM,2,1,4,A,{p},0", False),  # a fragment
    ("$AIVDM,1,1,,A,{p},0", False),
    ("!AIVDM,1,1,,A,{p},2", False),  # 28 characters minus 2 fill bits: 166 bits
    ("!AIVDM,1,1,,A,{p}0,2", True),  # 29 characters minus 2 fill bits: 172 bits
    ("!AIVDM,1,1,,A,{p},x", False),
    ("!AIVDM,1,1,,A,{p}x,0", False),  # "x" is outside the 6-bit alphabet
    ("!AIVDM,1,1,,A,5{q},0", False),  # type 5
    ("!AIVDM,1,1,,A,{p},0,extra", False),
])
def test_only_canonical_position_sentences_take_the_batch_path(sentence, batch) -> None:
    p = "13u?etPv2;0n:dDPwUM1U1Cb069D"
    line = tagged(with_checksum(sentence.format(p=p, q=p[1:])), T0)
    raws = [b"", line.encode(), line.lower().encode()]
    fast = scan_fast_lines(raws, prefix_xor(b"".join(raws)))
    assert (fast.index[1] >= 0) is batch and fast.index[0] == fast.index[2] == -1
    if batch:
        body = line.split("\\")[-1].encode()
        assert fast.checksum[0] == (xor_checksum(body[1:-3]), int(body[-2:], 16))
        assert fast.sentence_len[0] == len(body)


VALID = [x.line.encode() for x in SyntheticTraffic(rng=np.random.default_rng(4),
                                                   start_unix_s=T0).run(600.0)]


@st.composite
def _mutated(draw: st.DrawFn) -> bytes:
    line = bytearray(draw(st.sampled_from(VALID)))
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, len(line) - 1))
        op = draw(st.sampled_from(["flip", "set", "cut", "insert"]))
        if op == "flip":
            line[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "set":  # a plausible character: keeps the line near-canonical
            line[i] = draw(st.sampled_from(list(b"0Ww`x,*!\\1B5A")))
        elif op == "cut":
            del line[i:]
        else:
            line[i:i] = draw(st.binary(min_size=1, max_size=3))
        if not line:
            break
    return bytes(line)


def _run(lines: list[bytes], batch: int, batch_decode: bool) -> tuple[object, list[object]]:
    p = AisPipeline(batch_decode=batch_decode)
    out: list[object] = []
    for i in range(0, len(lines), batch):
        b = p.feed_batch(lines[i:i + batch])
        out += [(r.mmsi, r.t_unix_s, r.msg_type, r.lat_deg, r.lon_deg, r.north_m, r.sog_m_s,
                 r.cog_rad, r.heading_rad, r.rot_rad_s, r.nav_status, r.station)
                for r in b.reports()]
        out += list(b.static)
    p.finish()
    return p.stats, out


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(lines=st.lists(st.one_of(_mutated(), st.sampled_from(VALID), st.binary(max_size=90)),
                      min_size=1, max_size=60),
       batch=st.integers(1, 60))
def test_the_pipeline_counts_and_accepts_the_same_with_and_without_the_batch_decoder(
        lines, batch) -> None:
    assert _run(lines, batch, True) == _run(lines, batch, False)


def test_a_whole_synthetic_feed_is_the_same_with_and_without_the_batch_decoder() -> None:
    with_batch = _run(VALID, 256, True)
    assert with_batch == _run(VALID, 256, False)
    assert with_batch[0].reports > 250  # type: ignore[attr-defined]
