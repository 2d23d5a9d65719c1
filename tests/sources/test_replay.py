"""File replay (pacing, speed, loop) and the history store (SQLite, replay of a session)."""

from __future__ import annotations

import asyncio
import math
import sqlite3
import time
from importlib import resources

import numpy as np
import pytest

from asvtwin.errors import SourceError
from asvtwin.geo import default_scene
from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    AisStatic,
    FileReplaySource,
    HistoryReplaySource,
    Pacer,
    SyntheticTraffic,
    TargetRegistry,
    tag_time,
)
from asvtwin.sources.history import HistoryStore, SqliteHistory, replay_session
from asvtwin.sources.weather import OfflineWeatherSource

from .conftest import T0, line, report

SAMPLE = "trondheim_synthetic_15min.nmea"


@pytest.fixture(scope="module")
def log_60s(tmp_path_factory):
    items = list(SyntheticTraffic(rng=np.random.default_rng(3), start_unix_s=T0).run(60.0))
    path = tmp_path_factory.mktemp("logs") / "fjord.nmea"
    path.write_text("\n".join(x.line for x in items) + "\n")
    return path, items


def collect(src):
    async def run():
        return [b async for b in src.batches()]

    t0 = time.perf_counter()
    batches = asyncio.run(run())
    return batches, time.perf_counter() - t0


def test_pacer_without_a_clock() -> None:
    p = Pacer(10.0, min_sleep_s=0.05)
    assert [p.delay(t) for t in (100.0, 100.2, 100.4, 101.0, 100.5, 103.0)] == \
        pytest.approx([0.0, 0.0, 0.0, 0.1, 0.0, 0.2])
    assert Pacer(None).delay(5.0) == 0.0
    with pytest.raises(ValueError, match="speed must be finite and > 0"):
        Pacer(0.0)


def test_file_replay_at_speed_factor(log_60s) -> None:
    path, items = log_60s
    span = items[-1].t_unix_s - items[0].t_unix_s
    batches, wall = collect(FileReplaySource(path, speed=120.0))
    assert sum(len(b) for b in batches) == sum(isinstance(x.truth, AisReport) for x in items)
    assert span / 120.0 * 0.9 <= wall <= span / 120.0 + 1.5
    fast, wall_fast = collect(FileReplaySource(path, speed=None))
    assert wall_fast < wall and sum(len(b) for b in fast) == sum(len(b) for b in batches)


def test_file_replay_loops_with_increasing_time(log_60s) -> None:
    path, items = log_60s
    pipe = AisPipeline()
    src = FileReplaySource(path, speed=None, loop=True, loop_gap_s=30.0, pipeline=pipe)

    n_pass = sum(isinstance(x.truth, AisReport) for x in items)

    async def run():
        got = []
        async for b in src.batches():
            got.append(b)
            if sum(len(x) for x in got) >= 3 * n_pass:
                return got
        return got

    t = np.concatenate([b.t_unix_s for b in asyncio.run(run())])[: 3 * n_pass]
    span = items[-1].t_unix_s - items[0].t_unix_s
    assert t.max() - t.min() == pytest.approx(3 * span + 2 * 30.0)
    assert np.all(np.diff(t) >= 0)
    assert pipe.stats.errors == {}  # no time_backwards, no duplicates across passes
    assert src.passes >= 2


def test_untagged_log_needs_a_clock(tmp_path) -> None:
    r = report()
    path = tmp_path / "bare.nmea"
    path.write_text(line(r)[line(r).index("!"):] + "\n")
    batches, _ = collect(FileReplaySource(path, speed=None))
    assert sum(len(b) for b in batches) == 0
    src = FileReplaySource(path, speed=None, clock=lambda: T0 + 99.0)
    (b,) = [b for b in collect(src)[0] if len(b)]
    assert b.t_unix_s.tolist() == [T0 + 99.0]
    with pytest.raises(SourceError, match="not a readable file"):
        FileReplaySource(tmp_path / "missing.nmea")


def test_bundled_sample_log() -> None:
    text = resources.files("asvtwin.sources").joinpath("data", SAMPLE).read_text()
    lines = text.splitlines()
    assert sum(tag_time(x.encode()) is not None for x in lines) == len(lines)
    p = AisPipeline()
    batch = p.feed_batch(lines)
    assert p.stats.errors["outside_scene"] == 1  # the coastal administration's example line
    assert p.stats.errors["duplicate"] > 0
    assert len(set(batch.mmsi.tolist())) == 5


