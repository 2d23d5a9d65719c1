"""Losses and storage (issue items 10-12): a full disk suspends recording, UDP losses are
counted, the history refuses files that are not its own and detects bit rot."""

from __future__ import annotations

import asyncio
import socket
import sqlite3
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from asvtwin.errors import SourceError
from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisPipeline, ReportBatch, SyntheticTraffic, UdpAisSource
from asvtwin.sources.history import SqliteHistory
from asvtwin.sources.recorder import HistoryRecorder

from .conftest import T0

FRAME = default_scene().frame


def _batches(n: int = 6, seconds: float = 60.0) -> list[ReportBatch]:
    lines = [x.line for x in SyntheticTraffic(rng=np.random.default_rng(2),
                                              start_unix_s=T0).run(n * seconds)]
    p = AisPipeline()
    k = len(lines) // n
    return [p.feed_batch(lines[i:i + k]) for i in range(0, len(lines), k)]


class _FullDisk(SqliteHistory):
    """A store on a disk that fills up: SQLite's page limit gives the real SQLITE_FULL."""

    def limit(self) -> None:
        pages = self._db.execute("PRAGMA page_count").fetchone()[0]
        self._db.execute(f"PRAGMA max_page_count = {pages}")


def test_a_full_disk_raises_source_error_and_keeps_the_database(tmp_path) -> None:
    batches = _batches()
    store = _FullDisk(tmp_path / "h.sqlite")
    store.append_batch(batches[0])
    store.limit()
    written = len(batches[0])
    with pytest.raises(SourceError, match="disk .* is full") as err:
        for b in batches[1:]:  # the last page's free space takes a batch or two
            store.append_batch(b)
            written += len(b)
    assert isinstance(err.value.__cause__, sqlite3.OperationalError)  # not raised raw
    # the failed batch left nothing behind, everything before it is intact
    assert store.count_reports() == written and store.check() == []
    store.close()


def test_the_recorder_suspends_counts_and_resumes(tmp_path) -> None:
    batches = _batches()
    store = _FullDisk(tmp_path / "h.sqlite")
    now = [0.0]
    rec = HistoryRecorder(store, clock=lambda: now[0], retry_after_s=60.0)
    rec.submit(batches[0])
    _wait_idle(rec)
    store.limit()
    k = 1
    while not rec.status().failures:  # until the disk is full
        rec.submit(batches[k])
        _wait_idle(rec)
        k += 1
    full = rec.status()
    rec.submit(batches[k])  # suspended: counted, not tried
    _wait_idle(rec)
    st = rec.status()
    assert st.suspended and st.failures == 1 and "full" in (st.last_error or "")
    assert st.lost_reports == len(batches[k - 1]) + len(batches[k])
    assert st.recorded_reports + st.lost_reports == sum(len(b) for b in batches[:k + 1])
    store._db.execute("PRAGMA max_page_count = 1073741823")  # space freed
    now[0] = 61.0
    rec.submit(batches[k + 1])
    final = rec.close()
    assert not final.suspended and final.failures == 1
    assert final.recorded_reports == full.recorded_reports + len(batches[k + 1])
    with SqliteHistory(tmp_path / "h.sqlite", readonly=True) as again:
        assert again.count_reports() == final.recorded_reports and again.check() == []


def _wait_idle(rec: HistoryRecorder) -> None:
    for _ in range(500):
        if rec.status().queued == 0:
            time.sleep(0.02)
            return
        time.sleep(0.01)


