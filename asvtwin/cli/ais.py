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
    p.add_argument("source", help="tcp://HOST:PORT | udp://:PORT | FILE | synthetic[:SEED]")
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
                       "time span and errors by kind.")
    s.add_argument("file", help="NMEA log (tag blocks optional)")
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
    from rich.table import Table

    from asvtwin.units import m_s_to_knots

    table = Table(title=title, title_justify="left")
    for col in ("MMSI", "Name", "Type", "North m", "East m", "SOG kn", "COG", "HDG", "Age s",
                "State"):
        table.add_column(col, justify="right" if col not in ("Name", "State") else "left")
    order = sorted(range(len(snapshot)), key=lambda i: int(snapshot.mmsi[i]))[:rows]
    for i in order:
        st = snapshot.static[i]
        vn, ve = snapshot.velocity_m_s[i]
        known = bool(snapshot.velocity_known[i])
        table.add_row(
            str(int(snapshot.mmsi[i])), (st.name if st and st.name else "-")[:20],
            str(st.ship_type) if st and st.ship_type else "-",
            f"{snapshot.position_m[i, 0]:9.0f}", f"{snapshot.position_m[i, 1]:9.0f}",
            f"{float(m_s_to_knots(math.hypot(vn, ve))):5.1f}" if known else "-",
            _deg(math.atan2(ve, vn)) if known else "-", _deg(float(snapshot.heading_rad[i])),
            f"{snapshot.age_s[i]:6.0f}", "[red]stale[/red]" if snapshot.stale[i] else "ok")
    return table


def _footer(source: Any) -> str:
    st = source.status()
    errors = ", ".join(f"{k} {v}" for k, v in sorted(st.stats.errors.items())) or "none"
    return (f"lines {st.stats.lines}  reports {st.stats.reports}  static {st.stats.statics}  "
            f"connected {st.connected}  reconnects {st.reconnects}  errors: {errors}")


def _listen(args: argparse.Namespace) -> int:
    import asyncio
    import time

    from rich.console import Group
    from rich.live import Live
    from rich.text import Text

    from asvtwin.errors import AsvTwinError
    from asvtwin.sources.ais import TargetRegistry, open_ais_source
    from asvtwin.sources.history import SqliteHistory

    console = _console()
    live_feed = args.source.startswith(("tcp://", "udp://"))
    try:
        source = open_ais_source(args.source, clock=time.time,
                                 speed=None if args.speed <= 0 else args.speed, loop=args.loop,
                                 seed=args.seed)
        store = SqliteHistory(args.db) if args.db else None
    except AsvTwinError:
        raise  # one line on stderr, exit 2: asvtwin.cli.main
    registry = TargetRegistry(epoch_unix_s=0.0)  # times shown are UNIX seconds

    def now() -> float:
        if live_feed:
            return time.time()
        return source.pipeline.latest_time_unix_s or 0.0

    def view() -> Any:
        t = now()
        title = f"AIS targets at {_iso(t)} ({args.source})"
        return Group(_table(registry.extrapolate(t), title, args.rows), Text(_footer(source)))

    async def consume() -> None:
        t_start: float | None = None
        async for batch in source.batches():
            registry.update_batch(batch)
            if store is not None:
                store.append_batch(batch)
            t = now()
            t_start = t if t_start is None else t_start
            if args.duration is not None and not live_feed and t - t_start >= args.duration:
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
        if store is not None:
            store.close()
    if args.no_live:
        console.print(view())
    return 0


def _stats(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from rich.console import Console
    from rich.table import Table

    from asvtwin.sources.ais import AisPipeline

    path = Path(args.file)
    if not path.is_file():
        raise FileNotFoundError(2, "not a readable file", args.file)
    pipeline = AisPipeline()
    mmsis: set[int] = set()
    t_lo, t_hi = math.inf, -math.inf
    chunk: list[bytes] = []

    def flush() -> None:
        nonlocal t_lo, t_hi
        batch = pipeline.feed_batch(chunk)
        mmsis.update(batch.mmsi.tolist())
        mmsis.update(s.mmsi for s in batch.static)
        if len(batch):
            t_lo = min(t_lo, float(batch.t_unix_s.min()))
            t_hi = max(t_hi, float(batch.t_unix_s.max()))
        chunk.clear()

    with path.open("rb") as fh:
        for line in fh:
            chunk.append(line)
            if len(chunk) >= 4096:
                flush()
    flush()
    st = pipeline.stats
    summary: dict[str, Any] = {"file": str(path), **st.as_dict(), "mmsis": len(mmsis),
               "time_span": None if t_lo > t_hi else {
                   "first": _iso(t_lo), "last": _iso(t_hi), "seconds": t_hi - t_lo}}
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    console = Console()
    console.print(f"[bold]{path}[/bold]: {st.lines} lines, {st.reports} position reports, "
                  f"{st.statics} static records, {len(mmsis)} MMSIs")
    if summary["time_span"]:
        span = summary["time_span"]
        console.print(f"time span {span['first']} .. {span['last']} ({span['seconds']:.0f} s)")
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
    console.print(t1, t2)
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

    from rich.console import Console
    from rich.table import Table

    from asvtwin.geo import default_scene
    from asvtwin.sources.history import SqliteHistory
    from asvtwin.units import m_s_to_knots

    if not Path(args.db).is_file():
        raise FileNotFoundError(2, "history database does not exist", args.db)
    from asvtwin.errors import AsvTwinError

    try:
        with SqliteHistory(args.db, migrate=args.migrate) as store:
            reports = store.query_reports(default_scene().frame, mmsi=args.mmsi,
                                          since_unix_s=args.since, until_unix_s=args.until,
                                          limit=args.limit)
    except AsvTwinError:
        raise  # one line on stderr, exit 2: asvtwin.cli.main
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
