"""What every AIS source shares: the async-iterator interface, status, pacing.

An AIS source is an async iterator of validated messages (:class:`AisReport` and
:class:`AisStatic`) in the scene's NED frame. Each source also offers :meth:`batches`, the
same messages as columnar :class:`ReportBatch` objects (what the registry and the history
take in one call). All sources decode through one :class:`AisPipeline`, whose counters are the
source's error counts.
"""

from __future__ import annotations

import abc
import asyncio
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from asvtwin.errors import ParameterError
from asvtwin.sources.ais.counters import PipelineStats
from asvtwin.sources.ais.pipeline import AisPipeline
from asvtwin.sources.ais.reports import AisMessage, ReportBatch

__all__ = ["AisSource", "Pacer", "PipelineSource", "SourceStatus", "tag_time"]


@dataclass(frozen=True)
class SourceStatus:
    """Health of a source, for the twin's status line.

    Attributes
    ----------
    connected : bool
        A connection (or socket, or file) is open now.
    reconnects : int
        Connections lost and retried.
    last_data_unix_s : float or None
        When data last arrived (by the source's clock); None before any or without a clock.
    stats : PipelineStats
        Decoding counts, including the errors by kind.
    """

    connected: bool
    reconnects: int
    last_data_unix_s: float | None
    stats: PipelineStats


@runtime_checkable
class AisSource(Protocol):
    """An async iterator of validated AIS messages in the scene's NED frame."""

    pipeline: AisPipeline

    def __aiter__(self) -> AsyncIterator[AisMessage]: ...

    def batches(self) -> AsyncIterator[ReportBatch]: ...

    def status(self) -> SourceStatus: ...


class PipelineSource(abc.ABC):
    """Base of the sources: holds the pipeline, the clock and the status counters.

    Parameters
    ----------
    pipeline : AisPipeline, optional
        The decoding pipeline (a new one on the default scene when omitted).
    clock : callable, optional
        Returns the current UNIX time [s]; gives lines without a tag block their receive time.
    """

    def __init__(self, *, pipeline: AisPipeline | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        self.pipeline = pipeline if pipeline is not None else AisPipeline(clock=clock)
        self.clock = clock
        self._connected = False
        self._reconnects = 0
        self._last_data: float | None = None

    def status(self) -> SourceStatus:
        """Current health and counts."""
        return SourceStatus(self._connected, self._reconnects, self._last_data,
                            self.pipeline.stats)

    def _now(self) -> float | None:
        return self.clock() if self.clock is not None else None

    @abc.abstractmethod
    def batches(self) -> AsyncIterator[ReportBatch]:
        """The validated reports, one batch per chunk of input (each source's own)."""

    def __aiter__(self) -> AsyncIterator[AisMessage]:
        return self._messages()

    async def _messages(self) -> AsyncIterator[AisMessage]:
        async for batch in self.batches():
            for s in batch.static:
                yield s
            for r in batch.reports():
                yield r


def tag_time(line: bytes) -> float | None:
    """The ``c:`` receive time [UNIX s] of a line's tag block, or None (no parsing errors)."""
    if not line.startswith(b"\\"):
        return None
    end = line.find(b"\\", 1)
    i = line.find(b"c:", 1, end)
    if end < 0 or i < 0:
        return None
    j = i + 2
    while j < end and line[j] not in b",*":
        j += 1
    try:
        c = float(line[i + 2:j])
    except ValueError:
        return None
    return c / 1000.0 if c > 1e11 else c


class Pacer:
    """Real-time pacing from stream times, without reading a clock.

    Each call to :meth:`delay` takes the next item's stream time and returns how long to sleep
    before handing it out: the stream-time step divided by ``speed``, accumulated until it is
    worth a sleep (>= ``min_sleep_s``). Processing time is not subtracted, so a slow consumer
    makes the replay slower, never faster, than ``speed``.

    Parameters
    ----------
    speed : float or None
        Replay speed factor (1 = real time, 100 = a hundred times faster); None for as fast
        as possible.
    min_sleep_s : float
        Smallest sleep worth taking [s].
    """

    def __init__(self, speed: float | None, *, min_sleep_s: float = 0.005) -> None:
        if speed is not None and not speed > 0:
            raise ParameterError(f"replay speed must be > 0 (or None), actually: {speed}")
        self.speed = speed
        self.min_sleep_s = min_sleep_s
        self._t_prev: float | None = None
        self._debt = 0.0

    def delay(self, t: float | None) -> float:
        """Seconds to sleep before the item at stream time ``t`` (0 when not yet worth it)."""
        if self.speed is None or t is None:
            return 0.0
        if self._t_prev is not None and t > self._t_prev:
            self._debt += (t - self._t_prev) / self.speed
        if self._t_prev is None or t > self._t_prev:
            self._t_prev = t
        if self._debt >= self.min_sleep_s:
            d, self._debt = self._debt, 0.0
            return d
        return 0.0


async def yield_control() -> None:
    """Let the event loop run other tasks (between large batches)."""
    await asyncio.sleep(0)
