"""The history database's schema: what a file is before anything is written, and migrations.

:class:`~asvtwin.sources.history.SqliteHistory` must never adopt a file that is not its own:
another application's SQLite database would silently gain the twin's tables and a write-ahead
log, and an old-schema file would be switched to WAL before being refused. So a file is
inspected first through a *read-only* connection (:func:`inspect_file`) and only then, if it
is empty or asvtwin's current schema (or ``migrate=True`` and an older one), opened for
writing.

Schema 3 (current), times in UNIX seconds:

- ``report_chunks(id, t_min_s, t_max_s, n, stations, columns, crc32)``: one row per appended
  batch, the reports as little-endian column arrays in the ``columns`` blob and its CRC-32
  (zlib) in ``crc32``, checked on every read so bit rot is reported, never served;
- ``report_chunk_mmsi(mmsi, t_min_s, chunk, t_max_s)``: which chunks hold a vessel, a
  ``WITHOUT ROWID`` table clustered on ``(mmsi, t_min_s, chunk)``. (Schema 2 had ``t_max_s``
  before ``chunk``; SQLite 3.40's ``PRAGMA integrity_check`` then reports a false "NULL
  value" for every row of such a table. With the key columns first the check is clean.)
- ``static``, ``weather``: one row per record; ``meta``: ``schema`` and ``max_chunk_span_s``.

Migrations, each in one transaction (an interrupted or failed one leaves the file as it
was): schema 1 (one row per report) and schema 2 (no checksums) to 3.
"""

from __future__ import annotations

import sqlite3
import zlib
from dataclasses import dataclass
from pathlib import Path

from asvtwin.errors import SourceError

__all__ = ["SCHEMA", "SCHEMA_VERSION", "FileKind", "inspect_file", "migrate_v2", "open_readonly"]

SCHEMA_VERSION = "3"
SCHEMA = """
CREATE TABLE IF NOT EXISTS report_chunks (
    id INTEGER PRIMARY KEY, t_min_s REAL NOT NULL, t_max_s REAL NOT NULL, n INTEGER NOT NULL,
    stations TEXT NOT NULL, columns BLOB NOT NULL, crc32 INTEGER NOT NULL);
CREATE INDEX IF NOT EXISTS report_chunks_t ON report_chunks (t_min_s);
CREATE TABLE IF NOT EXISTS report_chunk_mmsi (
    mmsi INTEGER NOT NULL, t_min_s REAL NOT NULL, chunk INTEGER NOT NULL, t_max_s REAL NOT NULL,
    PRIMARY KEY (mmsi, t_min_s, chunk)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS static (
    t_unix_s REAL NOT NULL, mmsi INTEGER NOT NULL, msg_type INTEGER NOT NULL, name TEXT,
    callsign TEXT, ship_type INTEGER, imo INTEGER, to_bow_m INTEGER, to_stern_m INTEGER,
    to_port_m INTEGER, to_starboard_m INTEGER, draught_m REAL, destination TEXT);
CREATE INDEX IF NOT EXISTS static_mmsi_t ON static (mmsi, t_unix_s);
CREATE TABLE IF NOT EXISTS weather (
    t_unix_s REAL NOT NULL, wind_speed_m_s REAL, wind_from_rad REAL, air_temperature_c REAL,
    air_pressure_pa REAL, relative_humidity REAL, cloud_fraction REAL, source TEXT);
CREATE INDEX IF NOT EXISTS weather_t ON weather (t_unix_s);
"""
_OURS = {"meta", "report_chunks", "report_chunk_mmsi", "static", "weather", "reports"}


@dataclass(frozen=True)
class FileKind:
    """What :func:`inspect_file` found.

    Attributes
    ----------
    schema : str or None
        ``meta.schema`` of an asvtwin history (``"1?"``: a ``reports`` table without a
        version), None for an empty or new file.
    tables : tuple of str
        Every table in the file.
    """

    schema: str | None
    tables: tuple[str, ...]


def open_readonly(path: str) -> sqlite3.Connection:
    """A read-only connection that writes nothing, not even a ``-shm`` file.

    ``mode=ro`` first; when that cannot open the file (a WAL database on read-only media
    needs a ``-shm`` file it cannot create) ``immutable=1``, which also skips locking: fine
    for media nobody writes to.
    """
    uri = Path(path).absolute().as_uri()
    try:
        db = sqlite3.connect(f"{uri}?mode=ro", uri=True, check_same_thread=False)
        db.execute("SELECT count(*) FROM sqlite_master").fetchone()
        return db
    except sqlite3.OperationalError:
        db = sqlite3.connect(f"{uri}?immutable=1", uri=True, check_same_thread=False)
        db.execute("SELECT count(*) FROM sqlite_master").fetchone()
        return db


def inspect_file(path: str) -> FileKind:
    """Classify a database file without writing to it.

    Raises
    ------
    SourceError
        If the file is not an SQLite database, or is another application's database (tables
        that are not asvtwin's, or no schema version).
    """
    if path == ":memory:" or not Path(path).exists() or Path(path).stat().st_size == 0:
        return FileKind(None, ())
    try:
        db = open_readonly(path)
        try:
            tables = tuple(r[0] for r in db.execute(
                "SELECT name FROM sqlite_master WHERE type='table' ORDER BY name"))
            meta = dict(db.execute("SELECT key, value FROM meta").fetchall()) \
                if "meta" in tables else {}
        finally:
            db.close()
    except sqlite3.Error as exc:
        raise SourceError(f"{path} is not a readable SQLite database ({exc}); the history "
                          "store refuses to write into it") from exc
    if not tables:
        return FileKind(None, ())
    foreign = sorted(set(tables) - _OURS)
    schema = meta.get("schema")
    if schema is None and "reports" in tables and "meta" not in tables:
        schema = "1?"
    if foreign or schema is None:
        raise SourceError(f"{path} is not an asvtwin history database (tables: "
                          f"{', '.join(tables)}); refusing to write into another application's "
                          "database: choose a new file")
    return FileKind(str(schema), tables)


def migrate_v2(db: sqlite3.Connection) -> None:
    """Schema 2 -> 3 inside the caller's transaction: checksum every chunk, rebuild the MMSI
    index table with its key columns first."""
    db.execute("ALTER TABLE report_chunks ADD COLUMN crc32 INTEGER")
    rows = db.execute("SELECT id, columns FROM report_chunks").fetchall()
    db.executemany("UPDATE report_chunks SET crc32 = ? WHERE id = ?",
                   [(zlib.crc32(blob), i) for i, blob in rows])
    db.execute("ALTER TABLE report_chunk_mmsi RENAME TO report_chunk_mmsi_v2")
    for statement in filter(str.strip, SCHEMA.split(";")):
        db.execute(statement)
    db.execute("INSERT INTO report_chunk_mmsi (mmsi, t_min_s, chunk, t_max_s) "
               "SELECT mmsi, t_min_s, chunk, t_max_s FROM report_chunk_mmsi_v2")
    db.execute("DROP TABLE report_chunk_mmsi_v2")
