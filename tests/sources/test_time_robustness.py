"""Bad clocks (issue items 4-6): a corrupt tag time must not hang or race a replay, one
future-dated report must not move the clock or wipe the picture, a lagging feed is said."""

from __future__ import annotations

import asyncio
import contextlib
import json
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from asvtwin.cli import main
from asvtwin.sources.ais import (
    AisPipeline,
    Backoff,
    FileReplaySource,
    TargetRegistry,
    TcpAisSource,
    encode_report,
)
from asvtwin.sources.ais.source import Pacer

from .conftest import LAT, LON, T0, report, tagged


def _log(tmp_path, n: int = 21, *, bad: dict[int, str] | None = None, name: str = "a.nmea",
         mmsis: int = 3) -> str:
    """n seconds of reports from ``mmsis`` vessels, one line a second; ``bad`` replaces the
    ``c:`` value of chosen lines (the tag checksum recomputed, so it is valid)."""
    lines = []
    for k in range(n):
        r = report(mmsi=257_000_001 + k % mmsis, t=T0 + k, lat=LAT + 1e-4 * k, lon=LON)
        line = tagged(encode_report(r), T0 + k)
        if bad and k in bad:
            body = f"s:2573555,c:{bad[k]}"
            cs = 0
            for ch in body.encode():
                cs ^= ch
            line = f"\\{body}*{cs:02X}\\" + line.split("\\")[-1]
        lines.append(line)
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return str(path)


async def _drain(src: FileReplaySource, timeout_s: float) -> tuple[int, float]:
    t0 = time.perf_counter()

    async def run() -> int:
        return sum([len(b) async for b in src.batches()])

    n = await asyncio.wait_for(run(), timeout_s)
    return n, time.perf_counter() - t0


@pytest.mark.parametrize("bad", ["inf", "nan", "1e30", str(int(T0) + 5 * 86400),
                                 str(int(T0) - 3 * 86400)])
def test_a_corrupt_tag_time_with_a_valid_checksum_does_not_hang_the_replay(tmp_path,
                                                                             bad) -> None:
    """Before: c:inf slept for ever, a flipped digit planned days of sleep."""
    path = _log(tmp_path, bad={10: bad})
    src = FileReplaySource(path, speed=20.0)  # 20 s of log at 20x: ~1 s
    n, wall = asyncio.run(_drain(src, timeout_s=10.0))
    assert 0.7 <= wall <= 3.0
    assert n == 20  # every line but the corrupt one (rejected by the pipeline)
    assert src.pacer.gaps == 0 and src.pacer.last == T0 + 20


def test_loop_passes_are_all_accepted_despite_a_corrupt_time(tmp_path) -> None:
    """Before: the loop span came from the corrupt time, and every later pass was rejected."""
    path = _log(tmp_path, bad={7: str(int(T0) + 7 * 86400)})
    src = FileReplaySource(path, speed=None, loop=True, loop_gap_s=5.0)  # shift >= dedup
    per_pass = [0, 0, 0]

    async def run() -> None:
        async for b in src.batches():  # a batch of pass k is handed out while passes == k
            if src.passes == 3:
                return
            per_pass[src.passes] += len(b)

    asyncio.run(asyncio.wait_for(run(), 10.0))
    assert per_pass == [20, 20, 20]
    assert src.span_s == pytest.approx(20.0)  # 0..20 s of the log, not 7 days


def test_pacer_caps_a_confirmed_gap_and_ignores_a_lone_jump_back() -> None:
    p = Pacer(1.0, min_sleep_s=0.0, max_step_s=60.0)
    assert [p.delay(t) for t in (0.0, 1.0, 3600.0, 3601.0, 3602.0)] == [0.0, 1.0, 0.0, 60.0, 1.0]
    assert p.gaps == 1 and (p.first, p.last) == (0.0, 3602.0)
    assert [p.delay(t) for t in (5.0, 3603.0)] == [0.0, 1.0]  # a lone old time: ignored
    assert p.outliers == 1


def test_one_future_dated_report_neither_moves_the_clock_nor_wipes_the_picture() -> None:
    """Before: a single valid line dated +3 h moved the clock, every other target was
    evicted, and that vessel's true reports were then rejected as time_backwards."""
    p = AisPipeline()
    reg = TargetRegistry(epoch_unix_s=T0)
    lines = [tagged(encode_report(report(mmsi=257_000_001 + k, t=T0 + k)), T0 + k)
             for k in range(40)]
    liar = 257_000_005
    lines.insert(20, tagged(encode_report(report(mmsi=liar, t=T0 + 10_800)), T0 + 10_800))
    lines.append(tagged(encode_report(report(mmsi=liar, t=T0 + 41)), T0 + 41))
    for k in range(0, len(lines), 8):
        reg.update_batch(p.feed_batch(lines[k:k + 8]))
    assert p.stats.errors == {"time_future": 1}
    assert p.latest_time_unix_s == T0 + 41 and p.stream_time_unix_s <= T0 + 41
    snap = reg.extrapolate(p.stream_time_unix_s - T0)
    assert len(snap) == 40 and liar in snap.mmsi.tolist()  # nobody evicted, the liar kept


def test_the_first_report_of_a_stream_is_judged_against_the_lines_after_it() -> None:
    """Before: a stream's first report was unbounded (dated 2099, accepted)."""
    lines = [tagged(encode_report(report(t=4_070_908_800.0)), 4_070_908_800.0)]  # 2099
    lines += [tagged(encode_report(report(mmsi=257_000_002 + k, t=T0 + k)), T0 + k)
              for k in range(10)]
    p = AisPipeline()
    batch = p.feed_batch(lines)
    assert p.stats.errors == {"time_future": 1} and len(batch) == 10


