"""NMEA lines -> validated AIS reports in the scene's NED frame (decode on pyais).

:class:`AisPipeline` is the one decoding path of every AIS source (TCP, UDP, file replay,
synthetic traffic, history). Per line, in order:

1. **sentence**: 7-bit ASCII, IEC 61162-450 tag block (``\\s:station,c:unix_time*hh\\``,
   checksum checked, ``c:`` in seconds or milliseconds), ``*hh`` checksum of the sentence,
   fields parsed by :class:`pyais.messages.NMEASentenceFactory`;
2. **assembly** of multi-fragment messages keyed by *(station, talker, channel, sequence id,
   fragment count)*, so interleaved messages from two stations never mix; lone, out-of-order
   and never-completed fragments are counted (pyais's own streams drop them silently and key
   without the station, hence this small assembler);
3. **duplicates**: the same payload again within ``dedup_window_s`` (one transmission heard
   by two base stations) is dropped;
4. **decode** with pyais (types 1/2/3, 5, 18, 19, 24; others are counted by type and skipped);
5. **validation**: MMSI range, "not available" values to NaN/None (lat 91, lon 181,
   SOG 102.3 kn, COG 360, heading 511, ROT -128 / +-127), position inside the scene box,
   receive time present, plausible, not behind the MMSI's last report, not in the future;
6. **projection** to the scene's NED frame, vectorised over the batch.

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
from pyais.messages import AISSentence, NMEASentenceFactory

from asvtwin.errors import ParameterError
from asvtwin.geo import Scene, default_scene
from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind, PipelineStats
from asvtwin.sources.ais.reports import AisStatic, ReportBatch
from asvtwin.units import KNOT_M_S

__all__ = ["DYNAMIC_TYPES", "STATIC_TYPES", "AisPipeline"]

#: Message types that carry a position report.
DYNAMIC_TYPES = frozenset({1, 2, 3, 18, 19})
#: Message types that carry static data.
STATIC_TYPES = frozenset({5, 19, 24})
#: Fewest payload bits each used type needs (ITU-R M.1371; type 5 tolerates 420).
_MIN_BITS = {1: 168, 2: 168, 3: 168, 18: 168, 19: 312, 5: 420, 24: 160}
_T_MIN_UNIX_S = 946_684_800.0  # 2000-01-01
_T_MAX_UNIX_S = 4_102_444_800.0  # 2100-01-01
_NAN = math.nan
_TWO_PI = 2.0 * math.pi
_DEG = math.pi / 180.0
_ROT_DEG_MIN = math.pi / 180.0 / 60.0  # deg/min -> rad/s


_BAD_TAG = object()  # cache marker: this tag block is invalid


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


class AisPipeline:
    """Decode, assemble, validate and project AIS NMEA lines (one instance per feed).

    Parameters
    ----------
    scene : Scene, optional
        Frame and bounds; :func:`asvtwin.geo.default_scene` when omitted.
    clock : callable, optional
        Returns the current UNIX time [s]. When given, reports more than ``max_future_s``
        ahead of it are rejected; without it the reference is the latest accepted time and
        the limit ``max_jump_s``.
    max_future_s : float
        Allowed lead over ``clock()`` [s] (receiver clocks drift a little).
    max_jump_s : float
        Allowed jump over the latest accepted time when there is no clock [s].
    dedup_window_s : float
        Identical payloads closer than this are one transmission heard twice [s].
    fragment_timeout_s : float
        A multi-fragment message not completed within this time is dropped [s].
    max_pending : int
        Most multi-fragment messages assembled at once (oldest dropped beyond).
    max_tracked_mmsi : int
        Most MMSIs whose last report time is kept for the time-order check.
    """

    def __init__(self, scene: Scene | None = None, *, clock: Callable[[], float] | None = None,
                 max_future_s: float = 60.0, max_jump_s: float = 6 * 3600.0,
                 dedup_window_s: float = 30.0, fragment_timeout_s: float = 10.0,
                 max_pending: int = 1024, max_tracked_mmsi: int = 200_000) -> None:
        for name, v in (("max_future_s", max_future_s), ("max_jump_s", max_jump_s),
                        ("dedup_window_s", dedup_window_s),
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
        self._dedup_s = float(dedup_window_s)
        self._frag_timeout_s = float(fragment_timeout_s)
        self._max_pending = int(max_pending)
        self._max_tracked = int(max_tracked_mmsi)
        self.counters = ErrorCounter()
        self._pending: dict[tuple[object, ...], tuple[list[AISSentence], float | None, str | None]] = {}
        self._seen: dict[bytes, float] = {}
        self._last_t: dict[int, float] = {}
        self._hwm: float | None = None  # latest accepted time [UNIX s]
        self._tag_cache: dict[bytes, Any] = {}
        self._lines = 0
        self._by_type: dict[int, int] = {}
        self._n_reports = 0
        self._n_static = 0

    # ------------------------------------------------------------------ public
    @property
    def stats(self) -> PipelineStats:
        """Counts since the start (a snapshot)."""
        return PipelineStats(lines=self._lines, messages_by_type=dict(self._by_type),
                             reports=self._n_reports, statics=self._n_static,
                             errors=dict(self.counters.counts))

    @property
    def latest_time_unix_s(self) -> float | None:
        """Latest accepted report time [UNIX s], None before the first."""
        return self._hwm

    def feed(self, line: bytes | str, *, recv_time_s: float | None = None) -> ReportBatch:
        """Process one line; see :meth:`feed_batch`."""
        return self.feed_batch((line,), recv_time_s=recv_time_s)

    def feed_batch(self, lines: Iterable[bytes | str], *, recv_time_s: float | None = None,
                   time_offset_s: float = 0.0) -> ReportBatch:
        """Process lines in order and return the accepted reports of this call.

        Parameters
        ----------
        lines : iterable of bytes or str
            NMEA sentences, with or without tag blocks; line ends are stripped.
        recv_time_s : float, optional
            Receive time [UNIX s] for lines without a tag block ``c:`` time.
        time_offset_s : float
            Added to every time (tag block or ``recv_time_s``) [s]; file replay uses it to
            keep time increasing when it loops.

        Returns
        -------
        ReportBatch
            Accepted dynamic reports (columnar, NED) and static records, in input order.
        """
        cols: tuple[list[float], ...] = ([], [], [], [], [], [], [], [], [], [])
        (c_t, c_lat, c_lon, c_sog, c_cog, c_hdg, c_rot, c_mmsi, c_type, c_nav) = cols
        c_station: list[str | None] = []
        static: list[AisStatic] = []
        count = self.counters.count
        produce = NMEASentenceFactory.produce
        by_type = self._by_type
        seen = self._seen
        last_t = self._last_t
        tags = self._tag_cache
        lat_lo, lat_hi, lon_lo, lon_hi = self._box
        dedup_s = self._dedup_s
        clock, hwm = self._clock, self._hwm
        lead = self._max_future_s if clock is not None else self._max_jump_s
        raws = [(r if type(r) is bytes else _as_bytes(r)).strip() for r in lines]
        # Checksums of every sentence and tag block from one prefix XOR over the batch:
        # xor(buf[a:b]) = P[b-1] ^ P[a-1] (NMEA: XOR of the bytes between the delimiters)
        joined = b"".join(raws)
        P = np.bitwise_xor.accumulate(np.frombuffer(joined, np.uint8)).tobytes() if joined else b""
        o_next = 0
        n_lines = 0
        for raw in raws:
            o = o_next
            o_next += len(raw)
            if not raw:
                continue
            n_lines += 1
            if not raw.isascii():
                count(ErrorKind.NON_ASCII, raw)
                continue
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
                parsed: Any = tags.get(tag)
                if parsed is None:
                    parsed = self._parse_tag(tag, P, o, raw)
                    if len(tags) > 1024:
                        tags.clear()
                    tags[tag] = parsed
                if parsed is _BAD_TAG:
                    count(ErrorKind.BAD_TAG_BLOCK, raw, "tag block checksum or c: malformed")
                    continue
                if parsed[0] is not None:
                    t = parsed[0]
                station = parsed[1]
                body = raw[b0:]
            else:
                body = raw
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
            if msg.frag_cnt > 1:
                done = self._assemble(msg, t, station, raw)
                if done is None:
                    continue
                msg, t, station = done
            ais_id = msg.ais_id
            by_type[ais_id] = by_type.get(ais_id, 0) + 1
            if ais_id not in _MIN_BITS:
                continue  # a type the twin does not use: counted by type only
            payload = msg.payload
            if t is not None:
                t += time_offset_s
                prev = seen.get(payload)
                if prev is not None:
                    if abs(t - prev) <= dedup_s:
                        count(ErrorKind.DUPLICATE, raw, f"same payload {t - prev:.1f} s apart")
                        continue
                    del seen[payload]  # re-insert at the end: the dict stays in time order
                seen[payload] = t
            if len(msg.bv) < _MIN_BITS[ais_id]:
                count(ErrorKind.SHORT_PAYLOAD, raw,
                      f"type {ais_id} needs {_MIN_BITS[ais_id]} bits, actually {len(msg.bv)}")
                continue
            try:
                m = msg.decode()
            except (AISBaseException, ValueError, IndexError, KeyError, TypeError) as exc:
                count(ErrorKind.DECODE_ERROR, raw, str(exc)[:80])
                continue
            mmsi = m.mmsi
            if not 0 < mmsi <= 999_999_999:
                count(ErrorKind.INVALID_MMSI, raw, f"MMSI in 1..999999999 expected, actually {mmsi}")
                continue
            if t is None:
                count(ErrorKind.MISSING_TIME, raw, "no tag block c: and no receive time")
                continue
            if not _T_MIN_UNIX_S <= t <= _T_MAX_UNIX_S:
                count(ErrorKind.INVALID_TIME, raw, f"time in 2000..2100 expected, actually {t}")
                continue
            if ais_id == 5 or ais_id == 24 or ais_id == 19:
                static.append(self._static(m, ais_id, t))
                self._n_static += 1
                if ais_id != 19:
                    continue
            lat = m.lat
            lon = m.lon
            if lat == 91.0 or lon == 181.0:
                count(ErrorKind.POSITION_UNAVAILABLE, raw, f"lat {lat}, lon {lon}")
                continue
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                count(ErrorKind.INVALID_POSITION, raw,
                      f"lat in [-90, 90] and lon in [-180, 180] expected, actually {lat}, {lon}")
                continue
            if not (lat_lo <= lat <= lat_hi and lon_lo <= lon <= lon_hi):
                count(ErrorKind.OUTSIDE_SCENE, raw,
                      f"lat {lat_lo}..{lat_hi}, lon {lon_lo}..{lon_hi} expected, "
                      f"actually {lat}, {lon}")
                continue
            # time order: not far ahead of the clock (or the stream), not behind this MMSI
            ref = clock() if clock is not None else hwm
            if ref is not None and t > ref + lead:
                count(ErrorKind.TIME_FUTURE, raw, f"time <= {ref + lead:.0f} expected, "
                      f"actually {t:.0f}")
                continue
            last = last_t.get(mmsi)
            if last is not None and t < last:
                count(ErrorKind.TIME_BACKWARDS, raw, f"time >= {last:.3f} (last report of "
                      f"{mmsi}) expected, actually {t:.3f}")
                continue
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
        if len(last_t) > self._max_tracked:
            self._trim_tracked()
        self._trim_seen()
        if not c_t:
            return ReportBatch.empty(tuple(static))
        lat_a = np.array(c_lat)
        lon_a = np.array(c_lon)
        north, east = self.scene.frame.to_ned(lat_a, lon_a)
        # "not available" -> NaN, units -> SI, angles -> [-pi, pi) (vectorised over the batch)
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
            static=tuple(static),
        )

    def _parse_tag(self, tag: bytes, P: bytes, o: int, raw: bytes
                   ) -> tuple[float | None, str | None] | object:
        """Check and parse a tag block (``tag`` = ``raw[1:end]``, ``raw`` at ``o`` in the batch)."""
        star = tag.rfind(b"*")
        try:
            # xor(raw[1:1 + star]) from the batch's prefix XOR P
            if star <= 0 or (P[o + star] ^ P[o]) != int(tag[star + 1:], 16):
                return _BAD_TAG
            t = None
            station = None
            for fld in tag[:star].split(b","):
                key = fld[:2]
                if key == b"c:":
                    c = float(fld[2:])
                    t = c / 1000.0 if c > 1e11 else c
                elif key == b"s:":
                    station = fld[2:].decode()
        except ValueError:
            return _BAD_TAG
        return (t, station)

    # ------------------------------------------------------------------ helpers
    def _assemble(self, msg: AISSentence, t: float | None, station: str | None, raw: bytes
                  ) -> tuple[AISSentence, float | None, str | None] | None:
        """Collect one fragment; return the assembled message when it is complete."""
        key = (station, msg.talker_id, msg.channel, msg.seq_id, msg.frag_cnt)
        pending = self._pending
        if msg.frag_num == 1:
            if key in pending:
                self.counters.count(ErrorKind.INCOMPLETE_FRAGMENT, raw,
                                    "a new message started before the last one completed")
            elif len(pending) >= self._max_pending:
                pending.pop(next(iter(pending)))
                self.counters.count(ErrorKind.INCOMPLETE_FRAGMENT, raw, "too many pending")
            self._expire_pending(t)
            pending[key] = ([msg], t, station)
            return None
        entry = pending.get(key)
        if entry is None:
            self.counters.count(ErrorKind.ORPHAN_FRAGMENT, raw,
                                f"fragment {msg.frag_num}/{msg.frag_cnt} without fragment 1")
            return None
        parts, t0, st0 = entry
        if msg.frag_num != len(parts) + 1:
            del pending[key]
            self.counters.count(ErrorKind.OUT_OF_ORDER_FRAGMENT, raw,
                                f"fragment {len(parts) + 1} expected, "
                                f"actually {msg.frag_num}/{msg.frag_cnt}")
            return None
        parts.append(msg)
        if len(parts) < msg.frag_cnt:
            return None
        del pending[key]
        whole = AISSentence.assemble_from_iterable(parts)
        return whole, (t0 if t0 is not None else t), st0

    def _expire_pending(self, t: float | None) -> None:
        """Drop pending messages older than the fragment timeout (oldest first)."""
        if t is None:
            return
        pending = self._pending
        while pending:
            key = next(iter(pending))
            t0 = pending[key][1]
            if t0 is None or t - t0 <= self._frag_timeout_s:
                break
            del pending[key]
            self.counters.count(ErrorKind.INCOMPLETE_FRAGMENT, None,
                                f"not completed within {self._frag_timeout_s} s")

    def _trim_seen(self) -> None:
        """Forget payloads older than the dedup window (the dict is in time order)."""
        seen = self._seen
        if self._hwm is None or not seen:
            return
        oldest = self._hwm - self._dedup_s
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
