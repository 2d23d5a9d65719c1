"""Stream time that no single report can move: the reference for "in the future" checks.

A feed's tag times are mostly right, but one corrupt or mis-set transmitter (a valid line
dated three hours or eighty years ahead) must neither wipe the target picture nor freeze the
replay. :class:`StreamClock` keeps the plausible times of the last messages and answers with
an upper order statistic of the latest ``window`` of them (by default the 4th largest of 32):

- robust: fewer than ``rank`` outliers among ``window`` messages never move it;
- current: in a quiet feed (a message a minute) the 4th largest is about 3 messages old, where
  a median would lag half the window (16 minutes) and reject the feed's own new reports;
- a real jump (a receiver restarted after hours, two logs concatenated) moves it once
  ``rank`` messages agree on the new time.

Times are judged against it by the caller (the pipeline rejects ``t > reference + lead``).
"""

from __future__ import annotations

import math

from asvtwin.errors import ParameterError

__all__ = ["T_MAX_UNIX_S", "T_MIN_UNIX_S", "StreamClock", "plausible_time"]

T_MIN_UNIX_S = 946_684_800.0  #: 2000-01-01T00:00Z, earliest plausible AIS receive time
T_MAX_UNIX_S = 4_102_444_800.0  #: 2100-01-01T00:00Z, latest plausible time


def plausible_time(t: float | None) -> bool:
    """True for a finite time in 2000..2100 [UNIX s]."""
    return t is not None and T_MIN_UNIX_S <= t <= T_MAX_UNIX_S


class StreamClock:
    """Robust current time of a stream from the times of its messages.

    Parameters
    ----------
    window : int
        How many of the latest times are considered.
    rank : int
        The reference is the ``rank``-th largest of them (1 = the maximum).
    """

    def __init__(self, *, window: int = 32, rank: int = 4) -> None:
        if not 1 <= rank <= window:
            raise ParameterError(f"StreamClock: 1 <= rank <= window expected, actually: "
                                 f"rank {rank}, window {window}")
        self.window = int(window)
        self.rank = int(rank)
        self.recent: list[float] = []  #: times appended since the last trim (hot path appends)
        self.reference: float | None = None  #: current reference [UNIX s], None before any

    def observe(self, t: float) -> None:
        """Add one plausible time [UNIX s]."""
        self.recent.append(t)
        if len(self.recent) >= 2 * self.window:
            self.update()

    def update(self) -> float | None:
        """Recompute (and trim) from the latest times; return the reference."""
        recent = self.recent
        if len(recent) > self.window:
            del recent[:-self.window]
        if recent:
            s = sorted(recent)
            self.reference = s[-min(self.rank, len(s))]
        return self.reference

    def prime(self, times: list[float]) -> None:
        """Start from a look-ahead at the first times of a stream (plausible ones only)."""
        good = [t for t in times if plausible_time(t) and math.isfinite(t)]
        if good:
            self.recent.extend(good[: self.window])
            self.update()
