"""NMEA lines -> validated AIS reports in the scene's NED frame.

:class:`AisPipeline` is the one decoding path of every AIS source (TCP, UDP, file replay,
synthetic traffic, history). Per line, in order (one method or module per stage):

1. **sentence** (:mod:`~asvtwin.sources.ais.sentence`, :meth:`AisPipeline._frame`): 7-bit
   ASCII (a garbage prefix is skipped up to the next ``\\`` or ``!``), IEC 61162-450 tag
   block (``\\s:station,c:time*hh\\``, checksum over the whole tag or, the national feed's
   group convention, over ``c:`` alone), ``*hh`` checksum of the sentence, fields parsed by
   :class:`pyais.messages.NMEASentenceFactory`, fill bits one digit 0..5, every payload
   character in the AIS 6-bit alphabet; ``!xxVDO`` (the own ship) is not a target;
2. **assembly** of multi-fragment messages (:class:`FragmentAssembler`), the timeout checked
   on every timed line and at the end of a stream (:meth:`AisPipeline.finish`);
3. **duplicates** (:class:`~asvtwin.sources.ais.duplicates.DuplicateFilter`): the same payload
   again within ``dedup_window_s`` (one transmission heard by two base stations) is dropped;
4. **decode**: one-sentence position reports (types 1, 2, 3, 18: most lines of a feed) for the
   whole batch at once (:mod:`~asvtwin.sources.ais.positions`, checked field for field against
   pyais), everything else with pyais (types 5, 19, 24 used; others counted by type, skipped);
5. **validation** (:class:`~asvtwin.sources.ais.validation.ReportValidator`):
   MMSI range, receive time present and plausible, position available, valid and inside the
   scene box, not behind the MMSI's last report, not in the future (ahead of the receive
   clock, or of the robust stream time :class:`StreamClock`, which no single report can
   move);
6. **projection** to the scene's NED frame and SI units, "not available" values (lat 91,
   lon 181, SOG 102.3 kn, COG 360, heading 511, ROT -128 / +-127) to NaN/None, vectorised
   over the batch (:mod:`~asvtwin.sources.ais.records`).

Every rejection is counted by :class:`~asvtwin.sources.ais.counters.ErrorKind`, logged once,
and skipped. Time comes from tag blocks or from ``recv_time_s`` passed by the caller; the
pipeline reads no clock except the optional ``clock`` callable given to it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from pyais.exceptions import AISBaseException
from pyais.messages import AISSentence

from asvtwin.errors import ParameterError
from asvtwin.geo import Scene, default_scene
from asvtwin.sources.ais.census import LogCensus
from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind, NoticeKind, PipelineStats
from asvtwin.sources.ais.duplicates import DuplicateFilter
from asvtwin.sources.ais.fragments import FragmentAssembler
from asvtwin.sources.ais.positions import FastLines, no_fast_lines, scan_fast_lines
from asvtwin.sources.ais.records import COLUMNS, pyais_row, report_batch, static_record
from asvtwin.sources.ais.reports import AisStatic, ReportBatch
from asvtwin.sources.ais.sentence import STARTS, TagCache, as_bytes, check_ais, prefix_xor, resync
from asvtwin.sources.ais.tagblock import TagBlockError, parse_tag_block
from asvtwin.sources.ais.timebase import T_MAX_UNIX_S, T_MIN_UNIX_S, StreamClock
from asvtwin.sources.ais.validation import ReportValidator, TimeReference

__all__ = ["DYNAMIC_TYPES", "STATIC_TYPES", "AisPipeline", "LogCensus"]

#: Message types that carry a position report.
DYNAMIC_TYPES = frozenset({1, 2, 3, 18, 19})
#: Message types that carry static data.
STATIC_TYPES = frozenset({5, 19, 24})
#: Fewest payload bits each used type needs (ITU-R M.1371; type 5 tolerates 420).
_MIN_BITS = {1: 168, 2: 168, 3: 168, 18: 168, 19: 312, 5: 420, 24: 160}
#: What pyais raises for a payload it cannot decode.
_DECODE_FAILURES = (AISBaseException, ValueError, IndexError, KeyError, TypeError)


class _Batch(TimeReference):
    """The state of one :meth:`AisPipeline.feed_batch` call, shared by its stages."""

    __slots__ = ("P", "fast", "recv_t", "rows", "slow", "static", "station", "t")

    def __init__(self, clock_now: float | None, ref: float | None, lead: float,
                 lag_limit: float, recv_t: float | None, P: bytes, fast: FastLines,
                 hwm: float | None) -> None:
        super().__init__(clock_now, ref, lead, lag_limit, hwm)
        self.recv_t = recv_t  #: receive time for lines without a tag time [UNIX s]
        self.P = P  #: prefix XOR of the joined batch (every checksum)
        self.fast = fast  #: the batch's canonical position reports, decoded at once
        self.rows: list[int] = []  #: accepted reports: row in fast + slow columns
        self.t: list[float] = []  #: accepted reports' times [UNIX s]
        self.station: list[str | None] = []
        self.static: list[AisStatic] = []
        self.slow: list[tuple[Any, ...]] = []  #: position reports decoded by pyais


class AisPipeline:
    """Decode, assemble, validate and project AIS NMEA lines (one instance per feed).

    Parameters
    ----------
    scene : Scene, optional
        Frame and bounds; :func:`asvtwin.geo.default_scene` when omitted.
    clock : callable, optional
        Returns the current UNIX time [s] (read once per batch: the receive time). When
        given, reports more than ``max_future_s`` ahead of it are rejected; without it the
        reference is the robust stream time (:class:`StreamClock`) and the limit
        ``max_jump_s``.
    max_future_s : float
        Allowed lead over ``clock()`` [s] (receiver clocks drift a little).
    max_jump_s : float
        Allowed lead over the robust stream time when there is no clock [s].
    max_lag_s : float
        With a clock: reports older than this behind it are counted as the notice
        ``feed_clock_lags`` (kept; the feed's clock, not the report, is wrong) [s].
    dedup_window_s : float
        Identical payloads closer than this are one transmission heard twice [s].
    fragment_timeout_s : float
        A multi-fragment message not completed within this time is dropped [s].
    max_pending : int
        Most multi-fragment messages assembled at once (oldest dropped beyond).
    max_tracked_mmsi : int
        Most MMSIs whose last report time is kept for the time-order check.
    bounds : bool
        Reject positions outside the scene's box (``outside_scene``). False keeps them
        (projected into the scene's frame, counted as the notice ``outside_scene_kept``):
        a log summary counts the whole feed.
    require_time : bool
        Reject messages without any time (``missing_time``). False accepts them with a NaN
        time and no time checks (a log summary of an untagged log).
    census : bool
        Keep a :class:`LogCensus` (every MMSI, the tag-time span) in :attr:`census`.
    batch_decode : bool
        Decode the batch's one-sentence position reports at once with numpy
        (:mod:`~asvtwin.sources.ais.positions`). False sends every message through pyais:
        the same reports and counts, about twice the time (for cross-checks and benchmarks).
    """

    def __init__(self, scene: Scene | None = None, *, clock: Callable[[], float] | None = None,
                 max_future_s: float = 60.0, max_jump_s: float = 600.0,
                 max_lag_s: float = 600.0, dedup_window_s: float = 30.0,
                 fragment_timeout_s: float = 10.0, max_pending: int = 1024,
                 max_tracked_mmsi: int = 200_000, bounds: bool = True,
                 require_time: bool = True, census: bool = False,
                 batch_decode: bool = True) -> None:
        for name, v in (("max_future_s", max_future_s), ("max_jump_s", max_jump_s),
                        ("max_lag_s", max_lag_s), ("dedup_window_s", dedup_window_s),
                        ("fragment_timeout_s", fragment_timeout_s)):
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"AisPipeline: {name} must be finite and >= 0, actually: {v}")
        for name, n in (("max_pending", max_pending), ("max_tracked_mmsi", max_tracked_mmsi)):
            if n < 1:
                raise ParameterError(f"AisPipeline: {name} must be >= 1, actually: {n}")
        self.scene = scene if scene is not None else default_scene()
        self._clock = clock
        self._max_future_s = float(max_future_s)
        self._max_jump_s = float(max_jump_s)
        self._max_lag_s = float(max_lag_s)
        self._batch_decode = bool(batch_decode)
        self.census: LogCensus | None = LogCensus() if census else None
        self.counters = ErrorCounter()
        self.notices = ErrorCounter(what="accepted with a quirk")
        self.fragments = FragmentAssembler(self.counters, timeout_s=fragment_timeout_s,
                                           max_pending=max_pending)
        self.duplicates = DuplicateFilter(dedup_window_s)
        self.stream_clock = StreamClock()
        self.tags = TagCache()
        self.validator = ReportValidator(self.scene.bounds, self.counters, self.notices,
                                         self.stream_clock, bounds=bounds,
                                         require_time=require_time,
                                         max_tracked_mmsi=max_tracked_mmsi)
        self._hwm: float | None = None  # latest accepted report time [UNIX s]
        self._lines = 0
        self._by_type: dict[int, int] = {}
        self._n_reports = 0
        self._n_static = 0
        self._clock_lag_s: float | None = None

    # ------------------------------------------------------------------ public
    @property
    def stats(self) -> PipelineStats:
        """Counts since the start (a snapshot)."""
        return PipelineStats(lines=self._lines, messages_by_type=dict(self._by_type),
                             reports=self._n_reports, statics=self._n_static,
                             errors=dict(self.counters.counts),
                             notices=dict(self.notices.counts),
                             stream_time_unix_s=self.stream_time_unix_s,
                             clock_lag_s=self._clock_lag_s,
                             pending_fragments=len(self.fragments))

    @property
    def dedup_window_s(self) -> float:
        """Identical payloads closer than this are one transmission heard twice [s]."""
        return self.duplicates.window_s

    @property
    def latest_time_unix_s(self) -> float | None:
        """Latest accepted report time [UNIX s], None before the first.

        Bounded by the robust stream time plus ``max_jump_s`` (or the clock plus
        ``max_future_s``): a report further ahead is rejected, never accepted."""
        return self._hwm

    @property
    def stream_time_unix_s(self) -> float | None:
        """Robust current time of the stream [UNIX s] from every timed line, in or out of
        the scene (:class:`StreamClock`); no single report moves it. None before any."""
        return self.stream_clock.update()

    def finish(self) -> int:
        """End of stream: count messages still waiting for fragments as incomplete."""
        return self.fragments.flush()

    def feed(self, line: bytes | str, *, recv_time_s: float | None = None) -> ReportBatch:
        """Process one line; see :meth:`feed_batch`."""
        return self.feed_batch((line,), recv_time_s=recv_time_s)

    def feed_batch(self, lines: Iterable[bytes | str], *, recv_time_s: float | None = None,
                   time_offset_s: float = 0.0) -> ReportBatch:
        """Process lines in order and return the accepted reports of this call.

        The result does not depend on how a stream is cut into batches, except that the very
        first batch of a stream without a clock also primes the stream time from its own
        lines (a first line dated 2099 is then judged against the lines after it).

        Parameters
        ----------
        lines : iterable of bytes or str
            NMEA sentences, with or without tag blocks; line ends are stripped.
        recv_time_s : float, optional
            Receive time [UNIX s] for lines without a tag block ``c:`` time (counted as the
            notice ``receive_time``).
        time_offset_s : float
            Added to every time (tag block or ``recv_time_s``) [s]; file replay uses it to
            keep time increasing when it loops.

        Returns
        -------
        ReportBatch
            Accepted dynamic reports (columnar, NED) and static records, in input order.
        """
        raws = [(r if type(r) is bytes else as_bytes(r)).strip() for r in lines]
        run = self._start(raws, recv_time_s, time_offset_s)
        f_index, f_len = run.fast.index, run.fast.sentence_len
        o_next = 0
        n_lines = 0
        for i, raw in enumerate(raws):
            o = o_next
            o_next += len(raw)
            if not raw:
                continue
            n_lines += 1
            framed = self._frame(run, raw, o)  # 1. framing, tag block
            if framed is None:
                continue
            raw, o, b0, t, station = framed
            j = f_index[i]
            if j >= 0 and len(raw) - b0 == f_len[j]:  # a canonical position report
                self._position_report(run, j, raw, t, station)
            else:
                self._message(run, raw, o, b0, t, station)
        self._lines += n_lines
        return self._end(run)

    # ------------------------------------------------------------------ the stages
    def _start(self, raws: list[bytes], recv_time_s: float | None,
               time_offset_s: float) -> _Batch:
        """Read the clock, set the time references, checksum and pre-decode the batch."""
        stream = self.stream_clock
        clock_now = self._clock() if self._clock is not None else None
        if clock_now is None and stream.reference is None:
            self._prime(raws)
        ref = clock_now if clock_now is not None else stream.reference
        if recv_time_s is not None:
            recv_time_s += time_offset_s
            if T_MIN_UNIX_S <= recv_time_s <= T_MAX_UNIX_S:
                stream.observe(recv_time_s)  # receive times count once per batch
                if clock_now is None:
                    ref = stream.reference
        self.tags.set_offset(time_offset_s)  # cached tag times include the offset
        # every checksum of the batch from one prefix XOR: xor(buf[a:b]) = P[b-1] ^ P[a-1]
        P = prefix_xor(b"".join(raws))
        return _Batch(clock_now, ref,
                      self._max_future_s if clock_now is not None else self._max_jump_s,
                      clock_now - self._max_lag_s if clock_now is not None else -math.inf,
                      recv_time_s, P, scan_fast_lines(raws, P) if self._batch_decode
                      else no_fast_lines(len(raws)), self._hwm)

    def _frame(self, run: _Batch, raw: bytes, o: int
               ) -> tuple[bytes, int, int, float | None, str | None] | None:
        """1. Framing and tag block: ``(raw, o, b0, t, station)`` with the sentence at
        ``raw[b0:]`` (``raw`` after any garbage prefix, at offset ``o`` of the batch), or
        None when rejected (counted)."""
        if raw[0] not in STARTS or not raw.isascii():
            k = resync(raw)
            if k <= 0:
                self.counters.count(ErrorKind.NON_ASCII if not raw.isascii()
                                    else ErrorKind.TRUNCATED, raw,
                                    "no sentence start (\\ ! $) in clean ASCII")
                return None
            self.notices.count(NoticeKind.RESYNCED, raw,
                               f"{k} bytes of garbage before the sentence")
            raw = raw[k:]
            o += k
        if raw[0] != 92:  # no b"\\": no IEC 61162-450 tag block
            if run.recv_t is not None:
                self.notices.count(NoticeKind.RECEIVE_TIME, raw, "no tag block")
            return raw, o, 0, run.recv_t, None
        end = raw.find(b"\\", 1)
        if end < 0:
            self.counters.count(ErrorKind.TRUNCATED, raw, "tag block not closed")
            return None
        if end + 1 == len(raw):
            self.counters.count(ErrorKind.TAG_BLOCK_WITHOUT_PAYLOAD, raw)
            return None
        tag = raw[1:end]
        parsed = self.tags.get(tag)
        if parsed is None:  # a new tag (a new second or station): parse, check, cache
            parsed = self.tags.parse(tag, run.P, o)
            t_tag = parsed[0] if len(parsed) == 3 else None
            if t_tag is not None and T_MIN_UNIX_S <= t_tag <= T_MAX_UNIX_S:
                stream = self.stream_clock
                stream.recent.append(t_tag)  # robust stream time: every distinct time
                if len(stream.recent) >= 2 * stream.window:
                    stream.update()
                    if run.clock_now is None:
                        run.ref = stream.reference
        if len(parsed) == 2:  # (kind, detail): rejected
            self.counters.count(parsed[0], raw, parsed[1])
            return None
        t = parsed[0]  # offset included (the cache is per offset)
        if t is None:
            t = run.recv_t
            if t is not None:
                self.notices.count(NoticeKind.RECEIVE_TIME, raw, "tag block without c:")
        if parsed[2]:
            self.notices.count(NoticeKind.TAG_CHECKSUM_C_ONLY, raw,
                               "tag checksum over c: alone (the national feed's group "
                               "convention)")
        return raw, o, end + 1, t, parsed[1]

    def _checked_line(self, run: _Batch, t: float | None) -> None:
        """After a line's sentence checks passed: the fragment timeout, on every line whose
        time is not a lie (a line dated hours ahead must not expire other stations'
        messages), and the census."""
        frags = self.fragments
        if t is not None and t > frags.deadline and (run.ref is None or t <= run.ref + run.lead):
            frags.expire(t)
        census = self.census
        if census is not None:
            if t is not None and T_MIN_UNIX_S <= t <= T_MAX_UNIX_S:
                census.see_time(t)
            else:
                census.untimed_lines += 1

    def _position_report(self, run: _Batch, j: int, raw: bytes, t: float | None,
                         station: str | None) -> None:
        """1.-5. for row ``j`` of the batch's canonical position reports (decoded in
        :meth:`_start`; the regular expression that chose them holds the field checks)."""
        fast = run.fast
        computed, sent = fast.checksum[j]
        if computed != sent:
            self.counters.count(ErrorKind.BAD_CHECKSUM, raw, f"checksum 0x{computed:02X} "
                                f"computed, 0x{sent:02X} in the sentence")
            return
        self._checked_line(run, t)
        ais_id = fast.msg_type[j]  # 2. (one sentence: nothing to assemble)
        self._by_type[ais_id] = self._by_type.get(ais_id, 0) + 1
        mmsi = fast.mmsi[j]
        if self.census is not None:
            self.census.mmsis.add(mmsi)
        if t is not None and self._duplicate(run, fast.payload[j], t, raw):  # 3.
            return
        t = self.validator.identity_and_time(raw, mmsi, t)  # 4. decoded; 5.
        if t is not None and self.validator.position(run, raw, mmsi, t, fast.lat_deg[j],
                                                     fast.lon_deg[j]):
            run.rows.append(j)
            run.t.append(t)
            run.station.append(station)

    def _message(self, run: _Batch, raw: bytes, o: int, b0: int, t: float | None,
                 station: str | None) -> None:
        """1.-5. for a line that is not a canonical position report, with pyais."""
        count = self.counters.count
        body = raw[b0:] if b0 else raw
        star = body.rfind(b"*")
        if star < 0 or len(body) - star != 3 or body[0] not in (33, 36):  # "!" or "$"
            count(ErrorKind.TRUNCATED, raw, "sentence does not end in *hh")
            return
        try:
            expected = int(body[star + 1:], 16)
        except ValueError:
            count(ErrorKind.TRUNCATED, raw, "checksum is not hexadecimal")
            return
        P = run.P
        actual = P[o + b0 + star - 1] ^ P[o + b0]
        if actual != expected:
            count(ErrorKind.BAD_CHECKSUM, raw,
                  f"checksum 0x{actual:02X} computed, 0x{expected:02X} in the sentence")
            return
        msg = check_ais(body, star)
        if isinstance(msg, tuple):
            count(msg[0], raw, msg[1])
            return
        self._checked_line(run, t)
        if msg.frag_cnt > 1:  # 2. assembly
            done = self.fragments.add(msg, t, station, raw)
            if done is None:
                return
            msg, t, station = done
        m = self._decode(run, msg, t, raw)  # 3.-4.
        if m is None:
            return
        ais_id = msg.ais_id
        mmsi = m.mmsi
        t = self.validator.identity_and_time(raw, mmsi, t)  # 5.
        if t is None:
            return
        if ais_id == 5 or ais_id == 24 or ais_id == 19:
            run.static.append(static_record(m, ais_id, t))
            self._n_static += 1
            if ais_id != 19:
                return
        if self.validator.position(run, raw, mmsi, t, m.lat, m.lon):
            run.rows.append(-1 - len(run.slow))  # counted from the end: after the fast rows
            run.slow.append(pyais_row(m, ais_id))
            run.t.append(t)
            run.station.append(station)

    def _duplicate(self, run: _Batch, payload: bytes, t: float, raw: bytes) -> bool:
        """3. The same payload again within the window: counted, True."""
        prev = self.duplicates.is_duplicate(payload, t, run.hwm)
        if prev is None:
            return False
        self.counters.count(ErrorKind.DUPLICATE, raw, f"same payload {t - prev:.1f} s apart")
        return True

    def _decode(self, run: _Batch, msg: AISSentence, t: float | None, raw: bytes) -> Any:
        """2.-4. for a pyais message: count its type, drop duplicates, check its length and
        decode it; None for a type the twin does not use or a rejection (counted)."""
        payload = msg.payload
        ais_id = msg.ais_id
        if ais_id not in _MIN_BITS and not payload:  # (an empty payload reads as type 0)
            self.counters.count(ErrorKind.SHORT_PAYLOAD, raw, "empty payload")
            return None
        self._by_type[ais_id] = self._by_type.get(ais_id, 0) + 1
        if self.census is not None and len(msg.bv) >= 38:
            self.census.mmsis.add(msg.bv.get(8, 30))
        if ais_id not in _MIN_BITS:
            return None  # a type the twin does not use: counted by type only
        if t is not None and self._duplicate(run, payload, t, raw):
            return None
        if len(msg.bv) < _MIN_BITS[ais_id]:
            self.counters.count(ErrorKind.SHORT_PAYLOAD, raw, f"type {ais_id} needs "
                                f"{_MIN_BITS[ais_id]} bits, actually {len(msg.bv)}")
            return None
        try:
            return msg.decode()
        except _DECODE_FAILURES as exc:
            self.counters.count(ErrorKind.DECODE_ERROR, raw, str(exc)[:80])
            return None

    def _end(self, run: _Batch) -> ReportBatch:
        """6. The batch's accepted reports as columns in SI and NED; state trimmed."""
        self._hwm = run.hwm
        self._n_reports += len(run.rows)
        stream = self.stream_clock
        if run.clock_now is not None and stream.update() is not None:
            self._clock_lag_s = run.clock_now - stream.reference  # type: ignore[operator]
        self.validator.trim()
        self.duplicates.trim(self._hwm)
        static = tuple(run.static)
        if not run.rows:
            return ReportBatch.empty(static)
        fast = run.fast.columns
        rows = np.array(run.rows, np.int64)
        if run.slow:  # pyais-decoded rows go after the fast ones
            n_fast = len(fast.mmsi)
            rows = np.where(rows < 0, n_fast - 1 - rows, rows)
            slow = list(zip(*run.slow))
            cols = {k: np.concatenate((getattr(fast, k), np.array(slow[c], np.float64)))
                    for c, k in enumerate(COLUMNS)}
        else:
            cols = {k: getattr(fast, k) for k in COLUMNS}
        return report_batch({k: v[rows] for k, v in cols.items()}, run.t, run.station,
                            static, self.scene.frame)

    # ------------------------------------------------------------------ state upkeep
    def _prime(self, raws: list[bytes]) -> None:
        """Start the stream time from the tag times of a stream's first lines."""
        times = []
        for raw in raws[:256]:
            if raw[:1] == b"\\" and (end := raw.find(b"\\", 1)) > 0:
                try:
                    t = parse_tag_block(raw[1:end]).t_unix_s
                except TagBlockError:
                    continue
                if t is not None:
                    times.append(t)
        self.stream_clock.prime(times)
