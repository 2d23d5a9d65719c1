"""History: every accepted AIS report, static record and weather sample, appended to a store.

:class:`HistoryStore` is the interface (a :class:`typing.Protocol`) so a server database can
replace the default :class:`SqliteHistory` (the standard library's :mod:`sqlite3`, one file,
write-ahead log). Reports are kept in WGS84 (latitude/longitude, SI speeds and angles) so a
recorded session can be replayed into any scene: :func:`replay_session` re-projects them into
the scene's NED frame and merges reports and static data in time order.

Schema 3 (times are UNIX seconds; the tables and migrations are described in
:mod:`asvtwin.sources.history_schema`). Dynamic reports arrive at up to thousands per second,
so they are stored *columnar*, one row per appended batch (a "chunk", at most 8192 reports),
instead of one SQLite row per report: a row-per-report insert with its two index entries
costs about as much CPU as pyais's decode of the line, a chunk a few microseconds per batch.
``columns`` holds the little-endian column arrays of :data:`_COLUMNS` one after the other
(every field exactly as accepted, float64; NaN = not available, ``nav_status`` -1 = not
available, ``station`` an index into the JSON list ``stations``, 0 = unknown) and ``crc32``
its checksum, verified on every read. ``meta.max_chunk_span_s``, the widest chunk time span,
bounds the index range a time query scans.

A file is inspected read-only before anything is written: another application's database,
a file that is not SQLite, or an older schema (without ``migrate=True``) is refused with a
message and left untouched. ``SqliteHistory(path, readonly=True)`` opens for queries only
(also on read-only media). Write failures (a full disk) raise :class:`SourceError`; the
database stays consistent (each append is one transaction).
"""

from __future__ import annotations

import dataclasses
import heapq
import json
import os
import sqlite3
import zlib
from collections.abc import Iterable, Iterator, Sequence
from itertools import repeat
from operator import attrgetter
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from asvtwin.errors import ParameterError, SourceError
from asvtwin.geo import LocalFrame
from asvtwin.sources.ais.reports import AisReport, AisStatic, ReportBatch
from asvtwin.sources.history_schema import (
    SCHEMA,
    SCHEMA_VERSION,
    inspect_file,
    migrate_v2,
    open_readonly,
)
from asvtwin.sources.weather.series import WeatherSample

__all__ = ["HistoryStore", "SqliteHistory", "replay_session"]

#: Column layout of a chunk blob: (field of ReportBatch, little-endian dtype), in this order.
_COLUMNS: tuple[tuple[str, str], ...] = (
    ("t_unix_s", "<f8"), ("mmsi", "<i8"), ("msg_type", "<i2"), ("lat_deg", "<f8"),
    ("lon_deg", "<f8"), ("sog_m_s", "<f8"), ("cog_rad", "<f8"), ("heading_rad", "<f8"),
    ("rot_rad_s", "<f8"), ("nav_status", "<i2"), ("station", "<u2"))
_ROW_BYTES = sum(np.dtype(d).itemsize for _, d in _COLUMNS)
_CHUNK_ROWS = 8192
_SEQ_BITS = 14  # a report's arrival key: chunk id << 14 | row (rows < 8192 < 2**14)
_SYNCHRONOUS = ("OFF", "NORMAL", "FULL", "EXTRA")
_V1_COLUMNS = ("t_unix_s, mmsi, msg_type, lat_deg, lon_deg, sog_m_s, cog_rad, heading_rad, "
               "rot_rad_s, nav_status, station")
_STATIC_FIELDS = [f.name for f in dataclasses.fields(AisStatic)]
_STATIC_ROW = attrgetter(*_STATIC_FIELDS)
_WEATHER_FIELDS = ["t_unix_s", "wind_speed_m_s", "wind_from_rad", "air_temperature_c",
                   "air_pressure_pa", "relative_humidity", "cloud_fraction"]

_Cols = dict[str, NDArray[Any]]


