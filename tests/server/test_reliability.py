"""The server under abuse, on a real uvicorn socket on 127.0.0.1 (ephemeral port): twenty
clients connecting and dropping at once, a client that stops reading, while the feed's
loop keeps its tick rate (measured: ticks per second with and without the clients)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from asvtwin.server import ServerThread, SyntheticFeed

CLIENTS = Path(__file__).with_name("wsclients.py")


def tick_rate(feed: SyntheticFeed, seconds: float) -> float:
    return tick_stats(feed, seconds)[0]


def tick_stats(feed: SyntheticFeed, seconds: float) -> tuple[float, float]:
    """(ticks per second, longest time without a tick [s]) over ``seconds``, polled every
    5 ms. A loop blocked by its clients shows as a long gap; a machine whose two cores
    are shared with another test worker and the clients' own process slows every tick a
    little and shows as a lower rate with short gaps."""
    t0 = last = time.perf_counter()
    n0 = n = feed.seq
    gap = 0.0
    while (now := time.perf_counter()) - t0 < seconds:
        if feed.seq != n:
            n, last = feed.seq, now
        gap = max(gap, now - last)
        time.sleep(0.005)
    return (feed.seq - n0) / (time.perf_counter() - t0), gap


@pytest.fixture(scope="module")
def server():
    feed = SyntheticFeed(60, seed=5, tick_hz=20.0)
    with ServerThread(feed, send_timeout_s=0.5) as srv:
        time.sleep(0.5)
        yield srv


def test_twenty_clients_connecting_and_dropping_keep_the_tick_rate(server):
    feed = server.feed
    base = tick_rate(feed, 2.0)
    proc = subprocess.Popen([sys.executable, str(CLIENTS), server.url.replace("http", "ws") + "ws",
                             "20", "10", "1.5", "3"], stdout=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not server.hub.clients and time.monotonic() < deadline:
        time.sleep(0.02)  # the clients' interpreter starting
    loaded, gap = tick_stats(feed, 4.0)
    out, _ = proc.communicate(timeout=120)
    cycles = [json.loads(line) for line in out.splitlines()]
    assert len(cycles) == 3
    for c in cycles:
        assert c["ok"] == 20, c["errors"]
        assert min(c["messages"]) >= 1  # every client got snapshots
    # the loop kept ticking (20 Hz nominal, a tick every 50 ms) with clients coming and
    # going: never 0.25 s (5 ticks) without one, and the rate within 25 % of the rate
    # without clients. (0.9 x the rate failed once in CI at 16.2 Hz against 20.0 Hz: the
    # other test worker and the 20 clients' process share the two cores with this one.)
    assert base >= 0.9 * 20.0, f"baseline tick rate {base:.1f} Hz (machine overloaded?)"
    assert gap < 0.25, f"{gap:.2f} s without a tick while clients came and went"
    assert loaded >= 0.75 * base, f"tick rate {loaded:.1f} Hz with clients vs {base:.1f} Hz without"
    deadline = time.monotonic() + 10
    while server.hub.clients and time.monotonic() < deadline:
        time.sleep(0.1)
    stats = httpx.get(server.url + "api/stats").json()
    assert stats["clients"] == 0  # every dropped client was cleaned up
    assert stats["counters"]["ws_connected"] >= 60


def _stalled_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake and then never reads."""
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.sendall(b"GET /ws?rate_hz=60 HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\n"
              b"Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
              b"Sec-WebSocket-Version: 13\r\n\r\n" % port)
    assert b"101" in s.recv(200)
    return s


def test_a_client_that_stops_reading_is_dropped_and_slows_no_one(server):
    feed, hub = server.feed, server.hub
    before = hub.counters["ws_send_timeouts"]
    stalled = _stalled_client(server.port)
    proc = subprocess.Popen([sys.executable, str(CLIENTS), server.url.replace("http", "ws") + "ws",
                             "1", "10", "6", "1"], stdout=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while len(hub.clients) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    rate = tick_rate(feed, 4.0)
    out, _ = proc.communicate(timeout=60)
    healthy = json.loads(out.splitlines()[0])
    try:
        assert hub.counters["ws_send_timeouts"] > before, "the stalled client was never dropped"
        assert rate >= 0.9 * 20.0, f"tick rate {rate:.1f} Hz with a stalled client"
        # the reading client got its 10 Hz (>= 80 % of 6 s x 10 Hz, first second included)
        assert healthy["messages"][0] >= 48, healthy
    finally:
        stalled.close()
