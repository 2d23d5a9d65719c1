"""TCP and UDP sources against local servers on 127.0.0.1 (never any other host)."""

from __future__ import annotations

import asyncio
import math
import socket

import numpy as np
import pytest

from asvtwin.errors import ParameterError
from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    Backoff,
    SyntheticTraffic,
    TargetRegistry,
    TcpAisSource,
    UdpAisSource,
)

from .conftest import T0

HOST = "127.0.0.1"


def synthetic(seconds: float, seed: int = 2):
    return list(SyntheticTraffic(rng=np.random.default_rng(seed), start_unix_s=T0).run(seconds))


def fast_backoff() -> Backoff:
    return Backoff(rng=np.random.default_rng(0), initial_s=0.01, max_s=0.05)


async def serve(script):
    """A TCP server on 127.0.0.1 whose k-th connection runs ``script[k](writer)``."""
    calls = {"n": 0}

    async def handle(reader, writer):
        k = calls["n"]
        calls["n"] += 1
        if k < len(script):
            await script[k](writer)
        writer.close()

    server = await asyncio.start_server(handle, HOST, 0)
    return server, server.sockets[0].getsockname()[1], calls


def test_backoff_doubles_with_bounded_jitter_and_resets() -> None:
    b = Backoff(rng=np.random.default_rng(1), initial_s=1.0, max_s=8.0, jitter=0.5)
    d = [b.next_delay() for _ in range(6)]
    for got, nominal in zip(d, [1, 2, 4, 8, 8, 8]):
        assert 0.5 * nominal <= got <= nominal
    assert len(set(d)) == 6  # jittered
    b.reset()
    assert b.next_delay() <= 1.0
    again = Backoff(rng=np.random.default_rng(1), initial_s=1.0, max_s=8.0, jitter=0.5)
    assert [again.next_delay() for _ in range(6)] == d  # seeded
    with pytest.raises(ParameterError, match="factor > 1"):
        Backoff(rng=np.random.default_rng(), factor=1.0)


def test_tcp_round_trip_ground_truth_to_registry() -> None:
    items = synthetic(600.0)
    payload = ("\r\n".join(x.line for x in items) + "\r\n").encode()

    async def send_all(writer):
        for i in range(0, len(payload), 1500):  # arbitrary segment boundaries
            writer.write(payload[i:i + 1500])
            await writer.drain()

    async def main():
        server, port, _ = await serve([send_all])
        src = TcpAisSource(HOST, port, backoff=fast_backoff(), max_reconnects=0)
        reg = TargetRegistry(epoch_unix_s=T0, rot_horizon_s=0.0)
        async with server:
            async for batch in src.batches():
                reg.update_batch(batch)
        return src, reg

    src, reg = asyncio.run(main())
    truth = {x.truth.mmsi: x.truth for x in items if isinstance(x.truth, AisReport)}
    t_end = max(t.t_unix_s for t in truth.values()) - T0
    snap = reg.extrapolate(t_end)
    assert src.status().stats.errors == {"disconnected": 1}
    assert src.status().stats.reports == sum(isinstance(x.truth, AisReport) for x in items)
    assert sorted(snap.mmsi.tolist()) == sorted(truth)
    for i, m in enumerate(snap.mmsi.tolist()):
        t = truth[m]
        age = t_end - (t.t_unix_s - T0)
        assert snap.age_s[i] == pytest.approx(age)
        # the registry holds the last truth, dead-reckoned straight (ROT off) for its age
        expected = (t.north_m + t.sog_m_s * age * math.cos(t.cog_rad),
                    t.east_m + t.sog_m_s * age * math.sin(t.cog_rad))
        tol = 0.25 + age * (0.05 * 1852 / 3600 + t.sog_m_s * math.radians(0.05))
        assert math.dist(snap.position_m[i], expected) <= tol
        assert reg.static(m) is not None


def test_reconnect_after_the_server_drops_mid_message() -> None:
    items = synthetic(300.0, seed=4)
    lines = [x.line.encode() + b"\n" for x in items]
    cut = 40

    async def first(writer):  # 40 lines, then half of the 41st, then the connection drops
        writer.write(b"".join(lines[:cut]) + lines[cut][:25])
        await writer.drain()

    async def second(writer):  # the feed carries on after the lost line
        writer.write(b"".join(lines[cut + 1:]))
        await writer.drain()

    async def main():
        server, port, calls = await serve([first, second])
        src = TcpAisSource(HOST, port, backoff=fast_backoff(), max_reconnects=1)
        async with server:
            n = sum([len(b) async for b in src.batches()])
        return src, n, calls["n"]

    src, n, connections = asyncio.run(main())
    st = src.status()
    assert connections == 2 and st.reconnects == 2 and not st.connected
    assert st.stats.errors["truncated"] == 1  # the half line, counted, not decoded
    assert st.stats.errors["disconnected"] == 2
    dynamic = [x for i, x in enumerate(items) if i != cut and isinstance(x.truth, AisReport)]
    assert n == len(dynamic)


def test_silent_feed_is_detected_and_reconnected_without_blocking_the_loop() -> None:
    items = synthetic(60.0, seed=6)

    async def silent(writer):
        await asyncio.sleep(1.0)

    async def talk(writer):
        writer.write(("\n".join(x.line for x in items) + "\n").encode())
        await writer.drain()

    async def main():
        server, port, _ = await serve([silent, talk])
        src = TcpAisSource(HOST, port, backoff=fast_backoff(), silence_timeout_s=0.2,
                           max_reconnects=1)
        ticks = 0

        async def twin_loop():  # the twin keeps ticking while the feed is silent
            nonlocal ticks
            while True:
                await asyncio.sleep(0.01)
                ticks += 1

        ticker = asyncio.create_task(twin_loop())
        async with server:
            n = sum([len(b) async for b in src.batches()])
        ticker.cancel()
        return src, n, ticks

    src, n, ticks = asyncio.run(main())
    assert src.status().stats.errors["silent_feed"] == 1
    assert n == sum(isinstance(x.truth, AisReport) for x in items)
    assert ticks >= 10


def test_connection_refused_is_counted_and_retried() -> None:
    with socket.socket() as s:
        s.bind((HOST, 0))
        port = s.getsockname()[1]  # closed again: nothing listens there

    async def main():
        src = TcpAisSource(HOST, port, backoff=fast_backoff(), max_reconnects=2,
                           connect_timeout_s=1.0)
        return src, [b async for b in src.batches()]

    src, batches = asyncio.run(main())
    assert batches == [] and src.status().stats.errors == {"connect_failed": 3}


def test_udp_listener_receives_datagrams() -> None:
    items = synthetic(120.0, seed=8)
    lines = [x.line.encode() for x in items]

    async def main():
        src = UdpAisSource(0, host=HOST, pipeline=AisPipeline())
        got: list[int] = []

        async def consume():
            async for batch in src.batches():
                got.append(len(batch))
                if src.status().stats.lines >= len(lines):
                    return

        task = asyncio.create_task(consume())
        await asyncio.wait_for(src.ready.wait(), 2.0)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for i in range(0, len(lines), 3):  # three sentences per datagram
                tx.sendto(b"\r\n".join(lines[i:i + 3]) + b"\r\n", (HOST, src.bound_port))
                await asyncio.sleep(0)
        await asyncio.wait_for(task, 5.0)
        return src, sum(got)

    src, n = asyncio.run(main())
    assert n == sum(isinstance(x.truth, AisReport) for x in items)
    assert src.status().stats.errors == {}
