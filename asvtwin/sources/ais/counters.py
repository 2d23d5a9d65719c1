"""Bad input at the AIS edge: counted by kind, logged once with context, skipped.

A live feed carries corrupt lines all day long; none of them may stop the twin, and none may
pass silently. Each rejected line or message is counted under one :class:`ErrorKind`; the
first occurrence of each kind is logged at WARNING with the offending line, the following ones
only at DEBUG. The counts are part of the pipeline's :class:`PipelineStats` and of a source's
status, so the twin's status shows them.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["ErrorCounter", "ErrorKind", "NoticeKind", "PipelineStats"]

_log = logging.getLogger("asvtwin.sources.ais")


class ErrorKind(enum.StrEnum):
    """Why an input line, message or connection was rejected."""

    # --- sentence layer
    NON_ASCII = "non_ascii"  #: bytes outside 7-bit ASCII
    TRUNCATED = "truncated"  #: no ``*hh`` checksum at the end, unclosed tag block, cut line
    BAD_CHECKSUM = "bad_checksum"  #: sentence checksum does not match
    BAD_TAG_BLOCK = "bad_tag_block"  #: tag block malformed: no ``*hh``, ``c:``/``g:`` not digits
    BAD_TAG_CHECKSUM = "bad_tag_checksum"  #: tag checksum matches neither the tag nor ``c:``
    TAG_BLOCK_WITHOUT_PAYLOAD = "tag_block_without_payload"  #: ``\\...*hh\\`` and nothing after
    MALFORMED = "malformed"  #: fields missing or out of range (fragment numbers, fill bits)
    NOT_AIS = "not_ais"  #: a valid NMEA sentence that is not VDM/VDO
    OWN_SHIP = "own_ship"  #: ``!xxVDO``: the own ship's transponder, never a target
    # --- fragment assembly
    ORPHAN_FRAGMENT = "orphan_fragment"  #: a later fragment without its first one
    OUT_OF_ORDER_FRAGMENT = "out_of_order_fragment"  #: fragment number skips or repeats
    INCOMPLETE_FRAGMENT = "incomplete_fragment"  #: message never completed (timed out/replaced)
    # --- payload
    SHORT_PAYLOAD = "short_payload"  #: fewer bits than the message type needs
    DECODE_ERROR = "decode_error"  #: a character outside the AIS 6-bit alphabet, or pyais failed
    INVALID_MMSI = "invalid_mmsi"  #: MMSI 0 or above 999 999 999
    POSITION_UNAVAILABLE = "position_unavailable"  #: lat 91 / lon 181 in a position report
    INVALID_POSITION = "invalid_position"  #: |lat| > 90 or |lon| > 180
    OUTSIDE_SCENE = "outside_scene"  #: valid position outside the scene's box
    # --- time
    MISSING_TIME = "missing_time"  #: neither a tag block time nor a receive time
    INVALID_TIME = "invalid_time"  #: before 2000 or after 2100
    TIME_BACKWARDS = "time_backwards"  #: older than the last accepted report of that MMSI
    TIME_FUTURE = "time_future"  #: too far ahead of the clock / the stream
    DUPLICATE = "duplicate"  #: same payload again within the window (two base stations)
    # --- transport
    CONNECT_FAILED = "connect_failed"  #: TCP connect refused or timed out
    DISCONNECTED = "disconnected"  #: the peer closed or reset the connection
    SILENT_FEED = "silent_feed"  #: no data for longer than the silence timeout
    QUEUE_OVERFLOW = "queue_overflow"  #: datagrams dropped because the consumer lags
    KERNEL_DROP = "kernel_drop"  #: datagrams the kernel dropped (socket buffer full)
    LINE_TOO_LONG = "line_too_long"  #: a TCP line longer than the limit (counted once)


class NoticeKind(enum.StrEnum):
    """Input accepted, but not as the standard says: counted so an operator sees it."""

    #: group tag checksum over ``c:`` alone (the national feed's convention)
    TAG_CHECKSUM_C_ONLY = "tag_checksum_c_only"
    RESYNCED = "resynced"  #: garbage before ``\\``/``!`` skipped, the sentence after it kept
    RECEIVE_TIME = "receive_time"  #: no tag time: stamped with the receive clock
    UNTIMED = "untimed"  #: no time at all, accepted because the pipeline does not require one
    OUTSIDE_SCENE_KEPT = "outside_scene_kept"  #: outside the scene box, kept (bounds off)
    CLOCK_LAG = "feed_clock_lags"  #: report time far behind the receive clock (kept)


@dataclass(frozen=True)
class PipelineStats:
    """Counts since the pipeline started (a snapshot, immutable).

    Attributes
    ----------
    lines : int
        Non-blank input lines seen.
    messages_by_type : Mapping[int, int]
        Assembled AIS messages by message type (all types, used or not).
    reports : int
        Dynamic reports accepted.
    statics : int
        Static records accepted.
    errors : Mapping[str, int]
        Rejections by :class:`ErrorKind` value.
    notices : Mapping[str, int]
        Accepted input that deviates from the standard, by :class:`NoticeKind` value.
    stream_time_unix_s : float or None
        Robust current time of the stream [UNIX s] (see :class:`StreamClock`).
    clock_lag_s : float or None
        Receive clock minus stream time [s] at the last batch (live feeds only): a feed whose
        tag times lag by years shows here.
    pending_fragments : int
        Multi-sentence messages still waiting for fragments.
    """

    lines: int
    messages_by_type: Mapping[int, int]
    reports: int
    statics: int
    errors: Mapping[str, int] = field(default_factory=dict)
    notices: Mapping[str, int] = field(default_factory=dict)
    stream_time_unix_s: float | None = None
    clock_lag_s: float | None = None
    pending_fragments: int = 0

    @property
    def total_errors(self) -> int:
        """Sum of all rejections."""
        return sum(self.errors.values())

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-ready dictionary."""
        return {
            "lines": self.lines,
            "messages_by_type": {str(k): v for k, v in sorted(self.messages_by_type.items())},
            "reports": self.reports,
            "statics": self.statics,
            "errors": dict(sorted(self.errors.items())),
            "notices": dict(sorted(self.notices.items())),
            "stream_time_unix_s": self.stream_time_unix_s,
            "clock_lag_s": self.clock_lag_s,
            "pending_fragments": self.pending_fragments,
        }


