"""The history store's columnar schema: ordering, exact round trip, atomicity, crash, migration."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from asvtwin.errors import ParameterError, SourceError
from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisStatic, ReportBatch
from asvtwin.sources.history import SqliteHistory

from .conftest import T0

FRAME = default_scene().frame
MMSIS = (257000001, 257000002, 257000003, 258000004, 259000005)


def random_batch(rng: np.random.Generator, t0: float, n: int) -> ReportBatch:
    """n reports from 5 vessels over ~n s after t0 (jittered, some equal times), some NaN."""
    def na(x: np.ndarray) -> np.ndarray:
        return np.where(rng.random(n) < 0.2, np.nan, x)

    lat = np.round(rng.uniform(63.40, 63.50, n), 6)
    lon = np.round(rng.uniform(10.30, 10.50, n), 6)
    north, east = FRAME.to_ned(lat, lon)
    stations = (None, "2573555", "2573485")
    return ReportBatch(
        mmsi=rng.choice(MMSIS, n), t_unix_s=np.round(t0 + np.sort(rng.uniform(0, n, n)) -
                                                      rng.uniform(0, 3, n)),
        msg_type=rng.choice([1, 3, 18], n), north_m=north, east_m=east, lat_deg=lat,
        lon_deg=lon, sog_m_s=na(rng.uniform(0, 10, n)), cog_rad=na(rng.uniform(-3, 3, n)),
        heading_rad=na(rng.uniform(-3, 3, n)), rot_rad_s=na(rng.normal(0, 0.01, n)),
        nav_status=rng.choice([-1, 0, 5], n),
        station=tuple(stations[k] for k in rng.integers(0, 3, n)))


def key(r) -> tuple:
    """A report's fields, NaN/None-safe, for exact comparison."""
    return (r.mmsi, r.t_unix_s, r.msg_type, r.lat_deg, r.lon_deg, r.sog_m_s, r.cog_rad,
            r.heading_rad, r.rot_rad_s, r.nav_status, r.station)


def test_queries_match_a_brute_force_reference(tmp_path) -> None:
    rng = np.random.default_rng(5)
    batches = [random_batch(rng, T0 + 40.0 * k, int(rng.integers(1, 60))) for k in range(40)]
    everything = [r for b in batches for r in b.reports()]  # arrival order
    with SqliteHistory(tmp_path / "h.sqlite") as store:
        for b in batches:
            assert store.append_batch(b) == len(b)
        assert store.count_reports() == len(everything)
        t_all = [r.t_unix_s for r in everything]
        assert store.time_span() == (min(t_all), max(t_all))
        for mmsi in (None, MMSIS[0], MMSIS[4], 999):
            for since, until in ((None, None), (T0 + 300, None), (None, T0 + 800),
                                 (T0 + 500.0, T0 + 530.0), (T0 + 99.0, T0 + 99.0)):
                for limit in (None, 7):
                    want = sorted(
                        (r for r in everything if (mmsi is None or r.mmsi == mmsi)
                         and (since is None or r.t_unix_s >= since)
                         and (until is None or r.t_unix_s <= until)),
                        key=lambda r: r.t_unix_s)  # stable: ties stay in arrival order
                    got = store.query_reports(FRAME, mmsi=mmsi, since_unix_s=since,
                                              until_unix_s=until, limit=limit)
                    assert [key(r) for r in got] == [key(r) for r in want[:limit]]
        got = store.query_reports(FRAME, mmsi=MMSIS[1])
        ref = [r for r in sorted(everything, key=lambda r: r.t_unix_s) if r.mmsi == MMSIS[1]]
        np.testing.assert_allclose([r.north_m for r in got], [r.north_m for r in ref],
                                   atol=1e-9)


def test_large_batch_splits_into_chunks_and_round_trips_exactly(tmp_path) -> None:
    rng = np.random.default_rng(6)
    batch = random_batch(rng, T0, 20_000)
    with SqliteHistory(tmp_path / "h.sqlite") as store:
        assert store.append_batch(batch) == 20_000
        (chunks,) = store._db.execute("SELECT COUNT(*) FROM report_chunks").fetchone()
        assert chunks == 3  # 8192 + 8192 + 3616
        got = {key(r) for r in store.query_reports(FRAME)}
    want = {key(r) for r in batch.reports()}
    assert len(got) == len(want) and got == want  # None for NaN compares equal: exact


def test_a_failed_append_writes_nothing(tmp_path) -> None:
    rng = np.random.default_rng(7)
    with SqliteHistory(tmp_path / "h.sqlite") as store:
        store.append_batch(random_batch(rng, T0, 10))
        bad = random_batch(rng, T0 + 100, 9000)
        bad.t_unix_s[8500] = np.inf  # in the second chunk: the first is already inserted
        with pytest.raises(ParameterError, match="t_unix_s: a finite UNIX time.*actually: inf"):
            store.append_batch(bad)
        store.append_static([AisStatic(257000001, T0, 5, name="FERJA")])
        assert store.count_reports() == 10
    with SqliteHistory(tmp_path / "h.sqlite") as store:
        assert store.count_reports() == 10 and len(store.query_static()) == 1
    with pytest.raises(ParameterError, match="synchronous: one of"):
        SqliteHistory(tmp_path / "x.sqlite", synchronous="SOMETIMES")