@runtime_checkable
class HistoryStore(Protocol):
    """Where accepted reports, static data and weather samples are appended and queried."""

    def append_batch(self, batch: ReportBatch) -> int:
        """Append a batch (its dynamic reports and static records); return rows written."""

    def append_reports(self, reports: Sequence[AisReport]) -> int:
        """Append dynamic reports; return rows written."""

    def append_static(self, records: Sequence[AisStatic]) -> int:
        """Append static records; return rows written."""

    def append_weather(self, samples: Sequence[WeatherSample], *, source: str = "") -> int:
        """Append weather samples; return rows written."""

    def query_reports(self, frame: LocalFrame, *, mmsi: int | None = None,
                      since_unix_s: float | None = None, until_unix_s: float | None = None,
                      limit: int | None = None) -> list[AisReport]:
        """Reports in time order, projected into ``frame``."""

    def query_static(self, *, mmsi: int | None = None, since_unix_s: float | None = None,
                     until_unix_s: float | None = None) -> list[AisStatic]:
        """Static records in time order."""

    def query_weather(self, *, since_unix_s: float | None = None,
                      until_unix_s: float | None = None) -> list[WeatherSample]:
        """Weather samples in time order."""

    def close(self) -> None:
        """Flush and release the store."""


def _where(mmsi: int | None, since: float | None, until: float | None) -> tuple[str, list[Any]]:
    clauses: list[str] = []
    args: list[Any] = []
    if mmsi is not None:
        clauses.append("mmsi = ?")
        args.append(int(mmsi))
    if since is not None:
        clauses.append("t_unix_s >= ?")
        args.append(float(since))
    if until is not None:
        clauses.append("t_unix_s <= ?")
        args.append(float(until))
    return (" WHERE " + " AND ".join(clauses) if clauses else ""), args


def _decode_chunk(n: int, blob: bytes) -> _Cols:
    """The column arrays of one chunk blob (read-only views on ``blob``)."""
    if len(blob) != n * _ROW_BYTES:
        raise SourceError(f"history chunk of {n} reports: {n * _ROW_BYTES} bytes expected, "
                          f"actually: {len(blob)}")
    cols: _Cols = {}
    offset = 0
    for name, dtype in _COLUMNS:
        cols[name] = np.frombuffer(blob, dtype, n, offset)
        offset += n * np.dtype(dtype).itemsize
    return cols