def test_duration_of_a_replay_counts_stream_time_of_reports_outside_the_scene(tmp_path,
                                                                            capsys) -> None:
    """Before: with no in-scene report in the first batch, --duration 60 stopped after a
    few seconds of stream time (the clock started at 0)."""
    lines = [tagged(encode_report(report(mmsi=257_400_000 + k % 5, t=T0 + k // 5, lat=69.0,
                                         lon=16.0)), T0 + k // 5) for k in range(1500)]
    lines += [tagged(encode_report(report(mmsi=257_000_001 + k % 5, t=T0 + 300 + k // 5)),
                     T0 + 300 + k // 5) for k in range(1500)]
    path = tmp_path / "far.nmea"
    path.write_text("\n".join(lines) + "\n")
    assert main(["ais", "listen", str(path), "--speed", "0", "--duration", "450",
                 "--no-live"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    # 450 s of stream time: 300 s out of the scene, then ~150 s (5 reports a second) in it,
    # give or take one batch of 512 lines (~100 s)
    n = int(out.split("reports ")[1].split()[0])
    assert 250 <= n <= 1300, out


@contextlib.contextmanager
def _serve(lines: list[str], hold_s: float = 1.5) -> Iterator[int]:
    """A TCP server on 127.0.0.1 (ephemeral port) that writes ``lines`` to each client, keeps
    the connection ``hold_s`` and closes it; runs in a thread inside the ``with``. Yields the
    port."""
    ready, stop, port = threading.Event(), threading.Event(), {}

    def server() -> None:
        async def handle(reader, writer):
            writer.write(("\n".join(lines) + "\n").encode())
            await writer.drain()
            await asyncio.sleep(hold_s)
            writer.close()

        async def run():
            srv = await asyncio.start_server(handle, "127.0.0.1", 0)
            port["p"] = srv.sockets[0].getsockname()[1]
            ready.set()
            while not stop.is_set():
                await asyncio.sleep(0.05)
            srv.close()

        asyncio.run(run())

    thread = threading.Thread(target=server, daemon=True)
    thread.start()
    assert ready.wait(10.0)
    try:
        yield port["p"]
    finally:
        stop.set()
        thread.join(10.0)


#: Two years behind the scenario time T0 (the receive clock is the machine's, later still).
OLD = T0 - 2 * 365 * 86400.0


def _lagging_lines() -> list[str]:
    """Five vessels in the fjord, national-feed format (``\\s:...,c:...*hh\\!BSVDM...``),
    tag times two years old."""
    return [tagged(encode_report(report(mmsi=257_000_001 + k, t=OLD + k)), OLD + k)
            for k in range(5)]


def test_a_lagging_feed_clock_is_said_and_the_table_is_not_empty(capsys, tmp_path) -> None:
    """Before: tag times years old over a live TCP feed were stored but the table was empty
    (every target evicted against the receive clock), with no word of why."""
    db = tmp_path / "lag.sqlite"
    with _serve(_lagging_lines()) as port:
        t_listen = time.time()
        assert main(["ais", "listen", f"tcp://127.0.0.1:{port}", "--duration", "1.0",
                     "--no-live", "--db", str(db)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    # counted: all five reports kept, each counted as the notice, none rejected
    assert "feed_clock_lags 5" in out and "reports 5 " in out, out
    assert "time_future" not in out and "time_backwards" not in out
    # said: by how much the feed lags, and at which time the table is shown
    days = float(out.split("lag the receive clock by ")[1].split(" days")[0])
    assert abs(days - (t_listen - (OLD + 1)) / 86400.0) < 0.1, out  # stream time: OLD + 1
    assert "the table is shown at the feed's time" in out
    for k in range(5):
        assert str(257_000_001 + k) in out  # shown at the feed's time, not evicted
    assert "recording: 5 reports" in out  # and stored


def test_a_lagging_live_tcp_feed_is_delivered_counted_and_its_lag_measured() -> None:
    """The API half: a TcpAisSource with the receive clock hands out every report of the
    lagging feed, counts each as ``feed_clock_lags`` and measures the lag in its status."""

    async def run(src: TcpAisSource) -> list[int]:
        got: list[int] = []
        async for batch in src.batches():
            got += batch.mmsi.tolist()
        return got

    with _serve(_lagging_lines(), hold_s=0.3) as port:
        src = TcpAisSource("127.0.0.1", port, clock=time.time, max_reconnects=0,
                           backoff=Backoff(rng=np.random.default_rng(0), initial_s=0.05,
                                           max_s=0.05))
        t0 = time.time()
        mmsis = asyncio.run(asyncio.wait_for(run(src), 10.0))
    st = src.status().stats
    assert sorted(mmsis) == [257_000_001 + k for k in range(5)]
    assert st.notices == {"feed_clock_lags": 5}
    assert set(st.errors) <= {"disconnected"}
    assert st.clock_lag_s is not None
    assert abs(st.clock_lag_s - (t0 - (OLD + 1))) < 15.0  # 2 years + (now - T0), to seconds


def test_stats_json_reports_stream_time(tmp_path, capsys) -> None:
    assert main(["ais", "stats", _log(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["stream_time_unix_s"] >= T0 + 15
