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

__all__ = ["ErrorCounter", "ErrorKind", "PipelineStats"]

_log = logging.getLogger("asvtwin.sources.ais")


class ErrorKind(enum.StrEnum):
    """Why an input line, message or connection was rejected."""

    # --- sentence layer
    NON_ASCII = "non_ascii"  #: bytes outside 7-bit ASCII
    TRUNCATED = "truncated"  #: no ``*hh`` checksum at the end, unclosed tag block, cut line
    BAD_CHECKSUM = "bad_checksum"  #: sentence checksum does not match
    BAD_TAG_BLOCK = "bad_tag_block"  #: tag block checksum or field malformed
    TAG_BLOCK_WITHOUT_PAYLOAD = "tag_block_without_payload"  #: ``\\...*hh\\`` and nothing after
    MALFORMED = "malformed"  #: fields missing or out of range (fragment numbers, fill bits)
    NOT_AIS = "not_ais"  #: a valid NMEA sentence that is not VDM/VDO
    # --- fragment assembly
    ORPHAN_FRAGMENT = "orphan_fragment"  #: a later fragment without its first one
    OUT_OF_ORDER_FRAGMENT = "out_of_order_fragment"  #: fragment number skips or repeats
    INCOMPLETE_FRAGMENT = "incomplete_fragment"  #: message never completed (timed out/replaced)
    # --- payload
    SHORT_PAYLOAD = "short_payload"  #: fewer bits than the message type needs
    DECODE_ERROR = "decode_error"  #: pyais could not decode the payload
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
    """

    lines: int
    messages_by_type: Mapping[int, int]
    reports: int
    statics: int
    errors: Mapping[str, int] = field(default_factory=dict)

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
        }


class ErrorCounter:
    """Counts rejections by kind and logs the first of each kind once.

    Parameters
    ----------
    logger : logging.Logger, optional
        Where to log; ``asvtwin.sources.ais`` by default.
    """

    def __init__(self, logger: logging.Logger | None = None) -> None:
        self._counts: dict[str, int] = {}
        self._log = logger or _log

    def count(self, kind: ErrorKind, context: object = None, detail: str = "") -> None:
        """Count one rejection of ``kind``; log it if it is the first of its kind.

        Parameters
        ----------
        kind : ErrorKind
            Why the input was rejected.
        context : object, optional
            The offending line or message (shown, shortened, in the log).
        detail : str
            Expected versus actual, e.g. ``"checksum 0x34 expected, actually 0x35"``.
        """
        key = kind.value
        n = self._counts.get(key, 0) + 1
        self._counts[key] = n
        if n == 1:
            ctx = context.decode("ascii", "backslashreplace") if isinstance(context, bytes) \
                else ("" if context is None else str(context))
            if len(ctx) > 160:
                ctx = ctx[:157] + "..."
            self._log.warning("AIS input rejected (%s, first of its kind, further ones counted "
                              "silently): %s%s", key, detail + ": " if detail else "", ctx)
        else:
            self._log.debug("AIS input rejected (%s): %s", key, detail)

    def __getitem__(self, kind: ErrorKind | str) -> int:
        return self._counts.get(str(kind), 0)

    @property
    def counts(self) -> Mapping[str, int]:
        """Read-only copy of the counts by kind."""
        return MappingProxyType(dict(self._counts))

    def total(self) -> int:
        """Sum over all kinds."""
        return sum(self._counts.values())