# ------------------------------------------------------------------------- history
def test_history_round_trip_with_not_available_as_null(tmp_path) -> None:
    frame = default_scene().frame
    reports = [report(t=T0 + 10 * k, lat=63.46 + 1e-4 * k) for k in range(5)]
    reports.append(report(mmsi=257000002, t=T0 + 5, sog_m_s=None, cog_deg=None,
                          heading_deg=None, rot_rad_s=None, nav_status=None))
    static = AisStatic(257000001, T0, 5, name="FERJA", ship_type=60, to_bow_m=50, to_stern_m=30)
    db = tmp_path / "h.sqlite"
    with SqliteHistory(db) as store:
        assert isinstance(store, HistoryStore)
        assert store.append_reports(reports) == 6
        store.append_static([static])
        fc = OfflineWeatherSource().fetch()
        assert store.append_weather(fc.series.samples()[:3], source=fc.source) == 3
    with SqliteHistory(db) as store:
        got = store.query_reports(frame)
        assert [r.t_unix_s for r in got] == sorted(r.t_unix_s for r in reports)
        na = store.query_reports(frame, mmsi=257000002)[0]
        assert (na.sog_m_s, na.cog_rad, na.heading_rad, na.rot_rad_s, na.nav_status) == (None,) * 5
        one = store.query_reports(frame, mmsi=257000001, since_unix_s=T0 + 15,
                                  until_unix_s=T0 + 30)
        assert [r.t_unix_s for r in one] == [T0 + 20, T0 + 30]
        r0 = store.query_reports(frame, mmsi=257000001, limit=1)[0]
        assert (r0.north_m, r0.east_m) == pytest.approx((reports[0].north_m, reports[0].east_m))
        assert r0.cog_rad == pytest.approx(math.pi / 4) and r0.station is None
        assert store.query_static(mmsi=257000001) == [static]
        w = store.query_weather()
        assert len(w) == 3 and w[0].air_pressure_pa == fc.series.air_pressure_pa[0]
        assert store.time_span() == (T0, T0 + 40) and store.count_reports() == 6
    con = sqlite3.connect(db)
    names = {row[0] for row in con.execute("SELECT name FROM sqlite_master WHERE type='index'")}
    assert {"report_chunks_t", "static_mmsi_t", "weather_t"} <= names
    # the queries behind query_reports seek an index, never scan the table
    by_time = " ".join(str(r) for r in con.execute(
        "EXPLAIN QUERY PLAN SELECT id, t_min_s FROM report_chunks WHERE 1 AND t_min_s >= 0 "
        "AND t_max_s >= 0 AND t_min_s <= 1 ORDER BY 2, 1"))
    assert "USING INDEX report_chunks_t (t_min_s>? AND t_min_s<?)" in by_time, by_time
    by_mmsi = " ".join(str(r) for r in con.execute(
        "EXPLAIN QUERY PLAN SELECT chunk, t_min_s FROM report_chunk_mmsi WHERE mmsi = 1 "
        "AND t_min_s >= 0 AND t_max_s >= 0 AND t_min_s <= 1 ORDER BY 2, 1"))
    assert "USING PRIMARY KEY (mmsi=? AND t_min_s>? AND t_min_s<?)" in by_mmsi, by_mmsi
    con.close()


def test_schema_version_is_checked(tmp_path) -> None:
    db = tmp_path / "old.sqlite"
    SqliteHistory(db).close()
    con = sqlite3.connect(db)
    con.execute("UPDATE meta SET value='0' WHERE key='schema'")
    con.commit()
    con.close()
    with pytest.raises(SourceError, match="schema 3 expected, actually: 0"):
        SqliteHistory(db)
    with pytest.raises(SourceError, match="schema 3 expected, actually: 0"):
        SqliteHistory(db, migrate=True)  # only schemas 1 and 2 can be converted


def test_recorded_session_replays_to_the_same_picture(tmp_path) -> None:
    items = list(SyntheticTraffic(rng=np.random.default_rng(4), start_unix_s=T0).run(400.0))
    pipe = AisPipeline()
    live = TargetRegistry(epoch_unix_s=T0)
    store = SqliteHistory(tmp_path / "s.sqlite")
    for k in range(0, len(items), 50):
        batch = pipe.feed_batch([x.line for x in items[k:k + 50]])
        live.update_batch(batch)
        store.append_batch(batch)
    replayed = TargetRegistry(epoch_unix_s=T0, frame=default_scene().frame)
    replayed.ingest(replay_session(store, default_scene().frame))
    a, b = live.extrapolate(400.0), replayed.extrapolate(400.0)
    assert a.mmsi.tolist() == b.mmsi.tolist()
    np.testing.assert_allclose(a.position_m, b.position_m, atol=1e-6)
    assert a.static == b.static
    # paced replay from the store: 400 s at 400x in about a second
    src = HistoryReplaySource(store, default_scene().frame, speed=400.0)
    batches, wall = collect(src)
    assert sum(len(x) for x in batches) == store.count_reports()
    assert 0.7 <= wall <= 3.0
    store.close()