def test_appended_batches_survive_a_killed_process(tmp_path) -> None:
    db = tmp_path / "crash.sqlite"
    child = textwrap.dedent(f"""
        import os, signal
        import numpy as np
        from asvtwin.sources.history import SqliteHistory
        from tests.sources.test_history import random_batch
        store = SqliteHistory({str(db)!r})
        rng = np.random.default_rng(8)
        for k in range(5):
            store.append_batch(random_batch(rng, {T0} + 100 * k, 200))
        os.kill(os.getpid(), signal.SIGKILL)  # no close(), no checkpoint
    """)
    proc = subprocess.run([sys.executable, "-c", child], check=False, cwd=str(_repo_root()),
                          timeout=60)
    assert proc.returncode == -9
    with SqliteHistory(db) as store:
        assert store.count_reports() == 1000
        assert len(store.query_reports(FRAME, since_unix_s=T0 + 400)) > 150


def _repo_root():
    from pathlib import Path

    return Path(__file__).resolve().parents[2]


V1_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
INSERT INTO meta VALUES ('schema', '1');
CREATE TABLE reports (
    t_unix_s REAL NOT NULL, mmsi INTEGER NOT NULL, msg_type INTEGER NOT NULL,
    lat_deg REAL NOT NULL, lon_deg REAL NOT NULL, sog_m_s REAL, cog_rad REAL,
    heading_rad REAL, rot_rad_s REAL, nav_status INTEGER, station TEXT);
CREATE INDEX reports_t ON reports (t_unix_s);
CREATE INDEX reports_mmsi_t ON reports (mmsi, t_unix_s);
CREATE TABLE static (
    t_unix_s REAL NOT NULL, mmsi INTEGER NOT NULL, msg_type INTEGER NOT NULL, name TEXT,
    callsign TEXT, ship_type INTEGER, imo INTEGER, to_bow_m INTEGER, to_stern_m INTEGER,
    to_port_m INTEGER, to_starboard_m INTEGER, draught_m REAL, destination TEXT);
CREATE TABLE weather (
    t_unix_s REAL NOT NULL, wind_speed_m_s REAL, wind_from_rad REAL, air_temperature_c REAL,
    air_pressure_pa REAL, relative_humidity REAL, cloud_fraction REAL, source TEXT);
INSERT INTO static (t_unix_s, mmsi, msg_type, name, ship_type)
    VALUES (1732100400.0, 257000001, 5, 'FERJA', 60);
"""


def test_schema_1_is_refused_or_migrated(tmp_path) -> None:
    db = tmp_path / "v1.sqlite"
    con = sqlite3.connect(db)
    con.executescript(V1_SCHEMA)
    rows = [(T0 + 10, 257000001, 1, 63.45, 10.40, 5.0, 0.5, 0.4, 0.0, 0, "2573555"),
            (T0 + 5, 257000002, 18, 63.46, 10.41, None, None, None, None, None, None),
            (T0 + 10, 257000002, 18, 63.461, 10.411, 2.0, -1.0, None, None, None, None)]
    con.executemany("INSERT INTO reports VALUES (?,?,?,?,?,?,?,?,?,?,?)", rows)
    con.commit()
    con.close()
    with pytest.raises(SourceError, match=r"schema 3 expected, actually: 1; .*migrate=True"):
        SqliteHistory(db)
    with SqliteHistory(db, migrate=True) as store:
        got = store.query_reports(FRAME)
        assert [(r.t_unix_s, r.mmsi) for r in got] == [
            (T0 + 5, 257000002), (T0 + 10, 257000001), (T0 + 10, 257000002)]
        assert got[0].sog_m_s is None and got[0].nav_status is None and got[0].station is None
        assert (got[1].sog_m_s, got[1].cog_rad, got[1].nav_status, got[1].station) == \
            (5.0, 0.5, 0, "2573555")
        assert store.query_static()[0].name == "FERJA"
    with SqliteHistory(db) as store:  # now schema 3: opens without migrating
        assert store.count_reports() == 3
        assert len(store.query_reports(FRAME, mmsi=257000002, since_unix_s=T0 + 6)) == 1
    names = {r[0] for r in sqlite3.connect(db).execute("SELECT name FROM sqlite_master")}
    assert "reports" not in names and "report_chunks" in names


def test_cli_history_refuses_old_schema_then_migrates(tmp_path, capsys) -> None:
    from asvtwin.cli import main

    db = tmp_path / "v1.sqlite"
    con = sqlite3.connect(db)
    con.executescript(V1_SCHEMA)
    con.execute("INSERT INTO reports VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                (T0 + 10, 257000001, 1, 63.45, 10.40, 5.0, 0.5, 0.4, 0.0, 0, "2573555"))
    con.commit()
    con.close()
    assert main(["ais", "history", "--db", str(db)]) == 2  # one line on stderr
    err = capsys.readouterr().err
    assert "actually: 1" in err and "--migrate" in err and "Traceback" not in err
    assert main(["ais", "history", "--db", str(db), "--migrate", "--json"]) == 0
    assert '"mmsi": 257000001' in capsys.readouterr().out
