"""``asvtwin ais``: listen to an AIS feed, summarise a log, query the history.

- ``asvtwin ais listen SOURCE`` with SOURCE ``tcp://HOST:PORT``, ``udp://:PORT``, an NMEA log
  file or ``synthetic`` (simulated fjord traffic): a live target table (rich), optionally
  recording into the history database (``--db``);
- ``asvtwin ais stats FILE``: messages by type, MMSIs, time span, errors by kind;
- ``asvtwin ais history --db PATH [--mmsi M] [--since T] [--until T]``: recorded reports.

This module is the edge where the wall clock lives: it passes ``time.time`` to the sources.
"""

from __future__ import annotations

import argparse
import math
from datetime import UTC, datetime
from typing import Any

__all__ = ["parse_time", "register"]


def parse_time(text: str) -> float:
    """ISO 8601 (``2024-11-20T11:00Z``, UTC when no zone) or UNIX seconds -> UNIX seconds."""
    try:
        return float(text)
    except ValueError:
        pass
    try:
        dt = datetime.fromisoformat(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(
            f"time must be ISO 8601 (2024-11-20T11:00Z) or UNIX seconds, actually: {text!r}"
        ) from exc
    return (dt if dt.tzinfo else dt.replace(tzinfo=UTC)).timestamp()


def _iso(t: float | None) -> str:
    if t is None:
        return "-"
    return datetime.fromtimestamp(t, tz=UTC).strftime("%Y-%m-%d %H:%M:%SZ")


def _deg(a: float | None) -> str:
    return "-" if a is None or math.isnan(a) else f"{math.degrees(a) % 360.0:5.1f}"


def register(subparsers: Any) -> None:
    """Add ``ais listen``, ``ais stats`` and ``ais history`` to the ``asvtwin`` command."""
    ais = subparsers.add_parser("ais", help="AIS: listen to a feed, summarise logs, history",
                                description=__doc__.split("\n\n")[0])
    sub = ais.add_subparsers(title="ais commands", metavar="COMMAND")
    ais.set_defaults(func=lambda args: (ais.print_help(), 2)[1])

    p = sub.add_parser("listen", help="live target table of a feed, log or synthetic traffic",
                       description="Print a live table of the AIS targets of SOURCE: "
                       "tcp://HOST:PORT, udp://:PORT, an NMEA log file, or 'synthetic'.")
    p.add_argument("source", help="tcp://HOST:PORT | udp://:PORT | FILE | synthetic[:SEED]; "
                   "lines without a tag-block time are stamped with the receive clock (said "
                   "in the counts)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="replay/synthetic speed factor (1 = real time, 0 = as fast as possible)")
    p.add_argument("--loop", action="store_true", help="loop a log file")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds of stream time (default: run until Ctrl-C)")
    p.add_argument("--refresh", type=float, default=1.0, metavar="S",
                   help="table refresh period in wall seconds")
    p.add_argument("--db", default=None, help="record accepted reports in this SQLite file")
    p.add_argument("--seed", type=int, default=0, help="seed of jitter / synthetic traffic")
    p.add_argument("--rows", type=int, default=40, help="most table rows shown")
    p.add_argument("--no-live", action="store_true",
                   help="no live display: print the final table and counts only")
    p.set_defaults(func=_listen)

    s = sub.add_parser("stats", help="summarise an NMEA log",
                       description="Decode an NMEA log and print messages by type, MMSIs, "
                       "time span, rejections and notes by kind, and the share inside the "
                       "Trondheim scene. Lines without tag blocks are counted too.")
    s.add_argument("file", help="NMEA log (tag blocks optional)")
    where = s.add_mutually_exclusive_group()
    where.add_argument("--no-bounds", dest="bounds", action="store_false", default=False,
                       help="count every message wherever it is (default); the Trondheim "
                            "scene's share is shown as a separate count")
    where.add_argument("--scene", dest="bounds", action="store_true",
                       help="apply the Trondheim scene's box as the twin does (reports outside "
                            "it are rejected as outside_scene)")
    s.add_argument("--json", action="store_true", help="print JSON instead of tables")
    s.set_defaults(func=_stats)

    h = sub.add_parser("history", help="query recorded reports",
                       description="List reports recorded by 'asvtwin ais listen --db'.")
    h.add_argument("--db", required=True, help="history SQLite file")
    h.add_argument("--mmsi", type=int, default=None)
    h.add_argument("--since", type=parse_time, default=None, help="ISO 8601 or UNIX s")
    h.add_argument("--until", type=parse_time, default=None, help="ISO 8601 or UNIX s")
    h.add_argument("--limit", type=int, default=100)
    h.add_argument("--json", action="store_true", help="print JSON lines")
    h.add_argument("--migrate", action="store_true",
                   help="convert a database of an older schema in place (one transaction)")
    h.set_defaults(func=_history)


def _table(snapshot: Any, title: str, rows: int) -> Any:
    """The target table: every value as reported, "-" where AIS says "not available"."""
    from rich.table import Table

    from asvtwin.units import m_s_to_knots

    table = Table(title=title, title_justify="left")
    for col in ("MMSI", "Name", "Type", "North m", "East m", "SOG kn", "COG", "HDG", "Age s",
                "State"):
        table.add_column(col, justify="right" if col not in ("Name", "State") else "left")
    order = sorted(range(len(snapshot)), key=lambda i: int(snapshot.mmsi[i]))[:rows]
    for i in order:
        st = snapshot.static[i]
        sog = float(snapshot.sog_m_s[i])
        table.add_row(
            str(int(snapshot.mmsi[i])), (st.name if st and st.name else "-")[:20],
            str(st.ship_type) if st and st.ship_type else "-",
            f"{snapshot.position_m[i, 0]:9.0f}", f"{snapshot.position_m[i, 1]:9.0f}",
            "-" if math.isnan(sog) else f"{float(m_s_to_knots(sog)):5.1f}",
            _deg(float(snapshot.cog_rad[i])), _deg(float(snapshot.true_heading_rad[i])),
            f"{snapshot.age_s[i]:6.0f}", "[red]stale[/red]" if snapshot.stale[i] else "ok")
    return table


def _footer(source: Any, recorder: Any = None, clock_note: str = "") -> str:
    """Counts under the table: lines, reports, rejections and notices by kind, recording."""
    st = source.status()
    errors = ", ".join(f"{k} {v}" for k, v in sorted(st.stats.errors.items())) or "none"
    text = (f"lines {st.stats.lines}  reports {st.stats.reports}  static {st.stats.statics}  "
            f"connected {st.connected}  reconnects {st.reconnects}  rejected: {errors}")
    if st.stats.notices:
        text += "\naccepted with notes: " + ", ".join(
            f"{k} {v}" + _NOTICE_MEANING.get(k, "") for k, v in sorted(st.stats.notices.items()))
    if clock_note:
        text += "\n" + clock_note
    if recorder is not None:
        r = recorder.status()
        text += (f"\nrecording: {r.recorded_reports} reports, {r.recorded_static} static"
                 + (f"; NOT recorded {r.lost_reports} reports, {r.lost_static} static"
                    if r.lost_reports or r.lost_static else "")
                 + (f"; SUSPENDED after {r.failures} failure(s): {r.last_error}"
                    if r.suspended else ""))
    return text


_NOTICE_MEANING = {
    "receive_time": " (lines without a tag-block time, stamped with the receive clock)",
    "tag_checksum_c_only": " (group tag blocks checksummed over c: alone, as the national "
                           "feed writes them)",
    "resynced": " (garbage before a sentence skipped)",
    "feed_clock_lags": " (report times far behind the receive clock)",
}


def _listen(args: argparse.Namespace) -> int:
    import asyncio
    import time

    from rich.console import Group
    from rich.live import Live
    from rich.text import Text

    from asvtwin.sources.ais import TargetRegistry, open_ais_source
    from asvtwin.sources.history import SqliteHistory
    from asvtwin.sources.recorder import HistoryRecorder

    console = _console()
    live_feed = args.source.startswith(("tcp://", "udp://"))
    # errors (AsvTwinError, OSError) end in one line on stderr, exit 2: asvtwin.cli.main
    source = open_ais_source(args.source, clock=time.time,
                             speed=None if args.speed <= 0 else args.speed, loop=args.loop,
                             seed=args.seed)
    recorder = HistoryRecorder(SqliteHistory(args.db), clock=time.monotonic) if args.db else None
    registry = TargetRegistry(epoch_unix_s=0.0)  # times shown are UNIX seconds
    note = {"clock": ""}

    def now() -> float:
        """The table's time: the receive clock for a live feed, unless the feed's own clock
        lags far behind it (then the feed's time, said in the footer); the robust stream
        time of a replay."""
        stream_t = source.pipeline.stream_time_unix_s
        if not live_feed:
            return stream_t if stream_t is not None else 0.0
        wall = time.time()
        if stream_t is not None and wall - stream_t > registry.evict_after_s:
            note["clock"] = (f"the feed's tag times lag the receive clock by "
                             f"{(wall - stream_t) / 86400.0:.1f} days: the table is shown at "
                             f"the feed's time {_iso(stream_t)}")
            return stream_t
        note["clock"] = ""
        return wall

    def view() -> Any:
        t = now()
        title = f"AIS targets at {_iso(t)} ({args.source})"
        return Group(_table(registry.extrapolate(t), title, args.rows),
                     Text(_footer(source, recorder, note["clock"])))

    async def consume() -> None:
        t_start: float | None = None
        async for batch in source.batches():
            registry.update_batch(batch)
            if recorder is not None:
                recorder.submit(batch)  # written by a worker thread, never on this loop
            if args.duration is None or live_feed:
                continue
            t = source.pipeline.stream_time_unix_s  # every timed line counts, in scene or not
            if t is not None:
                if t_start is None:  # the log's first time, if the source knows it
                    t_start = getattr(getattr(source, "pacer", None), "first", None) or t
                if t - t_start >= args.duration:
                    return

    async def run() -> None:
        task = asyncio.create_task(consume())
        loop = asyncio.get_running_loop()
        # a live feed runs --duration wall seconds (it may be silent); a replay, stream seconds
        deadline = loop.time() + args.duration if live_feed and args.duration else math.inf
        live = None if args.no_live else Live(view(), console=console, auto_refresh=False)
        if live is not None:
            live.start()
        try:
            while not task.done() and loop.time() < deadline:
                await asyncio.wait({task}, timeout=min(args.refresh, deadline - loop.time()))
                if live is not None:
                    live.update(view(), refresh=True)
        finally:
            if live is not None:
                live.stop()
        if not task.done():
            task.cancel()
        try:
            await task
        except asyncio.CancelledError:
            pass

    try:
        asyncio.run(run())
    except KeyboardInterrupt:
        pass
    finally:
        if recorder is not None:
            recorder.close()
    if args.no_live:
        console.print(view())
    return 0


def _stats(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from rich.console import Console
    from rich.table import Table

    from asvtwin.geo import default_scene
    from asvtwin.sources.ais import AisPipeline

    path = Path(args.file)
    if not path.is_file():
        raise FileNotFoundError(2, "not a readable file", args.file)
    scene = default_scene()
    b = scene.bounds
    # a summary counts the whole log: no scene box (unless --scene), no time required
    pipeline = AisPipeline(scene, bounds=args.bounds, require_time=False, census=True)
    in_scene = 0
    chunk: list[bytes] = []

    def flush() -> None:
        nonlocal in_scene
        batch = pipeline.feed_batch(chunk)
        in_scene += int(((batch.lat_deg >= b.lat_min_deg) & (batch.lat_deg <= b.lat_max_deg)
                         & (batch.lon_deg >= b.lon_min_deg)
                         & (batch.lon_deg <= b.lon_max_deg)).sum())
        chunk.clear()

    with path.open("rb") as fh:
        for line in fh:
            chunk.append(line)
            if len(chunk) >= 4096:
                flush()
    flush()
    pipeline.finish()
    st = pipeline.stats
    census = pipeline.census
    assert census is not None
    t_lo, t_hi = census.t_first_unix_s, census.t_last_unix_s
    scene_box = (f"lat {b.lat_min_deg}..{b.lat_max_deg}, lon {b.lon_min_deg}..{b.lon_max_deg}")
    summary: dict[str, Any] = {
        "file": str(path), **st.as_dict(), "mmsis": len(census.mmsis),
        "time_span": None if t_lo is None or t_hi is None else {
            "first": _iso(t_lo), "last": _iso(t_hi), "seconds": t_hi - t_lo},
        "timed_lines": census.timed_lines, "untimed_lines": census.untimed_lines,
        "scene": {"name": "trondheim", "box": scene_box, "filter_applied": args.bounds,
                  "position_reports_in_scene": in_scene,
                  "position_reports_outside_scene": (st.reports - in_scene) if not args.bounds
                  else st.errors.get("outside_scene", 0)},
    }
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    console = Console()
    console.print(f"[bold]{path}[/bold]: {st.lines} lines, {sum(st.messages_by_type.values())} "
                  f"messages, {st.reports} position reports, {st.statics} static records, "
                  f"{len(census.mmsis)} MMSIs (all message types)")
    if summary["time_span"]:
        span = summary["time_span"]
        console.print(f"time span {span['first']} .. {span['last']} ({span['seconds']:.0f} s, "
                      f"from the tag blocks of {census.timed_lines} lines)")
    if census.untimed_lines:
        console.print(f"{census.untimed_lines} lines without a tag-block time (counted; their "
                      "reports carry no time)")
    sc = summary["scene"]
    console.print(f"scene trondheim ({scene_box}): {sc['position_reports_in_scene']} position "
                  f"reports inside, {sc['position_reports_outside_scene']} outside"
                  + (" (rejected: --scene)" if args.bounds else " (counted above; --scene "
                     "applies the filter as the twin does)"))
    t1 = Table(title="messages by type")
    t1.add_column("type", justify="right")
    t1.add_column("count", justify="right")
    for k, v in sorted(st.messages_by_type.items()):
        t1.add_row(str(k), str(v))
    t2 = Table(title="rejected, by kind")
    t2.add_column("kind")
    t2.add_column("count", justify="right")
    for kind, n in sorted(st.errors.items()):
        t2.add_row(kind, str(n))
    t3 = Table(title="accepted with notes, by kind")
    t3.add_column("kind")
    t3.add_column("count", justify="right")
    for kind, n in sorted(st.notices.items()):
        t3.add_row(kind, str(n))
    console.print(t1, t2, t3)
    return 0


def _console():
    """A console; when output is not a terminal (a pipe, a log), wide enough for the
    target table instead of the 80-column default."""
    from rich.console import Console

    c = Console()
    return c if c.is_terminal else Console(width=140)


def _history(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from rich.table import Table

    from asvtwin.geo import default_scene
    from asvtwin.sources.history import SqliteHistory
    from asvtwin.units import m_s_to_knots

    if not Path(args.db).is_file():
        raise FileNotFoundError(2, "history database does not exist", args.db)
    # queries open the file read-only (nothing written, works on read-only media); errors
    # end in one line on stderr, exit 2: asvtwin.cli.main
    with SqliteHistory(args.db, migrate=args.migrate, readonly=not args.migrate) as store:
        reports = store.query_reports(default_scene().frame, mmsi=args.mmsi,
                                      since_unix_s=args.since, until_unix_s=args.until,
                                      limit=args.limit)
    if args.json:
        for r in reports:
            print(json.dumps({k: getattr(r, k) for k in r.__slots__}))
        return 0
    table = Table(title=f"{len(reports)} reports from {args.db}")
    for col in ("time (UTC)", "MMSI", "lat", "lon", "SOG kn", "COG", "HDG", "station"):
        table.add_column(col)
    for r in reports:
        table.add_row(_iso(r.t_unix_s), str(r.mmsi), f"{r.lat_deg:.5f}", f"{r.lon_deg:.5f}",
                      "-" if r.sog_m_s is None else f"{float(m_s_to_knots(r.sog_m_s)):.1f}",
                      _deg(r.cog_rad), _deg(r.heading_rad), r.station or "-")
    _console().print(table)
    return 0
