"""Recording a live feed into the history without stalling it or dying with the disk.

A receiver that records must keep receiving when recording fails. :class:`HistoryRecorder`
takes batches from the event loop without blocking it (a bounded queue, written by one worker
thread, so SQLite's commits and fsyncs never run on the loop) and, when the store fails (a
full disk, a file made read-only), *suspends* recording instead of raising: it counts what
was not recorded, logs the cause once, and tries again after ``retry_after_s``. The twin and
the target table carry on from the feed.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass

from asvtwin.errors import ParameterError, SourceError
from asvtwin.sources.ais.reports import ReportBatch
from asvtwin.sources.history import HistoryStore

__all__ = ["HistoryRecorder", "RecorderStatus"]

_log = logging.getLogger("asvtwin.sources.history")
_STOP = object()


@dataclass(frozen=True)
class RecorderStatus:
    """What was recorded and what was not.

    Attributes
    ----------
    recorded_reports, recorded_static : int
        Rows written.
    lost_reports, lost_static : int
        Rows not written: the store failed, recording was suspended, or the queue was full.
    failures : int
        Appends that failed.
    suspended : bool
        Recording is suspended now (after a failure, until the retry time).
    last_error : str or None
        The latest failure's message.
    queued : int
        Batches waiting for the writer.
    """

    recorded_reports: int
    recorded_static: int
    lost_reports: int
    lost_static: int
    failures: int
    suspended: bool
    last_error: str | None
    queued: int


class HistoryRecorder:
    """Append batches to a store from a worker thread; suspend, count and retry on failure.

    Parameters
    ----------
    store : HistoryStore
        Where to write (opened by the caller; closed by :meth:`close`).
    clock : callable
        Current time [s] (monotonic or UNIX), for the retry time.
    retry_after_s : float
        After a failed append, batches are counted as lost for this long, then writing is
        tried again [s].
    max_queue : int
        Batches waiting for the writer; beyond it new batches are counted as lost.
    """

    def __init__(self, store: HistoryStore, *, clock: Callable[[], float],
                 retry_after_s: float = 60.0, max_queue: int = 256) -> None:
        if not retry_after_s >= 0 or max_queue < 1:
            raise ParameterError(f"HistoryRecorder: retry_after_s >= 0 and max_queue >= 1 "
                                 f"expected, actually: {retry_after_s}, {max_queue}")
        self.store = store
        self.clock = clock
        self.retry_after_s = float(retry_after_s)
        self._queue: queue.Queue[object] = queue.Queue(max_queue)
        self._lock = threading.Lock()
        self._recorded = [0, 0]
        self._lost = [0, 0]
        self._failures = 0
        self._retry_at: float | None = None
        self._last_error: str | None = None
        self._thread = threading.Thread(target=self._run, name="asvtwin-history-writer",
                                        daemon=True)
        self._thread.start()

    def submit(self, batch: ReportBatch) -> None:
        """Queue a batch for writing (never blocks; counts it as lost if the queue is full)."""
        if not len(batch) and not batch.static:
            return
        try:
            self._queue.put_nowait(batch)
        except queue.Full:
            self._lose(batch, "the writer is behind (queue full)")

    def status(self) -> RecorderStatus:
        """Counts so far."""
        with self._lock:
            return RecorderStatus(self._recorded[0], self._recorded[1], self._lost[0],
                                  self._lost[1], self._failures, self._retry_at is not None,
                                  self._last_error, self._queue.qsize())

    def close(self, timeout_s: float = 30.0) -> RecorderStatus:
        """Write what is queued, stop the worker, close the store; return the final counts.

        A store that cannot be closed (its final commit fails) is counted like a failed
        append, not raised."""
        self._queue.put(_STOP)
        self._thread.join(timeout_s)
        try:
            self.store.close()
        except SourceError as exc:
            with self._lock:
                self._failures += 1
                self._last_error = str(exc)
            _log.warning("history: %s", exc)
        return self.status()

    def _lose(self, batch: ReportBatch, why: str) -> None:
        with self._lock:
            self._lost[0] += len(batch)
            self._lost[1] += len(batch.static)
        _log.debug("history: batch of %d reports not recorded: %s", len(batch), why)

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            assert isinstance(item, ReportBatch)
            if self._retry_at is not None:
                if self.clock() < self._retry_at:
                    self._lose(item, "recording suspended")
                    continue
                with self._lock:
                    self._retry_at = None
                _log.warning("history: trying to record again")
            try:
                self.store.append_batch(item)
            except SourceError as exc:
                with self._lock:
                    self._failures += 1
                    self._last_error = str(exc)
                    self._retry_at = self.clock() + self.retry_after_s
                self._lose(item, str(exc))
                _log.warning("history: recording suspended for %.0f s, the feed goes on: %s",
                             self.retry_after_s, exc)
                continue
            with self._lock:
                self._recorded[0] += len(item)
                self._recorded[1] += len(item.static)
