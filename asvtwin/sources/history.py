"""History: every accepted AIS report, static record and weather sample, appended to a store.

:class:`HistoryStore` is the interface (a :class:`typing.Protocol`) so a server database can
replace the default :class:`SqliteHistory` (the standard library's :mod:`sqlite3`, one file,
write-ahead log). Reports are kept in WGS84 (latitude/longitude, SI speeds and angles) so a
recorded session can be replayed into any scene: :func:`replay_session` re-projects them into
the scene's NED frame and merges reports and static data in time order.

Tables (times are UNIX seconds; NULL is "not available"):

- ``reports(t_unix_s, mmsi, msg_type, lat_deg, lon_deg, sog_m_s, cog_rad, heading_rad,
  rot_rad_s, nav_status, station)``, indexed on ``t_unix_s`` and ``(mmsi, t_unix_s)``;
- ``static(t_unix_s, mmsi, msg_type, name, callsign, ship_type, imo, to_bow_m, to_stern_m,
  to_port_m, to_starboard_m, draught_m, destination)``, indexed on ``(mmsi, t_unix_s)``;
- ``weather(t_unix_s, wind_speed_m_s, wind_from_rad, air_temperature_c, air_pressure_pa,
  relative_humidity, cloud_fraction, source)``, indexed on ``t_unix_s``.
"""

from __future__ import annotations

import dataclasses
import heapq
import os
import sqlite3
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np

from asvtwin.errors import SourceError
from asvtwin.geo import LocalFrame
from asvtwin.sources.ais.reports import AisReport, AisStatic, ReportBatch
from asvtwin.sources.weather.series import WeatherSample

__all__ = ["HistoryStore", "SqliteHistory", "replay_session"]

_SCHEMA_VERSION = "1"
_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS reports (
    t_unix_s REAL NOT NULL, mmsi INTEGER NOT NULL, msg_type INTEGER NOT NULL,
    lat_deg REAL NOT NULL, lon_deg REAL NOT NULL, sog_m_s REAL, cog_rad REAL,
    heading_rad REAL, rot_rad_s REAL, nav_status INTEGER, station TEXT);
CREATE INDEX IF NOT EXISTS reports_t ON reports (t_unix_s);
CREATE INDEX IF NOT EXISTS reports_mmsi_t ON reports (mmsi, t_unix_s);
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
_REPORT_COLUMNS = ("t_unix_s, mmsi, msg_type, lat_deg, lon_deg, sog_m_s, cog_rad, heading_rad, "
                   "rot_rad_s, nav_status, station")
_STATIC_FIELDS = [f.name for f in dataclasses.fields(AisStatic)]
_WEATHER_FIELDS = ["t_unix_s", "wind_speed_m_s", "wind_from_rad", "air_temperature_c",
                   "air_pressure_pa", "relative_humidity", "cloud_fraction"]


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


