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
import functools
import math
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from asvtwin.errors import ParameterError
from asvtwin.sources.ais.counters import PipelineStats
from asvtwin.sources.ais.pipeline import AisPipeline
from asvtwin.sources.ais.reports import AisMessage, ReportBatch
from asvtwin.sources.ais.tagblock import TagBlockError, parse_tag_block
from asvtwin.sources.ais.timebase import plausible_time

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
    """The ``c:`` receive time [UNIX s] of a line's tag block, or None.

    Only a time that can be trusted for pacing: the tag block's checksum holds (either
    convention of :func:`~asvtwin.sources.ais.tagblock.parse_tag_block`) and the time is
    plausible (2000..2100). Never raises.
    """
    if not line.startswith(b"\\"):
        return None
    end = line.find(b"\\", 1)
    return _tag_block_time(line[1:end]) if end > 0 else None


@functools.lru_cache(maxsize=4096)
def _tag_block_time(tag: bytes) -> float | None:
    """A tag block's trustworthy time (a pure function of the tag: cached, as lines of one
    second from one station share their tag)."""
    try:
        t = parse_tag_block(tag).t_unix_s
    except TagBlockError:
        return None
    return t if plausible_time(t) else None


class Pacer:
    """Real-time pacing from stream times, without reading a clock.

    Each call to :meth:`delay` takes the next item's stream time and returns how long to sleep
    before handing it out: the stream-time step divided by ``speed``, accumulated until it is
    worth a sleep (>= ``min_sleep_s``). Processing time is not subtracted, so a slow consumer
    makes the replay slower, never faster, than ``speed``.

    One corrupt time must not stall or race the replay: a jump of more than ``max_step_s``
    (forwards or backwards) is taken only when the next time confirms it (lies within
    ``max_step_s`` of it); a lone outlier is ignored (:attr:`outliers`). A confirmed forward
    jump (a gap in the log) sleeps at most ``max_step_s / speed`` (:attr:`gaps`). The
    timeline the pacer follows (:attr:`first`, :attr:`last`) is what a looping replay uses as
    the log's span.

    Parameters
    ----------
    speed : float or None
        Replay speed factor (1 = real time, 100 = a hundred times faster); None for as fast
        as possible (the timeline is still followed).
    min_sleep_s : float
        Smallest sleep worth taking [s].
    max_step_s : float
        Largest stream-time step paced as it is [s].
    """

    def __init__(self, speed: float | None, *, min_sleep_s: float = 0.005,
                 max_step_s: float = 60.0) -> None:
        if speed is not None and not (speed > 0 and math.isfinite(speed)):
            raise ParameterError(f"replay speed must be finite and > 0 (or None), actually: "
                                 f"{speed}")
        if not (max_step_s > 0 and math.isfinite(max_step_s)):
            raise ParameterError(f"max_step_s must be finite and > 0, actually: {max_step_s}")
        self.speed = speed
        self.min_sleep_s = min_sleep_s
        self.max_step_s = float(max_step_s)
        self._t_prev: float | None = None
        self._jump: float | None = None
        self._debt = 0.0
        self.first: float | None = None  #: first time of the timeline [s]
        self.last: float | None = None  #: latest time of the timeline [s]
        self.outliers = 0  #: lone times ignored
        self.gaps = 0  #: confirmed forward jumps longer than max_step_s (sleep capped)

    def delay(self, t: float | None) -> float:
        """Seconds to sleep before the item at stream time ``t`` (0 when not yet worth it)."""
        if t is None or not math.isfinite(t):
            return 0.0
        prev = self._t_prev
        if prev is None:
            self._t_prev = self.first = self.last = t
            return 0.0
        step = t - prev
        if abs(step) > self.max_step_s:
            jump = self._jump
            if jump is None or abs(t - jump) > self.max_step_s:
                if jump is not None:
                    self.outliers += 1  # the previous lone jump was not confirmed
                self._jump = t
                return 0.0
            self._jump = None  # confirmed: a gap (or a restart) in the log
            if step > 0:
                self.gaps += 1
                self._debt += self.max_step_s / self.speed if self.speed else 0.0
            self._t_prev = t
            self.last = t if self.last is None or t > self.last else self.last
            return self._pay()
        if self._jump is not None:
            self.outliers += 1
            self._jump = None
        if step > 0:
            if self.speed is not None:
                self._debt += step / self.speed
            self._t_prev = t
            if self.last is None or t > self.last:
                self.last = t
        return self._pay()

    def _pay(self) -> float:
        if self._debt >= self.min_sleep_s:
            d, self._debt = self._debt, 0.0
            return d
        return 0.0


async def yield_control() -> None:
    """Let the event loop run other tasks (between large batches)."""
    await asyncio.sleep(0)