class SqliteHistory:
    """The default :class:`HistoryStore`: one SQLite file (or ``":memory:"``).

    Every :meth:`append_batch` is one transaction. With the default WAL journal and
    ``synchronous="NORMAL"`` a process crash loses nothing that was appended, and a power cut
    or OS crash can lose only the last transactions since the last WAL checkpoint, never
    corrupt the file; ``synchronous="FULL"`` makes every append durable (one fsync each).

    Parameters
    ----------
    path : str or os.PathLike
        Database file, created if missing; ``":memory:"`` for a throw-away store.
    synchronous : str
        SQLite ``synchronous`` pragma: ``"OFF"``, ``"NORMAL"`` (default), ``"FULL"``, ``"EXTRA"``.
    migrate : bool
        Convert a schema-1 (one row per report) or schema-2 (no checksums) database to the
        current schema in one transaction instead of refusing it.
    readonly : bool
        Open for queries only: nothing is written, not even a journal (works on read-only
        media). Schemas 2 and 3 can be read (schema 2 without checksums to verify).

    Raises
    ------
    SourceError
        If the file cannot be opened, is not an asvtwin history (another application's
        database, not SQLite), or holds another schema version (and ``migrate`` is False or
        cannot convert it). Nothing is written to a refused file.
    ParameterError
        If ``synchronous`` is not one of the values above.
    """

    def __init__(self, path: str | os.PathLike[str] = ":memory:", *,
                 synchronous: str = "NORMAL", migrate: bool = False,
                 readonly: bool = False) -> None:
        self.path = str(path)
        self.readonly = bool(readonly)
        if str(synchronous).upper() not in _SYNCHRONOUS:
            raise ParameterError(f"synchronous: one of {_SYNCHRONOUS} expected, "
                                 f"actually: {synchronous!r}")
        kind = inspect_file(self.path)  # read-only: refuses foreign files before any write
        found = kind.schema
        if readonly:
            self._open_readonly(found)
            return
        if found is not None and found != SCHEMA_VERSION and not (
                migrate and found in ("1", "2")):
            hint = (f"; open it with SqliteHistory(path, migrate=True) (asvtwin ais history "
                    f"--migrate) to convert it to schema {SCHEMA_VERSION}"
                    if found in ("1", "2") else "")
            raise SourceError(f"{self.path}: history schema {SCHEMA_VERSION} expected, "
                              f"actually: {found}{hint}")
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False)
            if found == "1":
                self._migrate_v1()
            elif found == "2":
                self._migrate(migrate_v2, "2")
            if self.path != ":memory:":
                self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute(f"PRAGMA synchronous={synchronous.upper()}")
            self._db.execute("CREATE TABLE IF NOT EXISTS meta "
                             "(key TEXT PRIMARY KEY, value TEXT NOT NULL)")
            meta = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
            self._db.executescript(SCHEMA)
            if found is None:
                self._db.execute("INSERT INTO meta VALUES ('schema', ?)", (SCHEMA_VERSION,))
                self._db.commit()
            self._span_s = float(meta.get("max_chunk_span_s", 0.0))
            self._checksums = True
        except sqlite3.Error as exc:
            raise SourceError(f"cannot open history database {self.path!r}: {exc}") from exc

    def _open_readonly(self, found: str | None) -> None:
        if found is None:
            raise SourceError(f"{self.path}: no history to read (empty or missing file)")
        if found not in ("2", SCHEMA_VERSION):
            raise SourceError(f"{self.path}: history schema 2 or {SCHEMA_VERSION} expected for "
                              f"reading, actually: {found}; convert it with --migrate on a "
                              "writable copy")
        try:
            self._db = open_readonly(self.path)
            meta = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
        except sqlite3.Error as exc:
            raise SourceError(f"cannot open history database {self.path!r} read-only: "
                              f"{exc}") from exc
        self._span_s = float(meta.get("max_chunk_span_s", 0.0))
        self._checksums = found == SCHEMA_VERSION

    def _write_error(self, exc: sqlite3.Error) -> SourceError:
        full = isinstance(exc, sqlite3.OperationalError) and "full" in str(exc)
        what = "the disk (or the database's size limit) is full" if full else str(exc)
        return SourceError(f"cannot write to history database {self.path!r}: {what}; the "
                           "database keeps everything appended before")

    # ------------------------------------------------------------------ writes
    def append_batch(self, batch: ReportBatch) -> int:
        """Append a batch in one transaction (all of it or, on an error, none of it).

        Returns
        -------
        int
            Dynamic reports plus static records written.

        Raises
        ------
        ParameterError
            If a report time is not finite.
        SourceError
            If the database cannot be written (full disk, read-only file, ...); nothing of
            the batch is written, everything before stays.
        """
        n = len(batch)
        try:
            for lo in range(0, n, _CHUNK_ROWS):
                hi = min(n, lo + _CHUNK_ROWS)
                self._insert_chunk({name: getattr(batch, name)[lo:hi]
                                    for name, _ in _COLUMNS[:-1]}, batch.station[lo:hi])
            if batch.static:
                n += self._insert_static(batch.static)
            self._db.commit()
        except sqlite3.Error as exc:
            self._rollback()
            raise self._write_error(exc) from exc
        except BaseException:
            self._rollback()
            raise
        return n

    def _rollback(self) -> None:
        try:
            self._db.rollback()
        except sqlite3.Error:  # the failed statement may have ended the transaction already
            pass

    def _insert_chunk(self, cols: _Cols, stations: Sequence[str | None]) -> None:
        t = cols["t_unix_s"]
        if not np.isfinite(t).all():
            bad = t[~np.isfinite(t)][0]
            raise ParameterError(f"t_unix_s: a finite UNIX time [s] expected, actually: {bad}")
        first = stations[0]
        if stations.count(first) == len(stations):  # the usual case: one feed, one station
            names = [] if first is None else [first]
            cols["station"] = np.full(len(t), len(names), np.uint16)
        else:
            names = [s for s in dict.fromkeys(stations) if s is not None]
            code = {None: 0} | {s: k + 1 for k, s in enumerate(names)}
            cols["station"] = np.fromiter(map(code.__getitem__, stations), np.uint16, len(t))
        blob = b"".join([np.ascontiguousarray(cols[name], dtype).tobytes()
                         for name, dtype in _COLUMNS])
        t_min, t_max = float(t.min()), float(t.max())
        chunk = self._db.execute(
            "INSERT INTO report_chunks (t_min_s, t_max_s, n, stations, columns, crc32) "
            "VALUES (?,?,?,?,?,?)",
            (t_min, t_max, len(t), json.dumps(names), blob, zlib.crc32(blob))).lastrowid
        # the chunk's span stands for each vessel's (cheaper; a query filters the rows anyway)
        self._db.executemany("INSERT INTO report_chunk_mmsi (mmsi, t_min_s, chunk, t_max_s) "
                             "VALUES (?,?,?,?)",
                             zip(np.unique(cols["mmsi"]).tolist(), repeat(t_min), repeat(chunk),
                                 repeat(t_max)))
        if t_max - t_min > self._span_s:
            self._span_s = t_max - t_min
            self._db.execute("INSERT OR REPLACE INTO meta VALUES ('max_chunk_span_s', ?)",
                             (repr(self._span_s),))

    def append_reports(self, reports: Sequence[AisReport]) -> int:
        return self.append_batch(ReportBatch.from_reports(list(reports)))

    def _insert_static(self, records: Iterable[AisStatic]) -> int:
        rows = list(map(_STATIC_ROW, records))
        self._db.executemany(f"INSERT INTO static ({','.join(_STATIC_FIELDS)}) "
                             f"VALUES ({','.join('?' * len(_STATIC_FIELDS))})", rows)
        return len(rows)

    def append_static(self, records: Sequence[AisStatic]) -> int:
        try:
            n = self._insert_static(records)
            self._db.commit()
        except sqlite3.Error as exc:
            self._rollback()
            raise self._write_error(exc) from exc
        return n

    def append_weather(self, samples: Sequence[WeatherSample], *, source: str = "") -> int:
        rows = [tuple(getattr(s, f) for f in _WEATHER_FIELDS) + (source,) for s in samples]
        try:
            self._db.executemany(f"INSERT INTO weather ({','.join(_WEATHER_FIELDS)}, source) "
                                 "VALUES (?,?,?,?,?,?,?,?)", rows)
            self._db.commit()
        except sqlite3.Error as exc:
            self._rollback()
            raise self._write_error(exc) from exc
        return len(rows)

    def _migrate_v1(self) -> None:
        """Schema 1 -> 3: re-write ``reports`` as chunks."""
        nan = float("nan")

        def v1(db: sqlite3.Connection) -> None:
            for statement in filter(str.strip, SCHEMA.split(";")):
                db.execute(statement)
            self._span_s = 0.0
            rows_cur = db.execute(f"SELECT {_V1_COLUMNS} FROM reports ORDER BY t_unix_s, rowid")
            while rows := rows_cur.fetchmany(_CHUNK_ROWS):
                c = list(zip(*rows))
                cols: _Cols = {name: np.array([nan if v is None else v for v in c[k]],
                                              np.float64)
                               for k, (name, _) in enumerate(_COLUMNS[:9])}
                cols["nav_status"] = np.array([-1 if v is None else v for v in c[9]], np.int64)
                self._insert_chunk(cols, c[10])
            db.execute("DROP TABLE reports")

        self._migrate(v1, "1")

    def _migrate(self, step: Any, found: str) -> None:
        """Run one migration in one transaction; any failure leaves the file as it was and
        raises :class:`SourceError` (a bad value in an old row, a full disk, ...)."""
        db = self._db
        try:
            db.execute("BEGIN")  # DDL included: a failed or interrupted migration changes nothing
            step(db)
            db.execute("UPDATE meta SET value=? WHERE key='schema'", (SCHEMA_VERSION,))
            db.commit()
        except (sqlite3.Error, ValueError, TypeError, OverflowError) as exc:
            self._rollback()
            db.close()
            raise SourceError(f"{self.path}: cannot migrate history schema {found} to "
                              f"{SCHEMA_VERSION} ({type(exc).__name__}: {exc}); the file is "
                              "unchanged") from exc

    # ------------------------------------------------------------------ reads
    def query_reports(self, frame: LocalFrame, *, mmsi: int | None = None,
                      since_unix_s: float | None = None, until_unix_s: float | None = None,
                      limit: int | None = None) -> list[AisReport]:
        return list(self.iter_reports(frame, mmsi=mmsi, since_unix_s=since_unix_s,
                                      until_unix_s=until_unix_s, limit=limit))

    def iter_reports(self, frame: LocalFrame, *, mmsi: int | None = None,
                     since_unix_s: float | None = None, until_unix_s: float | None = None,
                     limit: int | None = None) -> Iterator[AisReport]:
        """Like :meth:`query_reports` but streamed chunk by chunk (for long sessions)."""
        for batch in self.iter_batches(frame, mmsi=mmsi, since_unix_s=since_unix_s,
                                       until_unix_s=until_unix_s, limit=limit):
            yield from batch.reports()

    def iter_batches(self, frame: LocalFrame, *, mmsi: int | None = None,
                     since_unix_s: float | None = None, until_unix_s: float | None = None,
                     limit: int | None = None) -> Iterator[ReportBatch]:
        """Stored reports as columnar batches, in time order (ties: arrival order).

        Parameters
        ----------
        frame : LocalFrame
            Frame the WGS84 positions are projected into (``north_m``, ``east_m``).
        mmsi : int, optional
            Only this vessel (found through ``report_chunk_mmsi``).
        since_unix_s, until_unix_s : float, optional
            Inclusive time range [UNIX s].
        limit : int, optional
            At most this many reports.
        """
        args: list[Any] = []
        if mmsi is None:
            sql = "SELECT id, t_min_s FROM report_chunks WHERE 1"
        else:
            sql = "SELECT chunk, t_min_s FROM report_chunk_mmsi WHERE mmsi = ?"
            args.append(int(mmsi))
        if since_unix_s is not None:  # a chunk starts at most max_chunk_span_s before it ends
            sql += " AND t_min_s >= ? AND t_max_s >= ?"
            args += [float(since_unix_s) - self._span_s, float(since_unix_s)]
        if until_unix_s is not None:
            sql += " AND t_min_s <= ?"
            args.append(float(until_unix_s))
        chunks = self._db.execute(sql + " ORDER BY 2, 1", args).fetchall()
        left = np.inf if limit is None else int(limit)
        pending: _Cols | None = None
        for chunk, t_start in [*chunks, (None, np.inf)]:
            if pending is not None:  # rows before t_start: no later chunk can precede them
                ready = int(np.searchsorted(pending["t_unix_s"], t_start, side="left"))
                if ready:
                    done = {k: v[:min(ready, left)] for k, v in pending.items()}
                    pending = {k: v[ready:] for k, v in pending.items()}
                    left -= len(done["seq"])
                    yield self._batch(frame, done)
                    if left <= 0:
                        return
            if chunk is None:
                break
            n, names, blob, crc = self._db.execute(
                f"SELECT n, stations, columns, {'crc32' if self._checksums else 'NULL'} "
                "FROM report_chunks WHERE id = ?", (chunk,)).fetchone()
            if crc is not None and zlib.crc32(blob) != crc:
                raise SourceError(f"{self.path}: report chunk {chunk} is corrupt (CRC-32 "
                                  f"0x{zlib.crc32(blob):08X} of the data, 0x{crc:08X} stored); "
                                  "restore the file from a backup")
            cols = _decode_chunk(n, blob)
            keep = np.ones(n, bool)
            if mmsi is not None:
                keep &= cols["mmsi"] == int(mmsi)
            if since_unix_s is not None:
                keep &= cols["t_unix_s"] >= since_unix_s
            if until_unix_s is not None:
                keep &= cols["t_unix_s"] <= until_unix_s
            rows = np.flatnonzero(keep)
            new = {k: v[rows] for k, v in cols.items()}
            new["seq"] = (np.int64(chunk) << _SEQ_BITS) | rows
            new["station_name"] = np.array([None, *json.loads(names)], object)[new["station"]]
            if pending is not None:
                new = {k: np.concatenate((pending[k], v)) for k, v in new.items()}
            order = np.lexsort((new["seq"], new["t_unix_s"]))
            pending = {k: v[order] for k, v in new.items()}

    @staticmethod
    def _batch(frame: LocalFrame, c: _Cols) -> ReportBatch:
        north, east = frame.to_ned(c["lat_deg"], c["lon_deg"])
        f8 = {k: np.array(c[k], np.float64) for k in (
            "t_unix_s", "lat_deg", "lon_deg", "sog_m_s", "cog_rad", "heading_rad", "rot_rad_s")}
        return ReportBatch(
            mmsi=np.array(c["mmsi"], np.int64), msg_type=np.array(c["msg_type"], np.int64),
            north_m=np.asarray(north, np.float64), east_m=np.asarray(east, np.float64),
            nav_status=np.array(c["nav_status"], np.int64),
            station=tuple(c["station_name"].tolist()), frame=frame,
            **f8)  # type: ignore[arg-type]

    def query_static(self, *, mmsi: int | None = None, since_unix_s: float | None = None,
                     until_unix_s: float | None = None) -> list[AisStatic]:
        where, args = _where(mmsi, since_unix_s, until_unix_s)
        cur = self._db.execute(f"SELECT {','.join(_STATIC_FIELDS)} FROM static{where} "
                               "ORDER BY t_unix_s, rowid", args)
        return [AisStatic(*row) for row in cur.fetchall()]

    def query_weather(self, *, since_unix_s: float | None = None,
                      until_unix_s: float | None = None) -> list[WeatherSample]:
        where, args = _where(None, since_unix_s, until_unix_s)
        cur = self._db.execute(
            f"SELECT {','.join(_WEATHER_FIELDS)} FROM weather{where} ORDER BY t_unix_s, rowid",
            args)
        return [WeatherSample(*row) for row in cur.fetchall()]

    def count_reports(self) -> int:
        """Number of stored dynamic reports."""
        return int(self._db.execute("SELECT TOTAL(n) FROM report_chunks").fetchone()[0])

    def time_span(self) -> tuple[float, float] | None:
        """First and last report time [UNIX s], None when empty."""
        lo, hi = self._db.execute(
            "SELECT MIN(t_min_s), MAX(t_max_s) FROM report_chunks").fetchone()
        return None if lo is None else (float(lo), float(hi))

    def check(self) -> list[str]:
        """Verify the file: SQLite's ``PRAGMA integrity_check`` and every chunk's CRC-32.

        Returns
        -------
        list of str
            Problems found; empty when the file is sound.
        """
        problems = [r[0] for r in self._db.execute("PRAGMA integrity_check") if r[0] != "ok"]
        if self._checksums:
            for chunk, blob, crc in self._db.execute(
                    "SELECT id, columns, crc32 FROM report_chunks ORDER BY id"):
                if zlib.crc32(blob) != crc:
                    problems.append(f"report chunk {chunk}: CRC-32 mismatch")
        return problems

    def close(self) -> None:
        if not self.readonly:
            try:
                self._db.commit()
            except sqlite3.Error as exc:
                self._db.close()
                raise self._write_error(exc) from exc
        self._db.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def replay_session(store: SqliteHistory, frame: LocalFrame, *,
                   since_unix_s: float | None = None, until_unix_s: float | None = None
                   ) -> Iterator[AisReport | AisStatic]:
    """A recorded session in time order: reports (projected into ``frame``) and static data.

    Feed it to a :class:`~asvtwin.sources.ais.registry.TargetRegistry` (``ingest``) to rebuild
    the target picture, or pace it with :class:`~asvtwin.sources.ais.replay.HistoryReplaySource`.
    """
    reports = store.iter_reports(frame, since_unix_s=since_unix_s, until_unix_s=until_unix_s)
    statics = iter(store.query_static(since_unix_s=since_unix_s, until_unix_s=until_unix_s))
    merged: Iterator[AisReport | AisStatic] = heapq.merge(  # type: ignore[misc]
        statics, reports, key=lambda m: m.t_unix_s)
    yield from merged