def test_listen_keeps_listening_when_recording_fails(tmp_path, capsys, monkeypatch) -> None:
    """Before: ais listen --db died with a traceback on a full disk."""
    from importlib import resources

    from asvtwin.cli import main

    def full(self, batch):  # every write fails as on a full disk
        raise SourceError(f"cannot write to history database {self.path!r}: the disk (or the "
                          "database's size limit) is full")

    monkeypatch.setattr(SqliteHistory, "append_batch", full)
    sample = str(resources.files("asvtwin.sources").joinpath("data",
                                                             "trondheim_synthetic_15min.nmea"))
    assert main(["ais", "listen", sample, "--speed", "0", "--no-live", "--db",
                 str(tmp_path / "h.sqlite")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "AIS targets" in out and "NOT recorded" in out and "SUSPENDED" in out


def test_udp_losses_in_the_kernel_and_the_queue_are_all_counted() -> None:
    """Before: 9,461 of 10,000 datagrams lost in the kernel with the counters at zero."""
    lines = [x.line.encode() for x in SyntheticTraffic(
        rng=np.random.default_rng(3), start_unix_s=T0).run(600.0)][:400]
    n_sent = 20_000
    result: dict[str, object] = {}

    def send(port: int) -> None:
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k in range(n_sent):
            tx.sendto(lines[k % len(lines)], ("127.0.0.1", port))
        tx.close()

    async def run() -> None:
        src = UdpAisSource(0, host="127.0.0.1", queue_size=64, rcvbuf_bytes=65536)

        async def consume() -> None:
            async for _ in src.batches():
                time.sleep(0.05)  # noqa: ASYNC251 (the point: a consumer that blocks the loop)

        task = asyncio.create_task(consume())
        await src.ready.wait()
        sender = threading.Thread(target=send, args=(src.bound_port,))
        sender.start()
        while sender.is_alive():
            await asyncio.sleep(0.01)
        await asyncio.sleep(1.0)
        task.cancel()
        try:
            await task
        except asyncio.CancelledError:
            pass
        result["src"] = src

    asyncio.run(run())
    src = result["src"]
    assert isinstance(src, UdpAisSource)
    errors = src.status().stats.errors
    assert src.drop_counter_available and src.rcvbuf_bytes_granted >= 65536
    kernel, queue = errors.get("kernel_drop", 0), errors.get("queue_overflow", 0)
    assert kernel > 0 and src.datagrams > 0  # the burst overran the socket buffer: it shows
    # every datagram is accounted for: received (then handed out, or dropped from the full
    # queue and counted) or dropped by the kernel and counted
    assert src.datagrams + kernel == n_sent, (src.datagrams, kernel, queue)


# ----------------------------------------------------------------------------- the file
def _fingerprint(path: Path) -> tuple[bytes, list[str]]:
    return path.read_bytes(), sorted(p.name for p in path.parent.iterdir())


def test_another_applications_database_is_refused_untouched(tmp_path) -> None:
    """Before: it silently gained asvtwin's tables and a WAL."""
    db = tmp_path / "app.sqlite"
    con = sqlite3.connect(db)
    con.execute("CREATE TABLE customers (id INTEGER PRIMARY KEY, name TEXT)")
    con.execute("INSERT INTO customers VALUES (1, 'Ola')")
    con.commit()
    con.close()
    before = _fingerprint(db)
    with pytest.raises(SourceError, match="not an asvtwin history database.*customers"):
        SqliteHistory(db)
    with pytest.raises(SourceError, match="not an asvtwin history"):
        SqliteHistory(db, migrate=True)
    assert _fingerprint(db) == before
    text = tmp_path / "notes.txt"
    text.write_text("not a database at all\n" * 100)
    with pytest.raises(SourceError, match="not a readable SQLite database"):
        SqliteHistory(text)
    assert text.read_text() == "not a database at all\n" * 100


def test_an_old_schema_is_refused_without_switching_it_to_wal(tmp_path) -> None:
    db = tmp_path / "v2.sqlite"
    _schema_2(db)
    before = _fingerprint(db)
    with pytest.raises(SourceError, match="schema 3 expected, actually: 2; .*--migrate"):
        SqliteHistory(db)
    assert _fingerprint(db) == before and before[0][18:20] == b"\x01\x01"  # still rollback


def _schema_2(db: Path, *, bad_blob: bool = False) -> None:
    """A database as schema 2 wrote it (no checksums, t_max_s before chunk)."""
    con = sqlite3.connect(db)
    con.executescript("""
    CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
    INSERT INTO meta VALUES ('schema', '2');
    CREATE TABLE report_chunks (id INTEGER PRIMARY KEY, t_min_s REAL NOT NULL,
        t_max_s REAL NOT NULL, n INTEGER NOT NULL, stations TEXT NOT NULL, columns BLOB NOT NULL);
    CREATE TABLE report_chunk_mmsi (mmsi INTEGER NOT NULL, t_min_s REAL NOT NULL,
        t_max_s REAL NOT NULL, chunk INTEGER NOT NULL, PRIMARY KEY (mmsi, t_min_s, chunk))
        WITHOUT ROWID;
    CREATE TABLE static (t_unix_s REAL NOT NULL, mmsi INTEGER NOT NULL, msg_type INTEGER NOT NULL,
        name TEXT, callsign TEXT, ship_type INTEGER, imo INTEGER, to_bow_m INTEGER,
        to_stern_m INTEGER, to_port_m INTEGER, to_starboard_m INTEGER, draught_m REAL,
        destination TEXT);
    CREATE TABLE weather (t_unix_s REAL NOT NULL, wind_speed_m_s REAL, wind_from_rad REAL,
        air_temperature_c REAL, air_pressure_pa REAL, relative_humidity REAL,
        cloud_fraction REAL, source TEXT);
    """)
    cols = [np.array([T0], "<f8"), np.array([257000001], "<i8"), np.array([1], "<i2"),
            np.array([63.45], "<f8"), np.array([10.4], "<f8"), np.array([5.0], "<f8"),
            np.array([0.5], "<f8"), np.array([0.4], "<f8"), np.array([0.0], "<f8"),
            np.array([0], "<i2"), np.array([1], "<u2")]
    blob = b"".join(c.tobytes() for c in cols)
    con.execute("INSERT INTO report_chunks VALUES (1, ?, ?, 1, '[\"2573555\"]', ?)",
                (T0, T0, blob))
    con.execute("INSERT INTO report_chunk_mmsi VALUES (257000001, ?, ?, 1)", (T0, T0))
    con.commit()
    con.close()


def test_schema_2_migrates_and_then_passes_sqlites_integrity_check(tmp_path) -> None:
    db = tmp_path / "v2.sqlite"
    _schema_2(db)
    assert sqlite3.connect(db).execute("PRAGMA integrity_check").fetchone()[0] != "ok"
    with SqliteHistory(db, migrate=True) as store:
        (r,) = store.query_reports(FRAME)
        assert (r.mmsi, r.sog_m_s, r.station) == (257000001, 5.0, "2573555")
        assert store.check() == []
    assert sqlite3.connect(db).execute("PRAGMA integrity_check").fetchall() == [("ok",)]


def test_a_failing_migration_is_a_clear_error_and_changes_nothing(tmp_path) -> None:
    from .test_history import V1_SCHEMA

    db = tmp_path / "v1.sqlite"
    con = sqlite3.connect(db)
    con.executescript(V1_SCHEMA)
    con.execute("INSERT INTO reports VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                (T0, 257000001, 1, "sixty-three", 10.40, 5.0, 0.5, 0.4, 0.0, 0, "2573555"))
    con.commit()
    con.close()
    before = db.read_bytes()
    with pytest.raises(SourceError, match="cannot migrate history schema 1 to 3 .*unchanged"):
        SqliteHistory(db, migrate=True)
    assert sqlite3.connect(db).execute("SELECT count(*) FROM reports").fetchone()[0] == 1
    assert db.read_bytes()[:100] == before[:100]


def test_fresh_store_is_clean_and_bit_rot_is_detected_not_served(tmp_path) -> None:
    db = tmp_path / "h.sqlite"
    with SqliteHistory(db) as store:
        for b in _batches(3):
            store.append_batch(b)
        assert store.check() == []
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA integrity_check").fetchall() == [("ok",)]
    blob = bytearray(con.execute("SELECT columns FROM report_chunks WHERE id = 2").fetchone()[0])
    blob[40] ^= 0x10  # one flipped bit in a latitude
    con.execute("UPDATE report_chunks SET columns = ? WHERE id = 2", (bytes(blob),))
    con.commit()
    con.close()
    with SqliteHistory(db, readonly=True) as store:
        assert store.check() == ["report chunk 2: CRC-32 mismatch"]
        with pytest.raises(SourceError, match="report chunk 2 is corrupt"):
            store.query_reports(FRAME)


def test_history_reads_from_read_only_media(tmp_path, capsys) -> None:
    """Before: `ais history` could not read a database on read-only media."""
    from asvtwin.cli import main

    media = tmp_path / "media"
    media.mkdir()
    db = media / "h.sqlite"
    with SqliteHistory(db) as store:
        store.append_batch(_batches(2)[0])
    before = _fingerprint(db)
    if subprocess.run(["chattr", "+i", str(media)], capture_output=True,
                      check=False).returncode != 0:
        pytest.skip("chattr +i (an immutable directory, like read-only media) not permitted")
    try:
        assert main(["ais", "history", "--db", str(db), "--limit", "2", "--json"]) == 0
        assert len(capsys.readouterr().out.splitlines()) == 2
    finally:
        subprocess.run(["chattr", "-i", str(media)], check=True)
    assert _fingerprint(db) == before  # nothing written, no -wal or -shm left behind
