"""Fuzzing the three parsers at the data edge (hypothesis): no exception escapes.

- the pipeline: random bytes, and valid national-feed-style lines with random mutations
  (byte flips, cuts, insertions), in random batch sizes; every line is either accepted or
  counted, and accepted reports are always finite positions inside the scene;
- the tag-block parser: anything gives a :class:`TagBlock` or a :class:`TagBlockError`;
- the weather parser: random JSON-like documents and mutations of the fixture give a
  :class:`WeatherSeries` or a :class:`SourceError`.
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asvtwin.errors import SourceError
from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisPipeline, SyntheticTraffic, TargetRegistry
from asvtwin.sources.ais.tagblock import TagBlock, TagBlockError, parse_tag_block
from asvtwin.sources.weather import FIXTURE_NAME, WeatherSeries, parse_compact

from .conftest import T0

VALID = [x.line.encode() for x in SyntheticTraffic(rng=np.random.default_rng(9),
                                                   start_unix_s=T0).run(300.0)]
FIXTURE = json.loads(resources.files("asvtwin.sources").joinpath("data", FIXTURE_NAME)
                     .read_text())
BOUNDS = default_scene().bounds
_FUZZ = settings(max_examples=100, deadline=None,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def mutated_line(draw: st.DrawFn) -> bytes:
    line = bytearray(draw(st.sampled_from(VALID)))
    for _ in range(draw(st.integers(0, 4))):
        op = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
        if not line:
            break
        i = draw(st.integers(0, len(line) - 1))
        if op == "flip":
            line[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "cut":
            del line[i:]
        elif op == "insert":
            line[i:i] = draw(st.binary(min_size=1, max_size=4))
        else:
            del line[i]
    return bytes(line)


@_FUZZ
@given(lines=st.lists(st.one_of(mutated_line(), st.binary(max_size=120),
                                st.sampled_from(VALID)), max_size=40),
       batch=st.integers(1, 40), recv=st.one_of(st.none(), st.floats(allow_nan=True)))
def test_pipeline_never_raises_and_counts_every_line(lines, batch, recv) -> None:
    p = AisPipeline()
    reg = TargetRegistry(epoch_unix_s=T0)
    accepted = 0
    for i in range(0, len(lines), batch):
        b = p.feed_batch(lines[i:i + batch], recv_time_s=recv)
        reg.update_batch(b)
        accepted += len(b) + len(b.static)
        assert np.isfinite(b.north_m).all() and np.isfinite(b.t_unix_s).all()
        assert ((b.lat_deg >= BOUNDS.lat_min_deg) & (b.lat_deg <= BOUNDS.lat_max_deg)).all()
    p.finish()
    st_ = p.stats
    assert st_.lines == sum(1 for x in lines if x.strip())
    reg.extrapolate(0.0)
    # nothing vanishes: a line on its own ends as a message (counted by type) or a rejection
    scene = default_scene()
    for x in lines[:5]:
        if x.strip():
            one = AisPipeline(scene)
            one.feed(x, recv_time_s=recv)
            one.finish()
            assert sum(one.stats.messages_by_type.values()) + one.stats.total_errors >= 1


@_FUZZ
@given(tag=st.one_of(st.binary(max_size=80),
                     st.from_regex(rb"[sgcxn]:[0-9a-z.\-]{0,14}(,[sgc]:[0-9\-]{0,12}){0,3}"
                                   rb"\*[0-9A-Fa-fG-Z]{0,3}", fullmatch=True)))
def test_tag_block_parser_gives_a_tag_block_or_its_own_error(tag: bytes) -> None:
    try:
        tb = parse_tag_block(tag)
    except TagBlockError:
        return
    assert isinstance(tb, TagBlock) and tb.checksum_over in ("tag", "c")
    assert tb.t_unix_s is None or tb.t_unix_s >= 0


_json = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                     lambda inner: st.lists(inner, max_size=4)
                     | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=20)


@st.composite
def mutated_doc(draw: st.DrawFn) -> object:
    doc = json.loads(json.dumps(FIXTURE))
    doc["properties"]["timeseries"] = doc["properties"]["timeseries"][:4]
    for _ in range(draw(st.integers(1, 3))):
        node = doc
        path = draw(st.lists(st.integers(0, 6), min_size=1, max_size=6))
        for step in path[:-1]:
            if isinstance(node, dict) and node:
                node = node[sorted(node)[step % len(node)]]
            elif isinstance(node, list) and node:
                node = node[step % len(node)]
        value = draw(_json)
        if isinstance(node, dict) and node:
            node[sorted(node)[path[-1] % len(node)]] = value
        elif isinstance(node, list) and node:
            node[path[-1] % len(node)] = value
    return doc


@_FUZZ
@given(doc=st.one_of(_json, mutated_doc(), st.binary(max_size=60)))
def test_weather_parser_gives_a_series_or_a_source_error(doc) -> None:
    try:
        series = parse_compact(doc)
    except SourceError:
        return
    assert isinstance(series, WeatherSeries) and len(series) >= 1
    assert np.all(np.diff(series.t_unix_s) > 0)