class ErrorCounter:
    """Counts rejections by kind and logs the first of each kind once.

    Parameters
    ----------
    logger : logging.Logger, optional
        Where to log; ``asvtwin.sources.ais`` by default.
    what : str
        How the log names a counted event ("rejected", or "accepted with a quirk").
    """

    def __init__(self, logger: logging.Logger | None = None, *, what: str = "rejected") -> None:
        self._counts: dict[str, int] = {}
        self._log = logger or _log
        self._what = what

    def count(self, kind: ErrorKind | NoticeKind, context: object = None,
              detail: str = "", n: int = 1) -> None:
        """Count one rejection of ``kind``; log it if it is the first of its kind.

        Parameters
        ----------
        kind : ErrorKind
            Why the input was rejected.
        context : object, optional
            The offending line or message (shown, shortened, in the log).
        detail : str
            Expected versus actual, e.g. ``"checksum 0x34 expected, actually 0x35"``.
        n : int
            How many (a kernel's drop counter reports many at once).
        """
        key = kind.value
        before = self._counts.get(key, 0)
        self._counts[key] = before + n
        if before == 0:
            ctx = context.decode("ascii", "backslashreplace") if isinstance(context, bytes) \
                else ("" if context is None else str(context))
            if len(ctx) > 160:
                ctx = ctx[:157] + "..."
            self._log.warning("AIS input %s (%s, first of its kind, further ones counted "
                              "silently): %s%s", self._what, key, detail + ": " if detail else "",
                              ctx)
        else:
            self._log.debug("AIS input %s (%s): %s", self._what, key, detail)

    def __getitem__(self, kind: ErrorKind | NoticeKind | str) -> int:
        return self._counts.get(str(kind), 0)

    @property
    def counts(self) -> Mapping[str, int]:
        """Read-only copy of the counts by kind."""
        return MappingProxyType(dict(self._counts))

    def total(self) -> int:
        """Sum over all kinds."""
        return sum(self._counts.values())