class SqliteHistory:
    """The default :class:`HistoryStore`: one SQLite file (or ``":memory:"``).

    Parameters
    ----------
    path : str or os.PathLike
        Database file, created if missing; ``":memory:"`` for a throw-away store.
    synchronous : str
        SQLite ``synchronous`` pragma: ``"NORMAL"`` (default, safe with WAL) or ``"OFF"``.

    Raises
    ------
    SourceError
        If the file cannot be opened or was written by an incompatible schema version.
    """

    def __init__(self, path: str | os.PathLike[str] = ":memory:", *,
                 synchronous: str = "NORMAL") -> None:
        self.path = str(path)
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False)
            if self.path != ":memory:":
                self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute(f"PRAGMA synchronous={synchronous}")
            self._db.executescript(_SCHEMA)
            row = self._db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
            if row is None:
                self._db.execute("INSERT INTO meta VALUES ('schema', ?)", (_SCHEMA_VERSION,))
                self._db.commit()
            elif row[0] != _SCHEMA_VERSION:
                raise SourceError(f"{self.path}: history schema {_SCHEMA_VERSION} expected, "
                                  f"actually: {row[0]}")
        except sqlite3.Error as exc:
            raise SourceError(f"cannot open history database {self.path!r}: {exc}") from exc

    # ------------------------------------------------------------------ writes
    def append_batch(self, batch: ReportBatch) -> int:
        n = 0
        if len(batch):
            # NaN binds as NULL in SQLite: "not available" stays absent
            rows = zip(batch.t_unix_s.tolist(), batch.mmsi.tolist(), batch.msg_type.tolist(),
                       batch.lat_deg.tolist(), batch.lon_deg.tolist(), batch.sog_m_s.tolist(),
                       batch.cog_rad.tolist(), batch.heading_rad.tolist(),
                       batch.rot_rad_s.tolist(), batch.nav_status.tolist(), batch.station)
            self._db.executemany(f"INSERT INTO reports ({_REPORT_COLUMNS}) "
                                 "VALUES (?,?,?,?,?,?,?,?,?,NULLIF(?,-1),?)", rows)
            n += len(batch)
        if batch.static:
            n += self._insert_static(batch.static)
        self._db.commit()
        return n

    def append_reports(self, reports: Sequence[AisReport]) -> int:
        return self.append_batch(ReportBatch.from_reports(list(reports)))

    def _insert_static(self, records: Iterable[AisStatic]) -> int:
        rows = [tuple(getattr(s, f) for f in _STATIC_FIELDS) for s in records]
        self._db.executemany(f"INSERT INTO static ({','.join(_STATIC_FIELDS)}) "
                             f"VALUES ({','.join('?' * len(_STATIC_FIELDS))})", rows)
        return len(rows)

    def append_static(self, records: Sequence[AisStatic]) -> int:
        n = self._insert_static(records)
        self._db.commit()
        return n

    def append_weather(self, samples: Sequence[WeatherSample], *, source: str = "") -> int:
        rows = [tuple(getattr(s, f) for f in _WEATHER_FIELDS) + (source,) for s in samples]
        self._db.executemany(f"INSERT INTO weather ({','.join(_WEATHER_FIELDS)}, source) "
                             "VALUES (?,?,?,?,?,?,?,?)", rows)
        self._db.commit()
        return len(rows)

    # ------------------------------------------------------------------ reads
    def query_reports(self, frame: LocalFrame, *, mmsi: int | None = None,
                      since_unix_s: float | None = None, until_unix_s: float | None = None,
                      limit: int | None = None) -> list[AisReport]:
        return list(self.iter_reports(frame, mmsi=mmsi, since_unix_s=since_unix_s,
                                      until_unix_s=until_unix_s, limit=limit))

    def iter_reports(self, frame: LocalFrame, *, mmsi: int | None = None,
                     since_unix_s: float | None = None, until_unix_s: float | None = None,
                     limit: int | None = None, chunk: int = 4096) -> Iterator[AisReport]:
        """Like :meth:`query_reports` but streamed in chunks (for long sessions)."""
        where, args = _where(mmsi, since_unix_s, until_unix_s)
        sql = f"SELECT {_REPORT_COLUMNS} FROM reports{where} ORDER BY t_unix_s, rowid"
        if limit is not None:
            sql += f" LIMIT {int(limit)}"
        cur = self._db.execute(sql, args)
        while rows := cur.fetchmany(chunk):
            lat = np.array([r[3] for r in rows])
            lon = np.array([r[4] for r in rows])
            north, east = frame.to_ned(lat, lon)
            for r, n, e in zip(rows, north.tolist(), east.tolist()):
                yield AisReport(mmsi=r[1], t_unix_s=r[0], msg_type=r[2], north_m=n, east_m=e,
                                lat_deg=r[3], lon_deg=r[4], sog_m_s=r[5], cog_rad=r[6],
                                heading_rad=r[7], rot_rad_s=r[8], nav_status=r[9],
                                station=r[10])

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
        return int(self._db.execute("SELECT COUNT(*) FROM reports").fetchone()[0])

    def time_span(self) -> tuple[float, float] | None:
        """First and last report time [UNIX s], None when empty."""
        lo, hi = self._db.execute("SELECT MIN(t_unix_s), MAX(t_unix_s) FROM reports").fetchone()
        return None if lo is None else (float(lo), float(hi))

    def close(self) -> None:
        self._db.commit()
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
