"""Replayed AIS: NMEA log files, synthetic fjord traffic, recorded history sessions.

- :class:`FileReplaySource` reads an NMEA log (with or without tag blocks) and paces it by the
  ``c:`` receive times: real time, a speed factor, or as fast as possible; it loops on request,
  shifting the times of each pass so they keep increasing.
- :class:`SyntheticAisSource` runs :class:`~asvtwin.sources.ais.synthetic.SyntheticTraffic` and
  feeds its NMEA through the same pipeline as live data (the default of the twin).
- :class:`HistoryReplaySource` paces a session recorded in a
  :class:`~asvtwin.sources.history.SqliteHistory`.
"""

from __future__ import annotations

import asyncio
import math
import os
from collections.abc import AsyncIterator, Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from asvtwin.errors import ParameterError, SourceError
from asvtwin.geo import LocalFrame
from asvtwin.sources.ais.pipeline import AisPipeline
from asvtwin.sources.ais.reports import AisReport, AisStatic, ReportBatch
from asvtwin.sources.ais.source import Pacer, PipelineSource, tag_time, yield_control
from asvtwin.sources.ais.synthetic import SyntheticTraffic

if TYPE_CHECKING:  # history imports the report types of this package: import it lazily
    from asvtwin.sources.history import SqliteHistory

__all__ = ["FileReplaySource", "HistoryReplaySource", "SyntheticAisSource"]

_MAX_BATCH = 512


class FileReplaySource(PipelineSource):
    """Replay an NMEA log file through the pipeline.

    Parameters
    ----------
    path : path
        The log, one sentence per line (gzip not supported; tag blocks optional).
    speed : float or None
        1.0 for real time, ``x`` for x times faster, None for as fast as possible. Lines
        without a ``c:`` time are not paced.
    loop : bool
        Start again at the end; each pass is shifted by the log's span plus ``loop_gap_s`` so
        time keeps increasing.
    loop_gap_s : float
        Pause between passes, in stream time [s].
    max_step_s : float
        Largest stream-time step paced as it is [s]; lone corrupt times are ignored (see
        :class:`~asvtwin.sources.ais.source.Pacer`). Only tag times whose checksum holds and
        that are plausible pace the replay or count towards the loop span.
    pipeline, clock
        See :class:`~asvtwin.sources.ais.source.PipelineSource`; untagged lines are stamped
        with ``clock()`` when reading them (counted as the notice ``receive_time``); without
        a clock they are counted as ``missing_time``.
    """

    def __init__(self, path: str | os.PathLike[str], *, speed: float | None = 1.0,
                 loop: bool = False, loop_gap_s: float = 60.0, max_step_s: float = 60.0,
                 pipeline: AisPipeline | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        super().__init__(pipeline=pipeline, clock=clock)
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"AIS log {str(self.path)!r} is not a readable file")
        self.speed = speed
        self.max_step_s = float(max_step_s)
        self.pacer = Pacer(speed, max_step_s=max_step_s)  # validates; replaced on each run
        self.loop = loop
        if not (math.isfinite(loop_gap_s) and loop_gap_s >= 0):
            raise ParameterError(f"loop_gap_s must be finite and >= 0, actually: {loop_gap_s}")
        self.loop_gap_s = float(loop_gap_s)
        self.passes = 0
        self.span_s: float | None = None  #: the log's span used between loop passes [s]

    async def batches(self) -> AsyncIterator[ReportBatch]:
        offset = 0.0
        span: float | None = None
        pacer = Pacer(self.speed, max_step_s=self.max_step_s)
        self.pacer = pacer
        self._connected = True
        try:
            while True:
                pending: list[bytes] = []
                with self.path.open("rb") as fh:
                    for line in fh:
                        t = tag_time(line)  # checksum-valid and plausible, else None
                        wait = pacer.delay(t + offset) if t is not None else 0.0
                        if wait > 0.0 or len(pending) >= _MAX_BATCH:
                            if pending:
                                yield self._feed(pending, offset)
                                pending = []
                            await (asyncio.sleep(wait) if wait > 0 else yield_control())
                        pending.append(line)
                if pending:
                    yield self._feed(pending, offset)
                self.pipeline.finish()  # fragments cannot complete across the end of the file
                self.passes += 1
                if not self.loop:
                    return
                # the next pass starts after everything the first accepted: the span of the
                # pacer's timeline (lone corrupt times are not on it) or of the pipeline's
                # accepted reports (bounded by the robust stream time), plus the gap
                if span is None:
                    span = 0.0
                    if pacer.first is not None and pacer.last is not None:
                        end = max(pacer.last, self.pipeline.latest_time_unix_s or -math.inf)
                        span = end - pacer.first
                    self.span_s = span
                # ... and beyond the duplicate window: a short log's lines are not copies
                offset += max(span + self.loop_gap_s, self.pipeline.dedup_window_s + 1.0)
                await yield_control()
        finally:
            self._connected = False

    def _feed(self, lines: list[bytes], offset: float) -> ReportBatch:
        self._last_data = self._now()
        return self.pipeline.feed_batch(lines, recv_time_s=self._last_data,
                                        time_offset_s=offset)


