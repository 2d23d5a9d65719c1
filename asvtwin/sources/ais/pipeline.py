"""NMEA lines -> validated AIS reports in the scene's NED frame (decode on pyais).

:class:`AisPipeline` is the one decoding path of every AIS source (TCP, UDP, file replay,
synthetic traffic, history). Per line, in order:

1. **sentence**: 7-bit ASCII (a garbage prefix is skipped up to the next ``\\`` or ``!``),
   IEC 61162-450 tag block (:mod:`~asvtwin.sources.ais.tagblock`: ``\\s:station,c:time*hh\\``,
   checksum over the whole tag or, the national feed's group convention, over ``c:`` alone),
   ``*hh`` checksum of the sentence, fields parsed by
   :class:`pyais.messages.NMEASentenceFactory`, fill bits one digit 0..5, every payload
   character in the AIS 6-bit alphabet; ``!xxVDO`` (the own ship) is not a target;
2. **assembly** of multi-fragment messages (:class:`FragmentAssembler`), the timeout checked
   on every timed line and at the end of a stream (:meth:`AisPipeline.finish`);
3. **duplicates**: the same payload again within ``dedup_window_s`` (one transmission heard
   by two base stations) is dropped;
4. **decode** with pyais (types 1/2/3, 5, 18, 19, 24; others are counted by type and skipped);
5. **validation**: MMSI range, "not available" values to NaN/None (lat 91, lon 181,
   SOG 102.3 kn, COG 360, heading 511, ROT -128 / +-127), position inside the scene box,
   receive time present, plausible, not behind the MMSI's last report, not in the future
   (ahead of the receive clock, or of the robust stream time :class:`StreamClock`, which no
   single report can move);
6. **projection** to the scene's NED frame, vectorised over the batch.

Every rejection is counted by :class:`~asvtwin.sources.ais.counters.ErrorKind`, logged once,
and skipped. Time comes from tag blocks or from ``recv_time_s`` passed by the caller; the
pipeline reads no clock except the optional ``clock`` callable given to it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pyais.exceptions import AISBaseException
from pyais.messages import NMEASentenceFactory

from asvtwin.errors import ParameterError
from asvtwin.geo import Scene, default_scene
from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind, NoticeKind, PipelineStats
from asvtwin.sources.ais.fragments import FragmentAssembler
from asvtwin.sources.ais.reports import AisStatic, ReportBatch
from asvtwin.sources.ais.tagblock import TagBlockError, parse_tag_block, parse_tag_block_time
from asvtwin.sources.ais.timebase import T_MAX_UNIX_S, T_MIN_UNIX_S, StreamClock
from asvtwin.units import KNOT_M_S

__all__ = ["DYNAMIC_TYPES", "STATIC_TYPES", "AisPipeline", "LogCensus"]

#: Message types that carry a position report.
DYNAMIC_TYPES = frozenset({1, 2, 3, 18, 19})
#: Message types that carry static data.
STATIC_TYPES = frozenset({5, 19, 24})
#: Fewest payload bits each used type needs (ITU-R M.1371; type 5 tolerates 420).
_MIN_BITS = {1: 168, 2: 168, 3: 168, 18: 168, 19: 312, 5: 420, 24: 160}
_NAN = math.nan
_TWO_PI = 2.0 * math.pi
_DEG = math.pi / 180.0
_ROT_DEG_MIN = math.pi / 180.0 / 60.0  # deg/min -> rad/s
#: The AIS 6-bit armouring alphabet (ITU-R M.1371 / IEC 61162-1): "0".."W" and "`".."w".
_ARMOUR = bytes(range(48, 88)) + bytes(range(96, 120))
_STARTS = b"\\!$"


def _as_bytes(line: object) -> bytes:
    if isinstance(line, str):
        return line.encode("utf-8", "surrogateescape")
    return bytes(line)  # type: ignore[call-overload]


def _text(value: object) -> str | None:
    """AIS 6-bit text without the ``@`` padding and blanks; None when empty."""
    if not isinstance(value, str):
        return None
    s = value.replace("@", " ").strip()
    return s or None


def _positive_or_none(value: object) -> int | None:
    return int(value) if isinstance(value, int) and value > 0 else None  # type: ignore[arg-type]


def _resync(raw: bytes) -> int:
    """Where a sentence starts after a garbage prefix, or -1: the first ``\\`` or ``!`` (AIS
    lines start so), else the first ``$``. Only the part after the last non-ASCII byte is
    searched (the sentence must be clean ASCII)."""
    start = 0
    if not raw.isascii():
        start = max(i for i, b in enumerate(raw) if b > 127) + 1
    found = [k for k in (raw.find(b"\\", start), raw.find(b"!", start)) if k >= 0]
    if not found:
        return raw.find(b"$", start)
    k = min(found)
    # a backslash right before "!" closes a tag block the garbage cut: keep the sentence
    return k + 1 if raw[k] == 92 and raw[k + 1:k + 2] == b"!" else k


@dataclass
class LogCensus:
    """What a log holds regardless of the twin's filters (``AisPipeline(census=True)``).

    Attributes
    ----------
    mmsis : set of int
        The MMSI of every assembled message with a checksum-valid sentence, of any type.
    t_first_unix_s, t_last_unix_s : float or None
        Earliest and latest plausible (2000..2100) tag-block time of any checksum-valid line.
    timed_lines, untimed_lines : int
        Checksum-valid sentences with and without a tag-block time.
    """

    mmsis: set[int] = field(default_factory=set)
    t_first_unix_s: float | None = None
    t_last_unix_s: float | None = None
    timed_lines: int = 0
    untimed_lines: int = 0

    def see_time(self, t: float) -> None:
        self.timed_lines += 1
        if self.t_first_unix_s is None or t < self.t_first_unix_s:
            self.t_first_unix_s = t
        if self.t_last_unix_s is None or t > self.t_last_unix_s:
            self.t_last_unix_s = t


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
    """

    def __init__(self, scene: Scene | None = None, *, clock: Callable[[], float] | None = None,
                 max_future_s: float = 60.0, max_jump_s: float = 600.0,
                 max_lag_s: float = 600.0, dedup_window_s: float = 30.0,
                 fragment_timeout_s: float = 10.0, max_pending: int = 1024,
                 max_tracked_mmsi: int = 200_000, bounds: bool = True,
                 require_time: bool = True, census: bool = False) -> None:
        for name, v in (("max_future_s", max_future_s), ("max_jump_s", max_jump_s),
                        ("max_lag_s", max_lag_s), ("dedup_window_s", dedup_window_s),
                        ("fragment_timeout_s", fragment_timeout_s)):
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"AisPipeline: {name} must be finite and >= 0, actually: {v}")
        for name, n in (("max_pending", max_pending), ("max_tracked_mmsi", max_tracked_mmsi)):
            if n < 1:
                raise ParameterError(f"AisPipeline: {name} must be >= 1, actually: {n}")
        self.scene = scene if scene is not None else default_scene()
        b = self.scene.bounds
        self._box = (b.lat_min_deg, b.lat_max_deg, b.lon_min_deg, b.lon_max_deg)
        self._clock = clock
        self._max_future_s = float(max_future_s)
        self._max_jump_s = float(max_jump_s)
        self._max_lag_s = float(max_lag_s)
        self._dedup_s = float(dedup_window_s)
        self._max_tracked = int(max_tracked_mmsi)
        self._bounds = bool(bounds)
        self._require_time = bool(require_time)
        self.census: LogCensus | None = LogCensus() if census else None
        self.counters = ErrorCounter()
        self.notices = ErrorCounter(what="accepted with a quirk")
        self.fragments = FragmentAssembler(self.counters, timeout_s=fragment_timeout_s,
                                           max_pending=max_pending)
        self.stream_clock = StreamClock()
        self._seen: dict[bytes, float] = {}
        self._last_t: dict[int, float] = {}
        self._hwm: float | None = None  # latest accepted report time [UNIX s]
        self._tag_cache: dict[bytes, tuple[Any, ...]] = {}  # (t + offset, station, c_only)
        self._bad_tag_cache: dict[bytes, tuple[Any, ...]] = {}  # (ErrorKind, detail)
        self._tag_offset = 0.0
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
        return self._dedup_s

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
        # The stages of the module docstring, inline: this loop runs ~100 000 times a second
        # and a function call per stage would cost a third of the time budget over pyais.
        cols: tuple[list[Any], ...] = ([], [], [], [], [], [], [], [], [], [], [])
        (c_t, c_lat, c_lon, c_sog, c_cog, c_hdg, c_rot, c_mmsi, c_type, c_nav,
         c_station) = cols
        static: list[AisStatic] = []
        count = self.counters.count
        notice = self.notices.count
        produce = NMEASentenceFactory.produce
        by_type = self._by_type
        seen = self._seen
        last_t = self._last_t
        tags = self._tag_cache
        bad_tags = self._bad_tag_cache
        frags = self.fragments
        census = self.census
        stream = self.stream_clock
        recent = stream.recent
        n_recent_max = 2 * stream.window
        lat_lo, lat_hi, lon_lo, lon_hi = self._box
        starts, armour, min_bits = _STARTS, _ARMOUR, _MIN_BITS  # locals: read per line
        t_min, t_max = T_MIN_UNIX_S, T_MAX_UNIX_S
        bounds = self._bounds
        dedup_s = self._dedup_s
        hwm = self._hwm
        raws = [(r if type(r) is bytes else _as_bytes(r)).strip() for r in lines]
        clock_now = self._clock() if self._clock is not None else None
        if clock_now is None and stream.reference is None:
            self._prime(raws)
        ref: Any = clock_now if clock_now is not None else stream.reference  # float or None
        lead = self._max_future_s if clock_now is not None else self._max_jump_s
        lag_limit = clock_now - self._max_lag_s if clock_now is not None else -math.inf
        if recv_time_s is not None:
            recv_time_s += time_offset_s
            if T_MIN_UNIX_S <= recv_time_s <= T_MAX_UNIX_S:
                stream.observe(recv_time_s)  # receive times count once per batch
                if clock_now is None:
                    ref = stream.reference
        if time_offset_s != self._tag_offset:  # cached tag times include the offset
            tags.clear()
            self._tag_offset = time_offset_s
        # Checksums of every sentence and tag block from one prefix XOR over the batch:
        # xor(buf[a:b]) = P[b-1] ^ P[a-1] (NMEA: XOR of the bytes between the delimiters)
        joined = b"".join(raws)
        P = np.bitwise_xor.accumulate(np.frombuffer(joined, np.uint8)).tobytes() if joined else b""
        o_next = 0
        n_lines = 0
        t: Any  # float or None (the hot loop narrows by hand)
        for raw in raws:
            o = o_next
            o_next += len(raw)
            if not raw:
                continue
            n_lines += 1
            # --- 1. sentence: ASCII, resync after garbage, tag block, checksum, fields
            if raw[0] not in starts or not raw.isascii():
                k = _resync(raw)
                if k <= 0:
                    count(ErrorKind.NON_ASCII if not raw.isascii() else ErrorKind.TRUNCATED,
                          raw, "no sentence start (\\ ! $) in clean ASCII")
                    continue
                notice(NoticeKind.RESYNCED, raw, f"{k} bytes of garbage before the sentence")
                raw = raw[k:]
                o += k
            t = recv_time_s
            station = None
            b0 = 0  # where the sentence starts in raw
            if raw[0] == 92:  # b"\\": IEC 61162-450 tag block
                end = raw.find(b"\\", 1)
                if end < 0:
                    count(ErrorKind.TRUNCATED, raw, "tag block not closed")
                    continue
                b0 = end + 1
                if b0 == len(raw):
                    count(ErrorKind.TAG_BLOCK_WITHOUT_PAYLOAD, raw)
                    continue
                tag = raw[1:end]
                parsed = tags.get(tag)
                if parsed is None:  # a new tag (a new second or station): parse, check, cache
                    parsed = bad_tags.get(tag)
                    if parsed is None:
                        parsed = self._parse_tag(tag, P, o, time_offset_s)
                        cache = bad_tags if len(parsed) == 2 else tags
                        if len(cache) > 1024:
                            cache.clear()
                        cache[tag] = parsed
                        t_tag = parsed[0] if len(parsed) == 3 else None
                        if t_tag is not None and t_min <= t_tag <= t_max:
                            recent.append(t_tag)  # robust stream time: every distinct time
                            if len(recent) >= n_recent_max:
                                stream.update()
                                if clock_now is None:
                                    ref = stream.reference
                    if len(parsed) == 2:  # (kind, detail): rejected
                        count(parsed[0], raw, parsed[1])
                        continue
                if parsed[0] is not None:
                    t = parsed[0]  # offset included (the caches are per offset)
                elif t is not None:
                    notice(NoticeKind.RECEIVE_TIME, raw, "tag block without c:")
                station = parsed[1]
                if parsed[2]:
                    notice(NoticeKind.TAG_CHECKSUM_C_ONLY, raw,
                           "tag checksum over c: alone (the national feed's group convention)")
                body = raw[b0:]
            else:
                body = raw
                if t is not None:
                    notice(NoticeKind.RECEIVE_TIME, raw, "no tag block")
            star = body.rfind(b"*")
            if star < 0 or len(body) - star != 3 or body[0] not in (33, 36):  # "!" or "$"
                count(ErrorKind.TRUNCATED, raw, "sentence does not end in *hh")
                continue
            try:
                expected = int(body[star + 1:], 16)
            except ValueError:
                count(ErrorKind.TRUNCATED, raw, "checksum is not hexadecimal")
                continue
            actual = P[o + b0 + star - 1] ^ P[o + b0]
            if actual != expected:
                count(ErrorKind.BAD_CHECKSUM, raw,
                      f"checksum 0x{actual:02X} computed, 0x{expected:02X} in the sentence")
                continue
            try:
                msg: Any = produce(body)
            except AISBaseException as exc:
                kind = ErrorKind.NOT_AIS if type(exc).__name__ == "UnknownMessageException" \
                    else ErrorKind.MALFORMED
                count(kind, raw, str(exc)[:80])
                continue
            if msg.TYPE != "AIS":
                count(ErrorKind.NOT_AIS, raw)
                continue
            if body[5] == 79:  # "!xxVDO": the own ship's transponder
                count(ErrorKind.OWN_SHIP, raw, "VDO is the own ship's report, not a target")
                continue
            if body[star - 2] != 44 or not 48 <= body[star - 1] <= 53:  # pyais reads "x" as 0
                count(ErrorKind.MALFORMED, raw, "fill bits must be one digit 0..5")
                continue
            if msg.payload.translate(None, armour):
                bad = msg.payload.translate(None, armour)[:1].decode("ascii", "replace")
                count(ErrorKind.DECODE_ERROR, raw,
                      f"payload character {bad!r} is outside the AIS 6-bit alphabet")
                continue
            # the fragment timeout, on every line whose time is not a lie (a line dated hours
            # ahead must not expire other stations' messages)
            if t is not None and t > frags.deadline and (ref is None or t <= ref + lead):
                frags.expire(t)
            if census is not None:
                if t is not None and t_min <= t <= t_max:
                    census.see_time(t)
                else:
                    census.untimed_lines += 1
            # --- 2. assembly
            if msg.frag_cnt > 1:
                done = frags.add(msg, t, station, raw)
                if done is None:
                    continue
                msg, t, station = done
            payload = msg.payload
            ais_id = msg.ais_id
            if ais_id not in min_bits and not payload:  # (an empty payload reads as type 0)
                count(ErrorKind.SHORT_PAYLOAD, raw, "empty payload")
                continue
            by_type[ais_id] = by_type.get(ais_id, 0) + 1
            if census is not None and len(msg.bv) >= 38:
                census.mmsis.add(msg.bv.get(8, 30))
            if ais_id not in min_bits:
                continue  # a type the twin does not use: counted by type only
            # --- 3. duplicates (the hwm test keeps this independent of the batch size: the
            # trim at the end of a batch only drops payloads this test would ignore anyway)
            if t is not None:
                prev = seen.get(payload)
                if prev is not None:
                    if abs(t - prev) <= dedup_s and (hwm is None or prev >= hwm - 2 * dedup_s):
                        count(ErrorKind.DUPLICATE, raw, f"same payload {t - prev:.1f} s apart")
                        continue
                    del seen[payload]  # re-insert at the end: the dict stays in time order
                seen[payload] = t
            # --- 4. decode
            if len(msg.bv) < min_bits[ais_id]:
                count(ErrorKind.SHORT_PAYLOAD, raw,
                      f"type {ais_id} needs {min_bits[ais_id]} bits, actually {len(msg.bv)}")
                continue
            try:
                m = msg.decode()
            except (AISBaseException, ValueError, IndexError, KeyError, TypeError) as exc:
                count(ErrorKind.DECODE_ERROR, raw, str(exc)[:80])
                continue
            # --- 5. validation
            mmsi = m.mmsi
            if not 0 < mmsi <= 999_999_999:
                count(ErrorKind.INVALID_MMSI, raw, f"MMSI in 1..999999999 expected, actually {mmsi}")
                continue
            timed = t is not None
            if not timed:
                if self._require_time:
                    count(ErrorKind.MISSING_TIME, raw, "no tag block c: and no receive time")
                    continue
                notice(NoticeKind.UNTIMED, raw, "no time: accepted without time checks")
                t = _NAN
            elif not t_min <= t <= t_max:
                count(ErrorKind.INVALID_TIME, raw, f"time in 2000..2100 expected, actually {t}")
                continue
            if ais_id == 5 or ais_id == 24 or ais_id == 19:
                static.append(self._static(m, ais_id, t))
                self._n_static += 1
                if ais_id != 19:
                    continue
            lat = m.lat
            lon = m.lon
            # inside the scene's box (the usual case) is valid and available; outside it, why
            if not (lat_lo <= lat <= lat_hi and lon_lo <= lon <= lon_hi):
                if lat == 91.0 or lon == 181.0:
                    count(ErrorKind.POSITION_UNAVAILABLE, raw, f"lat {lat}, lon {lon}")
                    continue
                if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                    count(ErrorKind.INVALID_POSITION, raw, "lat in [-90, 90] and lon in "
                          f"[-180, 180] expected, actually {lat}, {lon}")
                    continue
                if bounds:
                    count(ErrorKind.OUTSIDE_SCENE, raw,
                          f"lat {lat_lo}..{lat_hi}, lon {lon_lo}..{lon_hi} expected, "
                          f"actually {lat}, {lon}")
                    continue
                notice(NoticeKind.OUTSIDE_SCENE_KEPT, raw, "outside the scene box, kept")
            if timed:  # time order, not far ahead of the clock or the stream
                if ref is not None and t > ref + lead:
                    if clock_now is None:
                        ref = stream.update()  # recompute before rejecting (quiet feeds)
                    if t > ref + lead:
                        count(ErrorKind.TIME_FUTURE, raw, f"time <= {ref + lead:.0f} expected "
                              f"({'receive clock' if clock_now is not None else 'stream time'}"
                              f" + {lead:g} s), actually {t:.0f}")
                        continue
                last = last_t.get(mmsi)
                if last is not None and t < last:
                    count(ErrorKind.TIME_BACKWARDS, raw, f"time >= {last:.3f} (last report of "
                          f"{mmsi}) expected, actually {t:.3f}")
                    continue
                if t < lag_limit:
                    notice(NoticeKind.CLOCK_LAG, raw, f"{clock_now - t:.0f} s behind the "
                           "receive clock")
                last_t[mmsi] = t
                if hwm is None or t > hwm:
                    hwm = t
            c_t.append(t)
            c_lat.append(lat)
            c_lon.append(lon)
            c_sog.append(m.speed)
            c_cog.append(m.course)
            c_hdg.append(m.heading)
            if ais_id <= 3:
                c_rot.append(m.turn)  # deg/min; TurnRate ±127/-128 (no value) float as such
                c_nav.append(m.status)
            else:
                c_rot.append(_NAN)
                c_nav.append(15)
            c_mmsi.append(mmsi)
            c_type.append(ais_id)
            c_station.append(station)
        self._lines += n_lines
        self._hwm = hwm
        self._n_reports += len(c_t)
        if clock_now is not None and stream.update() is not None:
            self._clock_lag_s = clock_now - stream.reference  # type: ignore[operator]
        if len(last_t) > self._max_tracked:
            self._trim_tracked()
        self._trim_seen()
        if not c_t:
            return ReportBatch.empty(tuple(static))
        return self._batch(cols, tuple(static))

    # ------------------------------------------------------------------ stages off the hot path
    def _batch(self, cols: tuple[list[Any], ...], static: tuple[AisStatic, ...]) -> ReportBatch:
        """6. Columns -> SI, "not available" -> NaN, projection to NED (vectorised)."""
        (c_t, c_lat, c_lon, c_sog, c_cog, c_hdg, c_rot, c_mmsi, c_type, c_nav,
         c_station) = cols
        lat_a = np.array(c_lat)
        lon_a = np.array(c_lon)
        north, east = self.scene.frame.to_ned(lat_a, lon_a)
        sog = np.array(c_sog)
        cog = np.array(c_cog)
        hdg = np.array(c_hdg, dtype=np.float64)
        rot = np.array(c_rot, dtype=np.float64)
        nav = np.array(c_nav, dtype=np.int64)
        return ReportBatch(
            mmsi=np.array(c_mmsi, dtype=np.int64), t_unix_s=np.array(c_t),
            msg_type=np.array(c_type, dtype=np.int64), north_m=north, east_m=east,
            lat_deg=lat_a, lon_deg=lon_a,
            sog_m_s=np.where(sog >= 102.3, np.nan, sog * KNOT_M_S),
            cog_rad=np.where(cog >= 360.0, np.nan, (cog * _DEG + np.pi) % _TWO_PI - np.pi),
            heading_rad=np.where(hdg >= 360.0, np.nan, (hdg * _DEG + np.pi) % _TWO_PI - np.pi),
            # decoded ROT is round((k / 4.733)^2) deg/min (k <= 126), never 127 or 128: those
            # are pyais's TurnRate values for "no turn information" / "turning, no value"
            rot_rad_s=np.where(np.isin(np.abs(rot), (127.0, 128.0)), np.nan, rot * _ROT_DEG_MIN),
            nav_status=np.where(nav == 15, -1, nav), station=tuple(c_station),
            static=static, frame=self.scene.frame,
        )

    @staticmethod
    def _parse_tag(tag: bytes, P: bytes, o: int, offset: float) -> tuple[Any, ...]:
        """A tag block as ``(t + offset, station, c_only)`` or ``(ErrorKind, detail)``
        (cached); ``tag`` is ``raw[1:end]`` of the line at offset ``o`` of the batch's prefix
        XOR ``P``."""
        star = tag.rfind(b"*")
        whole = (P[o + star] ^ P[o]) if star > 0 else None  # xor(raw[1:1 + star])
        if whole is not None and len(tag) - star == 3:
            # the common form "s:station,c:digits" with the standard checksum, parsed here
            # (this path runs for a third of a feed's lines: each new second and station)
            fields = tag[:star].split(b",")
            if len(fields) == 2 and fields[0][:2] == b"s:" and fields[1][:2] == b"c:":
                c = fields[1][2:]
                try:
                    ok = c.isdigit() and len(c) <= 16 and int(tag[star + 1:], 16) == whole
                except ValueError:
                    ok = False
                if ok:
                    secs = float(c)
                    return ((secs / 1000.0 if secs > 1e11 else secs) + offset,
                            fields[0][2:].decode("ascii", "backslashreplace"), False)
        try:
            t, station, c_only = parse_tag_block_time(tag, whole)
        except TagBlockError as exc:
            return (ErrorKind.BAD_TAG_CHECKSUM if exc.checksum else ErrorKind.BAD_TAG_BLOCK,
                    str(exc))
        return (None if t is None else t + offset, station, c_only)

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

    def _trim_seen(self) -> None:
        """Forget payloads older than the dedup window (the dict is in time order)."""
        seen = self._seen
        if self._hwm is None or not seen:
            return
        oldest = self._hwm - 2 * self._dedup_s
        # one pass, then delete: next(iter(seen)) after each deletion would rescan the freed
        # slots at the front of the dict every time (quadratic in the payloads per batch)
        stale = []
        for payload, t in seen.items():
            if t >= oldest:
                break
            stale.append(payload)
        for payload in stale:
            del seen[payload]
        if len(seen) > 200_000:  # a pathological feed (times far apart): start afresh
            seen.clear()

    def _trim_tracked(self) -> None:
        """Forget the MMSIs heard longest ago (keeps memory bounded under MMSI churn)."""
        items = sorted(self._last_t.items(), key=lambda kv: kv[1])
        self._last_t = dict(items[len(items) // 2:])

    @staticmethod
    def _static(m: object, ais_id: int, t: float) -> AisStatic:
        g = m.__getattribute__
        draught = g("draught") if ais_id == 5 else None
        imo = g("imo") if ais_id == 5 else None
        has_dims = hasattr(m, "to_bow")
        return AisStatic(
            mmsi=int(g("mmsi")), t_unix_s=t, msg_type=ais_id,
            name=_text(getattr(m, "shipname", None)),
            callsign=_text(getattr(m, "callsign", None)),
            ship_type=_positive_or_none(int(st)) if (st := getattr(m, "ship_type", None)) is not None else None,
            imo=_positive_or_none(imo),
            to_bow_m=_positive_or_none(g("to_bow")) if has_dims else None,
            to_stern_m=_positive_or_none(g("to_stern")) if has_dims else None,
            to_port_m=_positive_or_none(g("to_port")) if has_dims else None,
            to_starboard_m=_positive_or_none(g("to_starboard")) if has_dims else None,
            draught_m=float(draught) if draught else None,
            destination=_text(getattr(m, "destination", None)),
        )
