"""Fan-out of snapshots to WebSocket clients without letting a slow client slow anyone.

One producer task polls the feed for a new :class:`~asvtwin.server.feed.Frame` (encoded
once: every client is sent the same bytes) and offers it to every client. Each client has
its own sender task fed by a one-frame slot where the newest frame replaces the one not
yet sent, so a client that reads slowly simply gets
fewer frames, and the producer never awaits a client. A blocked ``send`` (a client that
stopped reading: uvicorn's ``send`` blocks once the socket buffers fill, ~2.7 MiB) is
bounded by ``send_timeout_s``; on timeout the client's tasks are cancelled rather than
awaiting ``close()``, which would block the same way. Events (the snapshot's ``events``)
go to each client through a separate small queue, so a skipped frame loses no event.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

import orjson

from asvtwin.server.api import ClientOptions
from asvtwin.server.feed import Frame, SnapshotFeed

__all__ = ["Client", "Hub"]

log = logging.getLogger(__name__)
_ids = itertools.count(1)


@dataclass(eq=False)
class Client:
    """One WebSocket client: its options, its one-slot frame mailbox and counters.

    ``slot`` holds the newest frame not yet sent (a queue of length one whose newest
    frame replaces the old); ``wake`` is set when a frame or an event arrives. One event
    per client and no per-message futures: the fan-out costs the loop one ``set()`` per
    client and frame, the sender one wake-up per message."""

    options: ClientOptions
    id: int = field(default_factory=lambda: next(_ids))
    slot: Frame | None = None
    events: deque[dict[str, Any]] = field(default_factory=lambda: deque(maxlen=256))
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    credit: asyncio.Event = field(default_factory=asyncio.Event)  # set: may send (ack mode)
    sent: int = 0
    replaced: int = 0
    bytes_sent: int = 0

    def offer(self, frame: Frame) -> None:
        """Put ``frame`` in the slot, replacing a frame not yet sent (never blocks)."""
        if self.slot is not None:
            self.replaced += 1
        self.slot = frame
        if frame.events:
            self.events.append({"type": "events", "seq": frame.seq, "t_s": frame.t_s,
                                "events": list(frame.events)})
        self.wake.set()


class Hub:
    """The set of connected clients, the producer task and the counters."""

    def __init__(self, feed: SnapshotFeed, *, poll_s: float = 1 / 60, send_timeout_s: float = 2.0
                 ) -> None:
        self.feed = feed
        self.poll_s = poll_s
        self.send_timeout_s = send_timeout_s
        self.clients: set[Client] = set()
        self.counters: Counter[str] = Counter()
        self.last_frame: Frame | None = None
        self._task: asyncio.Task[None] | None = None
        self.producer_lag_ms: deque[float] = deque(maxlen=1000)

    # ------------------------------------------------------------- producer
    async def _produce(self) -> None:
        while True:
            t0 = time.perf_counter()
            try:
                fr = self.feed.frame()
            except Exception:
                self.counters["feed_errors"] += 1
                if self.counters["feed_errors"] == 1:
                    log.exception("the feed failed to give a frame")
                fr = None
            # a new Frame object is a new snapshot (feeds cache one Frame per snapshot),
            # also when a paused twin republishes under the same seq and time
            if fr is not None and fr is not self.last_frame:
                self.last_frame = fr
                self.counters["frames"] += 1
                for c in self.clients:
                    c.offer(fr)
            self.producer_lag_ms.append((time.perf_counter() - t0) * 1e3)
            await asyncio.sleep(self.poll_s)

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._produce(), name="producer")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    # ------------------------------------------------------------- clients
    def add(self, options: ClientOptions) -> Client:
        c = Client(options)
        c.credit.set()
        self.clients.add(c)
        self.counters["ws_connected"] += 1
        if self.last_frame is not None:
            c.offer(self.last_frame)
        return c

    def remove(self, c: Client) -> None:
        self.clients.discard(c)
        self.counters["ws_closed"] += 1

    async def send_loop(self, ws: Any, c: Client) -> None:
        """Send the newest frame at most ``rate_hz`` times per second; events first."""
        next_t = time.monotonic()
        while True:
            await c.wake.wait()
            c.wake.clear()
            while c.events:
                await self._send(ws, c, orjson.dumps(c.events.popleft()), text=True)
            frame, c.slot = c.slot, None
            if frame is None:
                continue
            if c.options.ack:
                # wait for the client to acknowledge the previous snapshot; a newer frame
                # arriving meanwhile replaces this one
                await c.credit.wait()
                c.credit.clear()
                if c.slot is not None:
                    frame, c.slot = c.slot, None
            data = frame.msgpack() if c.options.format == "msgpack" else frame.data
            await self._send(ws, c, data, text=False)
            c.sent += 1
            self.counters["frames_sent"] += 1
            next_t = max(next_t + 1.0 / c.options.rate_hz, time.monotonic())
            await asyncio.sleep(next_t - time.monotonic())

    async def _send(self, ws: Any, c: Client, data: bytes, *, text: bool) -> None:
        try:
            if text:
                await asyncio.wait_for(ws.send_text(data.decode()), self.send_timeout_s)
            else:
                await asyncio.wait_for(ws.send_bytes(data), self.send_timeout_s)
        except TimeoutError:
            self.counters["ws_send_timeouts"] += 1
            raise
        c.bytes_sent += len(data)
        self.counters["bytes_sent"] += len(data)

    def stats(self) -> dict[str, Any]:
        lag = sorted(self.producer_lag_ms)
        return {
            "clients": len(self.clients),
            "counters": dict(self.counters),
            "per_client": [{"id": c.id, "rate_hz": c.options.rate_hz, "format": c.options.format,
                            "sent": c.sent, "replaced": c.replaced, "bytes_sent": c.bytes_sent}
                           for c in self.clients],
            "producer_ms_median": lag[len(lag) // 2] if lag else None,
            "last_seq": self.last_frame.seq if self.last_frame else None,
        }