class SyntheticAisSource(PipelineSource):
    """Simulated fjord traffic as an AIS feed, decoded by the real pipeline.

    Parameters
    ----------
    traffic : SyntheticTraffic
        The simulation (seeded through its ``rng``).
    speed : float or None
        Pacing factor against the simulated time (None: as fast as possible).
    duration_s : float or None
        Simulated time to run [s]; None runs until the consumer stops.
    chunk_s : float
        Simulated time generated per step [s].
    pipeline : AisPipeline, optional
        Decoding pipeline; a new one on the traffic's scene when omitted.
    """

    def __init__(self, traffic: SyntheticTraffic, *, speed: float | None = 1.0,
                 duration_s: float | None = None, chunk_s: float = 10.0,
                 pipeline: AisPipeline | None = None) -> None:
        super().__init__(pipeline=pipeline if pipeline is not None
                         else AisPipeline(traffic.traffic.scene))
        Pacer(speed)
        self.traffic = traffic
        self.speed = speed
        self.duration_s = duration_s
        self.chunk_s = float(chunk_s)

    async def batches(self) -> AsyncIterator[ReportBatch]:
        pacer = Pacer(self.speed)
        done = 0.0
        self._connected = True
        try:
            while self.duration_s is None or done < self.duration_s - 1e-9:
                step = self.chunk_s if self.duration_s is None else \
                    min(self.chunk_s, self.duration_s - done)
                pending: list[str] = []
                t_pending: float | None = None
                for item in self.traffic.run(step):
                    wait = pacer.delay(item.t_unix_s)
                    if wait > 0.0 and pending:
                        self._last_data = t_pending
                        yield self.pipeline.feed_batch(pending)
                        pending = []
                    if wait > 0.0:
                        await asyncio.sleep(wait)
                    pending.append(item.line)
                    t_pending = item.t_unix_s
                if pending:
                    self._last_data = t_pending
                    yield self.pipeline.feed_batch(pending)
                done += step
                await yield_control()
        finally:
            self._connected = False


class HistoryReplaySource(PipelineSource):
    """Replay a recorded session from the history store, paced by its report times.

    The stored messages were validated when recorded; they are re-projected into ``frame``
    and handed out without decoding again (the pipeline's counts stay zero).
    """

    def __init__(self, store: SqliteHistory, frame: LocalFrame, *, speed: float | None = 1.0,
                 since_unix_s: float | None = None, until_unix_s: float | None = None) -> None:
        super().__init__(pipeline=AisPipeline())
        Pacer(speed)
        self.store = store
        self.frame = frame
        self.speed = speed
        self.since_unix_s = since_unix_s
        self.until_unix_s = until_unix_s

    def _session(self) -> Iterator[AisReport | AisStatic]:
        from asvtwin.sources.history import replay_session

        return replay_session(self.store, self.frame, since_unix_s=self.since_unix_s,
                              until_unix_s=self.until_unix_s)

    async def batches(self) -> AsyncIterator[ReportBatch]:
        pacer = Pacer(self.speed)
        reports: list[AisReport] = []
        static: list[AisStatic] = []
        self._connected = True
        try:
            for msg in self._session():
                wait = pacer.delay(msg.t_unix_s)
                if (wait > 0.0 or len(reports) >= _MAX_BATCH) and (reports or static):
                    yield ReportBatch.from_reports(reports, tuple(static), frame=self.frame)
                    reports, static = [], []
                if wait > 0.0:
                    await asyncio.sleep(wait)
                self._last_data = msg.t_unix_s
                (static if isinstance(msg, AisStatic) else reports).append(msg)  # type: ignore[arg-type]
            if reports or static:
                yield ReportBatch.from_reports(reports, tuple(static), frame=self.frame)
        finally:
            self._connected = False
