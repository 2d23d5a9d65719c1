"""A live AIS feed for the twin (``ais.mode: live``): raw NMEA lines from ``tcp://`` or
``udp://``, taken at each tick.

The network readers are the project's own :class:`~asvtwin.sources.ais.TcpAisSource`
(reconnect with backoff and jitter, silence timeout, over-long and cut-off lines counted)
and :class:`~asvtwin.sources.ais.UdpAisSource` (bounded queue, kernel drops counted). They
run in their own thread with their own asyncio loop, so the twin's tick never waits on the
network. The twin needs the *raw lines* (it records them as its raw input, and decodes them
in its own pipeline like every other AIS line), so the readers are given a line tap in
place of their decoding pipeline: it queues every line they split off and keeps their
connection counters (connect failures, disconnects, silence). :meth:`LiveAisFeed.take`
hands the lines received since the last call to the tick.

A live feed is real time: the twin's clock must run at speed 1 and its epoch is the wall
time at the start, so tag-block times of the received lines fall in the run's time.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections import deque
from typing import Any

from asvtwin.errors import ScenarioError
from asvtwin.geo import Scene
from asvtwin.sources.ais import AisPipeline, ReportBatch, TcpAisSource, UdpAisSource

__all__ = ["LiveAisFeed", "parse_feed_url"]

_log = logging.getLogger(__name__)


def parse_feed_url(url: str) -> tuple[str, str, int]:
    """``tcp://host:port`` or ``udp://host:port`` as (scheme, host, port).

    Raises
    ------
    ScenarioError
        Another scheme, no host or a port outside 1..65535.
    """
    scheme, _, rest = str(url).partition("://")
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    if scheme not in ("tcp", "udp") or not host or not port.isdigit() or \
            not 1 <= int(port) <= 65535:
        raise ScenarioError(f"ais.url must be tcp://host:port or udp://host:port with port in "
                            f"[1, 65535], actually: {url!r}")
    return scheme, host, int(port)


class _LineTap:
    """Stands in for the readers' pipeline: queues the raw lines, keeps the counters."""

    def __init__(self, scene: Scene, sink: deque[str], lock: threading.Lock) -> None:
        self._inner = AisPipeline(scene)
        self._sink = sink
        self._lock = lock
        self.lines = 0
        self.dropped = 0

    @property
    def counters(self) -> Any:
        return self._inner.counters

    @property
    def stats(self) -> Any:
        return self._inner.stats

    def feed_batch(self, lines: Any, *, recv_time_s: float | None = None,
                   time_offset_s: float = 0.0) -> ReportBatch:
        out = [(x.decode("ascii", "replace") if isinstance(x, bytes) else str(x)).strip()
               for x in lines]
        out = [x for x in out if x]
        with self._lock:
            cap = self._sink.maxlen
            if cap is not None:  # the oldest lines fall out of the bounded buffer
                self.dropped += max(0, len(self._sink) + len(out) - cap)
            self._sink.extend(out)
            self.lines += len(out)
        return ReportBatch.empty()


class LiveAisFeed:
    """Raw NMEA lines from a live ``tcp://`` or ``udp://`` feed, read in a background thread.

    Parameters
    ----------
    url : str
        ``tcp://host:port`` (the twin connects) or ``udp://host:port`` (the twin listens on
        that address).
    scene : Scene
        The scene (the readers' counters need a pipeline).
    max_lines : int
        Lines buffered between two ticks; beyond, the oldest are dropped and counted in
        :attr:`dropped` (a tick that stalls for long cannot grow memory without bound).
    silence_timeout_s : float
        TCP: reconnect when nothing arrives for this long [s]; UDP: count a silent feed.
    """

    def __init__(self, url: str, scene: Scene, *, max_lines: int = 100_000,
                 silence_timeout_s: float = 60.0) -> None:
        self.url = url
        self.scheme, self.host, self.port = parse_feed_url(url)
        self._lines: deque[str] = deque(maxlen=int(max_lines))
        self._lock = threading.Lock()
        self._tap = _LineTap(scene, self._lines, self._lock)
        if self.scheme == "tcp":
            self.source: TcpAisSource | UdpAisSource = TcpAisSource(
                self.host, self.port, pipeline=self._tap,  # type: ignore[arg-type]
                silence_timeout_s=silence_timeout_s)
        else:
            self.source = UdpAisSource(self.port, host=self.host,
                                       pipeline=self._tap,  # type: ignore[arg-type]
                                       silence_timeout_s=silence_timeout_s)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task[None] | None = None
        self._started = threading.Event()
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"ais-live-{self.scheme}-{self.port}")
        self._thread.start()
        self._started.wait(5.0)

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop

        async def consume() -> None:
            async for _ in self.source.batches():  # the tap queues the lines
                pass

        try:
            self._task = loop.create_task(consume())
            self._started.set()
            loop.run_until_complete(self._task)
        except asyncio.CancelledError:
            pass  # stop() cancelled the reader: the normal end of a live feed
        except Exception as exc:  # noqa: BLE001 - the feed's end is reported, not raised
            self.error = f"live AIS feed {self.url} stopped: {exc}"
            _log.warning("%s", self.error)
        finally:
            self._started.set()
            loop.close()

    @property
    def alive(self) -> bool:
        """Whether the reader thread is running."""
        return self._thread.is_alive()

    @property
    def connected(self) -> bool:
        """Whether the reader holds a connection (TCP) or a bound socket (UDP) now."""
        return bool(self.source.status().connected)

    def counters(self) -> dict[str, int]:
        """The readers' error counts by kind (connect failures, disconnects, ...)."""
        return {str(k): int(v) for k, v in self._tap.stats.errors.items()}

    def take(self) -> list[str]:
        """The lines received since the last call, in arrival order."""
        with self._lock:
            out = list(self._lines)
            self._lines.clear()
        return out

    @property
    def dropped(self) -> int:
        """Lines dropped because more than ``max_lines`` arrived between two ticks."""
        return self._tap.dropped

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the reader and wait for its thread."""
        loop, task = self._loop, self._task
        if loop is not None and task is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(task.cancel)
            except RuntimeError:  # the loop already ended
                pass
        self._thread.join(timeout_s)
